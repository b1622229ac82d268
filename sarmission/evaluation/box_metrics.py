"""Box-level metrics by size band: COCO-style AP and AR, F2, and recall at NWD thresholds.

Matching (per image, per class unless class-agnostic, per NWD threshold t): detections in order
of decreasing score each take the unmatched GT box with the highest NWD, provided NWD >= t
(greedy, one GT per detection, as COCO does with IoU). Because the order is by score, the
matches of the detections above any score threshold are the same as if only those had been
matched, so one matching serves both AP and F2.

Size bands (``sarmission.boxes.SIZE_BANDS``, by area in px^2, lower bound exclusive): GT boxes
belong to the band of their own area. For a band, a detection matched to a GT of that band is a
true positive; matched to a GT of another band it is ignored (neither TP nor FP); unmatched, it
is a false positive of the band of its own area and ignored elsewhere. Band ``all`` counts
everything. (COCO instead re-matches per band with out-of-band GT as "ignore" regions; the
choice here keeps one matching for all bands.)

Per band, class and threshold:

* AP: 101-point interpolated precision: recall levels r in {0, 0.01, ..., 1}; precision at r is
  the highest precision at any recall >= r along the score-ranked list (0 beyond the last
  recall reached); AP is their mean.
* AR: the recall reached by all detections (no per-image cap on their number).
* F2 at ``score_thr`` (detections with score > ``score_thr``): ``P = TP / (TP + FP)``,
  ``R = TP / n_GT``, ``F2 = 5 P R / (4 P + R)`` (0 when P = R = 0); recall weighs 4x precision.

Reported values are means over the classes that have GT in the band and over the thresholds
(COCO's "mAP", "mAR"; "mF2" likewise); ``ap_per_threshold`` keeps the per-threshold means.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from sarmission.boxes import NWD_CONSTANT, SIZE_BANDS, box_area, nwd_matrix
from sarmission.evaluation.matching import FrameBoxes

#: NWD thresholds averaged for AP/AR/F2, as COCO averages IoU 0.50:0.05:0.95.
DEFAULT_NWD_THRESHOLDS: tuple[float, ...] = tuple(round(0.5 + 0.05 * i, 2) for i in range(10))
_RECALL_LEVELS = np.linspace(0.0, 1.0, 101)

DEFINITIONS: dict[str, str] = {
    "matching": "greedy by decreasing score, one GT per detection, highest NWD >= threshold",
    "bands": (
        "GT by own area; detections matched to another band's GT ignored; unmatched "
        "detections are FPs of the band of their own area"
    ),
    "ap": "mean over classes and NWD thresholds of 101-point interpolated precision",
    "ar": "mean over classes and NWD thresholds of the recall reached by all detections",
    "f2": "mean over classes and thresholds of 5PR/(4P+R) for detections with score > score_thr",
    "precision": "TP / (TP + FP) at score > score_thr (same averaging)",
    "recall": "TP / n_GT at score > score_thr (same averaging)",
}


@dataclass
class BandMetrics:
    """Metrics of one size band; all ``None`` when the band has no GT boxes."""

    n_gt: int
    n_detections: int
    ap: float | None
    ar: float | None
    f2: float | None
    precision: float | None
    recall: float | None
    ap_per_threshold: dict[float, float] = field(default_factory=dict)


@dataclass
class BoxMetrics:
    """Metrics per size band (``extremely_tiny``, ``tiny``, ``small``, ``all``)."""

    bands: dict[str, BandMetrics]
    nwd_thresholds: tuple[float, ...]
    score_thr: float
    class_agnostic: bool
    definitions: dict[str, str] = field(default_factory=lambda: dict(DEFINITIONS))

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-serialisable dict."""
        out = asdict(self)
        out["nwd_thresholds"] = list(self.nwd_thresholds)
        for band in out["bands"].values():
            band["ap_per_threshold"] = {str(t): v for t, v in band["ap_per_threshold"].items()}
        return out


def greedy_match(
    det_boxes: np.ndarray,
    det_scores: np.ndarray,
    gt_boxes: np.ndarray,
    thresholds: Sequence[float],
    constant: float = NWD_CONSTANT,
) -> np.ndarray:
    """Greedy one-to-one matching at each threshold → ``[T, N_det]`` GT index or -1.

    Detections in decreasing score order (ties by input order) take the unmatched GT with the
    highest NWD >= threshold.
    """
    n_det, n_gt = len(det_boxes), len(gt_boxes)
    result = np.full((len(thresholds), n_det), -1, np.int64)
    if n_det == 0 or n_gt == 0:
        return result
    sim = nwd_matrix(det_boxes, gt_boxes, constant)
    order = np.argsort(-np.asarray(det_scores), kind="stable")
    for t, thr in enumerate(thresholds):
        taken = np.zeros(n_gt, bool)
        for d in order:
            row = np.where(taken | (sim[d] < thr), -1.0, sim[d])
            g = int(np.argmax(row))
            if row[g] >= 0:
                taken[g] = True
                result[t, d] = g
    return result


def interpolated_ap(scores: np.ndarray, is_tp: np.ndarray, n_gt: int) -> tuple[float, float]:
    """(AP, max recall) of a ranked list: 101-point interpolated precision (COCO).

    ``scores`` / ``is_tp`` are the counted detections (TP or FP); ``n_gt`` > 0.
    """
    order = np.argsort(-scores, kind="stable")
    tp = np.cumsum(is_tp[order])
    fp = np.cumsum(~is_tp[order])
    if tp.size == 0:
        return 0.0, 0.0
    recall = tp / n_gt
    precision = tp / (tp + fp)
    envelope = np.maximum.accumulate(precision[::-1])[::-1]
    idx = np.searchsorted(recall, _RECALL_LEVELS, side="left")
    sampled = np.where(idx < recall.size, envelope[np.minimum(idx, recall.size - 1)], 0.0)
    return float(sampled.mean()), float(recall[-1])


def f_beta(precision: float, recall: float, beta: float = 2.0) -> float:
    """``(1 + b^2) P R / (b^2 P + R)``; 0 when both are 0. ``beta=2`` favours recall."""
    denominator = beta * beta * precision + recall
    return 0.0 if denominator == 0 else (1 + beta * beta) * precision * recall / denominator


@dataclass
class _Counted:
    """Detections counted for one (band, class, threshold) and the band's GT count."""

    scores: list[np.ndarray] = field(default_factory=list)
    is_tp: list[np.ndarray] = field(default_factory=list)
    n_gt: int = 0


def _in_band(area: np.ndarray, band: str) -> np.ndarray:
    low, high = SIZE_BANDS[band]
    return (area > low) & (area <= high)


def evaluate_boxes(
    ground_truth: Mapping[Any, FrameBoxes],
    detections: Mapping[Any, FrameBoxes],
    nwd_thresholds: Sequence[float] = DEFAULT_NWD_THRESHOLDS,
    score_thr: float = 0.5,
    class_agnostic: bool = False,
    constant: float = NWD_CONSTANT,
) -> BoxMetrics:
    """AP, AR, F2, precision and recall per size band (definitions in the module docstring).

    ``ground_truth`` and ``detections`` map image ids to boxes; images only in ``detections``
    contribute false positives. Classes must be equal to match unless ``class_agnostic``.
    """
    thresholds = tuple(float(t) for t in nwd_thresholds)
    if not thresholds:
        raise ValueError("at least one NWD threshold is needed")
    counted: dict[tuple[str, int, int], _Counted] = {}
    n_det_band = dict.fromkeys(SIZE_BANDS, 0)
    empty = FrameBoxes.empty()
    for image_id in set(ground_truth) | set(detections):
        gt = ground_truth.get(image_id, empty)
        det = detections.get(image_id, empty)
        gt_cls = np.zeros(len(gt), np.int64) if class_agnostic else gt.class_ids
        det_cls = np.zeros(len(det), np.int64) if class_agnostic else det.class_ids
        gt_area, det_area = box_area(gt.boxes), box_area(det.boxes)
        for band in SIZE_BANDS:
            n_det_band[band] += int(_in_band(det_area, band).sum())
        for cls in np.union1d(gt_cls, det_cls).tolist():
            g_idx, d_idx = np.flatnonzero(gt_cls == cls), np.flatnonzero(det_cls == cls)
            matches = greedy_match(
                det.boxes[d_idx], det.scores[d_idx], gt.boxes[g_idx], thresholds, constant
            )
            for band in SIZE_BANDS:
                gt_in = _in_band(gt_area[g_idx], band)
                det_in = _in_band(det_area[d_idx], band)
                for t in range(len(thresholds)):
                    m = matches[t]
                    matched_in = np.zeros(m.shape, bool)
                    matched_in[m >= 0] = gt_in[m[m >= 0]]
                    counts = ((m < 0) & det_in) | matched_in
                    entry = counted.setdefault((band, cls, t), _Counted())
                    entry.scores.append(det.scores[d_idx][counts])
                    entry.is_tp.append(matched_in[counts])
                    entry.n_gt += int(gt_in.sum())

    bands = {
        band: _band_metrics(band, counted, thresholds, score_thr, n_det_band[band])
        for band in SIZE_BANDS
    }
    return BoxMetrics(bands, thresholds, score_thr, class_agnostic)


def _band_metrics(
    band: str,
    counted: dict[tuple[str, int, int], _Counted],
    thresholds: tuple[float, ...],
    score_thr: float,
    n_det: int,
) -> BandMetrics:
    per_t: dict[int, list[tuple[float, float, float, float, float]]] = {}
    n_gt_total = 0
    for (b, _, t), entry in counted.items():
        if b != band or entry.n_gt == 0:
            continue
        if t == 0:
            n_gt_total += entry.n_gt
        scores, is_tp = np.concatenate(entry.scores), np.concatenate(entry.is_tp)
        ap, ar = interpolated_ap(scores, is_tp, entry.n_gt)
        above = scores > score_thr
        tp = int((is_tp & above).sum())
        fp = int((~is_tp & above).sum())
        precision = tp / (tp + fp) if tp + fp else 0.0
        recall = tp / entry.n_gt
        per_t.setdefault(t, []).append((ap, ar, f_beta(precision, recall), precision, recall))
    if not per_t:
        return BandMetrics(0, n_det, None, None, None, None, None)
    means = {t: np.mean(np.array(rows), axis=0) for t, rows in per_t.items()}
    overall = np.mean(np.array(list(means.values())), axis=0)
    return BandMetrics(
        n_gt=n_gt_total,
        n_detections=n_det,
        ap=float(overall[0]),
        ar=float(overall[1]),
        f2=float(overall[2]),
        precision=float(overall[3]),
        recall=float(overall[4]),
        ap_per_threshold={thresholds[t]: float(v[0]) for t, v in sorted(means.items())},
    )


def recall_at_nwd(
    ground_truth: Mapping[Any, FrameBoxes],
    boxes: Mapping[Any, FrameBoxes],
    thresholds: Sequence[float] = (0.1, 0.5),
    score_thr: float | None = None,
    class_agnostic: bool = True,
    constant: float = NWD_CONSTANT,
) -> dict[float, float]:
    """Recall R_t = matched GT / all GT at each NWD threshold t (paper Table 3).

    For RPN proposals leave ``class_agnostic`` True and ``score_thr`` None (every box counts);
    for head output pass ``class_agnostic=False`` and the score threshold (boxes with
    score > ``score_thr``). Matching is the greedy one-to-one matching of :func:`greedy_match`.
    Returns 0 for every threshold when there is no GT.
    """
    thresholds = tuple(float(t) for t in thresholds)
    matched = np.zeros(len(thresholds), np.int64)
    n_gt = 0
    empty = FrameBoxes.empty()
    for image_id, gt in ground_truth.items():
        det = boxes.get(image_id, empty)
        if score_thr is not None:
            det = det.select(det.scores > score_thr)
        n_gt += len(gt)
        gt_cls = np.zeros(len(gt), np.int64) if class_agnostic else gt.class_ids
        det_cls = np.zeros(len(det), np.int64) if class_agnostic else det.class_ids
        for cls in np.unique(gt_cls).tolist():
            d_idx = np.flatnonzero(det_cls == cls)
            m = greedy_match(
                det.boxes[d_idx], det.scores[d_idx], gt.boxes[gt_cls == cls], thresholds, constant
            )
            matched += (m >= 0).sum(axis=1)
    return {t: (float(matched[i]) / n_gt if n_gt else 0.0) for i, t in enumerate(thresholds)}
