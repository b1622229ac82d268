"""One evaluation report: SAR metrics, box metrics by size band and per-module recall.

:func:`evaluate_detections` turns an annotated dataset and per-image detections (and, when the
detector was run here, its per-image RPN proposals) into one JSON-serialisable dict;
:func:`format_report` renders it as fixed-width text tables in the layout of the paper's tables.

Ground truth: only the people among the detector's classes count. A dataset category is a
target when its name, normalised (lower case, every run of other characters than letters and
digits becomes ``_``), equals a head class that is a person
(:mod:`sarmission.class_roles`) or an alias in :data:`CATEGORY_ALIASES` (SeaDronesSee
MOT calls a swimmer with a life jacket a ``floater``). Annotations of every other category (boats,
buoys, ``ignored`` regions, people on boats) are left out of the ground truth, and so are the
detections of a head's other classes (a head that names boats reports its boats apart): a
person-class detection on a boat is a false alarm. Each target category maps to one head class,
and class-aware metrics compare that class with the detection's.
"""

from __future__ import annotations

import json
from collections.abc import Collection, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from sarmission.boxes import SIZE_BANDS, xywh_to_xyxy
from sarmission.class_roles import CATEGORY_ALIASES, normalise_class, person_class_ids
from sarmission.data.coco_video import Category, VideoDataset
from sarmission.evaluation import box_metrics, sar_metrics
from sarmission.evaluation.matching import FrameBoxes, ground_truth_by_image, match_frame
from sarmission.evaluation.reliability import format_reliability, reliability_table

#: NWD thresholds of the per-module recall (paper Table 3).
MODULE_RECALL_THRESHOLDS: tuple[float, ...] = (0.1, 0.5)

REPORT_DEFINITIONS: dict[str, str] = {
    "target_categories": (
        "GT = annotations of the dataset categories whose normalised name (lower case, other "
        "characters than letters/digits -> '_') is a head class that is a person, or an alias "
        "of one (floater -> swimmer_with_life_jacket); crowd annotations and other categories "
        "are left out, so person detections on them are false alarms; detections of the "
        "head's other classes (boat, buoy, ...) are left out."
    ),
    "evaluated_frames": (
        "The dataset's images, or only those the detector processed (frames it could not "
        "read and frames past --max-frames are left out of every metric)."
    ),
    "module_recall_rpn": (
        "R@t = GT boxes matched / GT boxes, every RPN proposal counted regardless of class "
        "and score; greedy one-to-one matching at NWD >= t, per frame."
    ),
    "module_recall_head": (
        "R@t as for the RPN, over the head's detections with score > score_thr whose class "
        "equals the GT box's class."
    ),
    **{f"box_{key}": text for key, text in box_metrics.DEFINITIONS.items()},
    **sar_metrics.DEFINITIONS,
}


#: ``"Swimmer with life-jacket"`` -> ``"swimmer_with_life_jacket"`` (one normalisation for
#: dataset categories and head classes alike).
normalise_name = normalise_class


def target_category_map(categories: Sequence[Category], classes: Sequence[str]) -> dict[int, int]:
    """Dataset category id -> head class index for the target categories (module docstring).

    Raises ``ValueError`` when no category of the dataset is a target.
    """
    index = {normalise_name(c): i for i, c in enumerate(classes)}
    mapping = {}
    for category in categories:
        name = normalise_name(category.name)
        name = CATEGORY_ALIASES.get(name, name)
        if name in index:
            mapping[category.id] = index[name]
    if not mapping:
        names = ", ".join(repr(c.name) for c in categories) or "none"
        raise ValueError(
            f"no annotation category is one of the detector's classes "
            f"{list(classes)} (dataset categories: {names})"
        )
    return mapping


def person_category_map(categories: Sequence[Category], classes: Sequence[str]) -> dict[int, int]:
    """:func:`target_category_map` restricted to the head classes that are people.

    Raises ``ValueError`` when no category of the dataset is a person class of the head.
    """
    mapping = target_category_map(categories, classes)
    people = set(person_class_ids(classes).tolist())
    kept = {cid: k for cid, k in mapping.items() if k in people}
    if not kept:
        named = ", ".join(classes[k] for k in sorted(set(mapping.values())))
        raise ValueError(f"no annotation category is a person class of the detector (only {named})")
    return kept


def people_only(boxes: FrameBoxes, person_ids: np.ndarray) -> FrameBoxes:
    """The boxes whose class is one of ``person_ids``."""
    keep = np.isin(boxes.class_ids, person_ids)
    if keep.all():
        return boxes
    return FrameBoxes(boxes.boxes[keep], boxes.scores[keep], boxes.class_ids[keep], boxes.ids[keep])


def detections_from_results(
    records: Sequence[Mapping[str, Any]], dataset: VideoDataset, classes: Sequence[str]
) -> dict[int, FrameBoxes]:
    """Per-image detections from COCO result records (``category_id`` = class index + 1).

    Raises ``ValueError`` when a record names an image id absent from ``dataset`` or a
    category id outside ``1..len(classes)``, or has a malformed box or score.
    """
    known = {image.id for image in dataset.images}
    unknown = sorted({r["image_id"] for r in records if r["image_id"] not in known}, key=str)
    if unknown:
        shown = ", ".join(map(str, unknown[:5])) + (" ..." if len(unknown) > 5 else "")
        raise ValueError(
            f"{len(unknown)} image id(s) of the detections are not in the annotations: {shown}"
        )
    grouped: dict[int, list[tuple[list[float], float, int]]] = {}
    for i, record in enumerate(records):
        category = record["category_id"]
        if not isinstance(category, int) or not 1 <= category <= len(classes):
            labels = ", ".join(f"{j + 1}={c}" for j, c in enumerate(classes))
            raise ValueError(
                f"detection record {i}: category_id {category!r} is not a class "
                f"of the detector ({labels})"
            )
        try:
            bbox = [float(v) for v in record["bbox"]]
            score = float(record["score"])
        except (TypeError, ValueError):
            raise ValueError(
                f"detection record {i}: bbox must be 4 numbers and score a "
                f"number, got {record['bbox']!r}, {record['score']!r}"
            ) from None
        if len(bbox) != 4:
            raise ValueError(f"detection record {i}: bbox must be [x, y, w, h], got {bbox}")
        if not np.isfinite([*bbox, score]).all():
            raise ValueError(
                f"detection record {i}: bbox and score must be finite, got {bbox}, {score}"
            )
        grouped.setdefault(record["image_id"], []).append((bbox, score, category - 1))
    return {
        image_id: FrameBoxes.of(
            xywh_to_xyxy(np.array([b for b, _, _ in rows]).reshape(-1, 4)),
            scores=[s for _, s, _ in rows],
            class_ids=[c for _, _, c in rows],
        )
        for image_id, rows in grouped.items()
    }


def subset(dataset: VideoDataset, image_ids: Collection[int]) -> VideoDataset:
    """The dataset restricted to ``image_ids`` (their annotations, every video and category)."""
    keep = set(image_ids)
    return replace(
        dataset,
        images=[im for im in dataset.images if im.id in keep],
        annotations=[a for a in dataset.annotations if a.image_id in keep],
    )


def _with_classes(
    boxes: Mapping[int, FrameBoxes], mapping: Mapping[int, int]
) -> dict[int, FrameBoxes]:
    """GT boxes with dataset category ids replaced by head class indices."""
    return {
        image_id: FrameBoxes(
            b.boxes, b.scores, np.array([mapping[c] for c in b.class_ids.tolist()], np.int64), b.ids
        )
        for image_id, b in boxes.items()
    }


def _recall(
    ground_truth: Mapping[int, FrameBoxes],
    boxes: Mapping[int, FrameBoxes],
    score_thr: float | None,
    class_agnostic: bool,
) -> dict[str, float]:
    recall = box_metrics.recall_at_nwd(
        ground_truth,
        boxes,
        MODULE_RECALL_THRESHOLDS,
        score_thr=score_thr,
        class_agnostic=class_agnostic,
    )
    return {f"R@{t:g}": value for t, value in recall.items()}


def evaluate_detections(
    dataset: VideoDataset,
    detections: Mapping[int, FrameBoxes],
    classes: Sequence[str],
    proposals: Mapping[int, FrameBoxes] | None = None,
    *,
    m: int = 3,
    k: int = 5,
    score_thr: float = 0.5,
    nwd_thr: float = 0.5,
    image_ids: Collection[int] | None = None,
) -> dict[str, Any]:
    """Evaluate per-image detections (class = head class index) against ``dataset``.

    ``proposals`` (RPN boxes per image, class-agnostic) adds the RPN's module recall.
    ``image_ids`` restricts the evaluation to those images (e.g. the frames a detector saw).
    Returns a JSON-serialisable dict with keys ``dataset``, ``classes``, ``categories``,
    ``settings``, ``sar`` (:class:`~sarmission.evaluation.sar_metrics.SarMetrics` fields),
    ``boxes`` (per size band: n_gt, n_detections, ap, ar, f2, precision, recall,
    ap_per_threshold), ``module_recall`` (``rpn`` — ``None`` without proposals — and ``head``,
    each ``{"R@0.1": .., "R@0.5": ..}``) and ``definitions`` (how every number is computed).
    """
    if not 1 <= m <= k:
        raise ValueError(f"need 1 <= m <= k, got m={m}, k={k}")
    mapping = person_category_map(dataset.categories, classes)
    if image_ids is not None:
        dataset = subset(dataset, image_ids)
    evaluated = {image.id for image in dataset.images}
    people = person_class_ids(classes)
    detections = {i: people_only(d, people) for i, d in detections.items() if i in evaluated}
    targets = sorted(mapping)

    sar = sar_metrics.evaluate_sar(
        sar_metrics.sequences_from_dataset(dataset, detections, targets),
        m=m,
        k=k,
        score_thr=score_thr,
        nwd_thr=nwd_thr,
    ).to_dict()
    sar.pop("definitions")
    ground_truth = _with_classes(ground_truth_by_image(dataset, targets), mapping)
    boxes = box_metrics.evaluate_boxes(ground_truth, detections, score_thr=score_thr).to_dict()
    boxes.pop("definitions")
    module_recall = {
        "rpn": None if proposals is None else _recall(ground_truth, proposals, None, True),
        "head": _recall(ground_truth, detections, score_thr, False),
    }
    reliability = _reliability(ground_truth, detections, nwd_thr)
    names = {c.id: c.name for c in dataset.categories}
    return {
        "dataset": {
            "annotations": None if dataset.source_path is None else str(dataset.source_path),
            "n_videos": len({im.video_id for im in dataset.images}),
            "n_frames": len(dataset.images),
            "n_gt_boxes": sum(len(b) for b in ground_truth.values()),
        },
        "classes": list(classes),
        "categories": {
            "targets": [
                {"id": cid, "name": names[cid], "class": classes[mapping[cid]]} for cid in targets
            ],
            "ignored": [
                {"id": c.id, "name": c.name} for c in dataset.categories if c.id not in mapping
            ],
        },
        "settings": {
            "m": m,
            "k": k,
            "score_thr": score_thr,
            "nwd_thr": nwd_thr,
            "box_nwd_thresholds": list(box_metrics.DEFAULT_NWD_THRESHOLDS),
            "module_recall_thresholds": list(MODULE_RECALL_THRESHOLDS),
        },
        "sar": sar,
        "boxes": boxes,
        "module_recall": module_recall,
        "reliability": reliability,
        "definitions": dict(REPORT_DEFINITIONS),
    }


def _reliability(
    ground_truth: Mapping[int, FrameBoxes], detections: Mapping[int, FrameBoxes], nwd_thr: float
) -> dict[str, Any]:
    """Every detection's score against whether it matched a GT box (NWD > ``nwd_thr``, any
    score): what a detection's confidence means on this data."""
    scores: list[float] = []
    correct: list[bool] = []
    for image_id, det in detections.items():
        gt = ground_truth.get(image_id)
        if gt is None or not len(det):
            continue
        match = match_frame(det, gt, score_thr=-1.0, nwd_thr=nwd_thr)
        hit = np.zeros(len(det), dtype=bool)
        hit[match.det_indices] = True
        scores += det.scores.tolist()
        correct += hit.tolist()
    return reliability_table(scores, correct)


def report_to_json(report: Mapping[str, Any]) -> str:
    """The report (or sweep rows) as indented JSON."""
    return json.dumps(report, indent=2)


def _num(value: float | None, spec: str, none: str = "-") -> str:
    return none if value is None else format(value, spec)


def format_report(report: Mapping[str, Any]) -> str:
    """Fixed-width text: SAR criteria, box metrics per size band, module recall, definitions."""
    sar, settings, data = report["sar"], report["settings"], report["dataset"]
    cats = report["categories"]
    targets = ", ".join(f"{c['name']} -> {c['class']}" for c in cats["targets"])
    ignored = ", ".join(c["name"] for c in cats["ignored"]) or "none"
    lines = [
        f"dataset: {data['annotations'] or '<in memory>'} ({data['n_videos']} videos, "
        f"{data['n_frames']} frames, {data['n_gt_boxes']} GT boxes)",
        f"targets: {targets}; ignored: {ignored}",
        "",
        f"SAR criteria (lock = matched in >= {settings['m']} of {settings['k']} frames; "
        f"match = Hungarian, score > {settings['score_thr']:g}, NWD > {settings['nwd_thr']:g})",
        f"  {'Search Success Rate (%)':<38}{_num(sar['search_success_rate'], '8.2f'):>8}"
        f"   {sar['n_locked']}/{sar['n_trajectories']} trajectories locked"
        f" ({sar['n_lockable']} annotated in >= {settings['m']} frames)",
        f"  {'False Alarm Rate, per frame (%)':<38}"
        f"{_num(sar['false_alarm_rate_per_frame'], '8.2f'):>8}"
        f"   {sar['n_false_alarms']} unmatched detections / {sar['n_frames']} frames",
        f"  {'False Alarm Rate, per detection (%)':<38}"
        f"{_num(sar['false_alarm_rate_detections'], '8.2f'):>8}"
        f"   {sar['n_false_alarms']} unmatched / {sar['n_detections']} detections",
        f"  {'Search time avg / max (frames)':<38}"
        f"{_num(sar['avg_search_time_frames'], '8.2f'):>8} / "
        f"{_num(sar['max_search_time_frames'], 'd')}",
        "",
        f"Box metrics (mean over classes and NWD {settings['box_nwd_thresholds'][0]:g}:0.05:"
        f"{settings['box_nwd_thresholds'][-1]:g}; F2 at score > {settings['score_thr']:g})",
        f"  {'band':<16}{'area px^2':>12}{'GT':>7}{'dets':>7}{'AP':>8}{'AR':>8}{'F2':>8}",
    ]
    for band, (low, high) in SIZE_BANDS.items():
        b = report["boxes"]["bands"][band]
        area = "any" if band == "all" else f"{low:g}-{high:g}"
        lines.append(
            f"  {band.replace('_', ' '):<16}{area:>12}{b['n_gt']:>7}"
            f"{b['n_detections']:>7}{_num(b['ap'], '.4f'):>8}"
            f"{_num(b['ar'], '.4f'):>8}{_num(b['f2'], '.4f'):>8}"
        )
    thresholds = [f"R@{t:g}" for t in settings["module_recall_thresholds"]]
    lines += [
        "",
        "Module recall (paper Table 3)",
        f"  {'module':<38}" + "".join(f"{t:>8}" for t in thresholds),
    ]
    for label, key in (("TTM-RPN (no category)", "rpn"), ("R-CNN-like head (category)", "head")):
        values = report["module_recall"][key]
        cells = ["n/a" if values is None else f"{values[t]:.4f}" for t in thresholds]
        lines.append(f"  {label:<38}" + "".join(f"{c:>8}" for c in cells))
    if report.get("reliability"):
        lines += [
            "",
            "Reliability (what a detection's score means: share matching a person, "
            "NWD > " + f"{settings['nwd_thr']:g})",
        ]
        lines += format_reliability(report["reliability"])
    definitions = report["definitions"]
    lines += [
        "",
        "FAR per frame: " + definitions["false_alarm_rate_per_frame"],
        "FAR per detection: " + definitions["false_alarm_rate_detections"],
    ]
    return "\n".join(lines)


def format_sweep(rows: Sequence[Mapping[str, Any]]) -> str:
    """The scalability sweep as a fixed-width table in the layout of the paper's Table 4.

    Each row needs ``ds``, ``topn``, ``ssr``, ``far_per_frame``, ``median_ms``, ``fps`` and
    ``gflops`` (``total``, ``vstmd``, ``rpn_other``, ``head``).
    """
    header = (
        f"{'ds':>3}{'N':>5}{'SSR %':>9}{'FAR %':>9}{'ms':>9}{'FPS':>8}"
        f"{'total GF':>10}{'vSTMD GF':>10}{'other GF':>10}{'head GF':>10}"
    )
    lines = [header, "-" * len(header)]
    for r in rows:
        g = r["gflops"]
        lines.append(
            f"{r['ds']:>3}{r['topn']:>5}{_num(r['ssr'], '.2f'):>9}"
            f"{_num(r['far_per_frame'], '.2f'):>9}{r['median_ms']:>9.2f}"
            f"{r['fps']:>8.2f}{g['total']:>10.4f}{g['vstmd']:>10.4f}"
            f"{g['rpn_other']:>10.4f}{g['head']:>10.4f}"
        )
    lines += [
        "ms = median wall time per frame of the whole cascade in this run, FPS = 1000 / ms",
        "FAR = 100 * unmatched detections / frames; GFLOPs per frame at the dataset's frame "
        "size (other = RPN + crops)",
    ]
    return "\n".join(lines)
