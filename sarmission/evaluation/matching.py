"""Per-frame one-to-one matching of detections to ground truth on NWD (paper section 5.1).

A detection is a *candidate* when its score is above ``score_thr``; a candidate may match a GT
box when their NWD is above ``nwd_thr`` (both strict, 0.5 by default). Among all valid pairs the
Hungarian algorithm (``scipy.optimize.linear_sum_assignment``) picks a one-to-one assignment that
first maximises the number of matches and then their total NWD: the cost of a valid pair is
``1 - NWD`` (< 1) and of an invalid pair a constant larger than any sum of valid costs, so an
invalid pair is only assigned where nothing valid is left, and is then dropped. Detections at or
below ``score_thr`` are neither matched nor unmatched: they are not reported at all.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from sarmission.boxes import NWD_CONSTANT, nwd_matrix, xywh_to_xyxy
from sarmission.data.coco_video import VideoDataset

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FrameBoxes:
    """Boxes of one image: ``boxes`` ``[N, 4]`` xyxy pixels, ``scores`` ``[N]``, ``class_ids``
    ``[N]`` and ``ids`` ``[N]`` (track ids of ground truth, -1 when unknown).

    Build with :meth:`of`, which fills missing columns (scores 1, classes 0, ids -1) and checks
    shapes. Ground truth ignores ``scores``.
    """

    boxes: np.ndarray
    scores: np.ndarray
    class_ids: np.ndarray
    ids: np.ndarray

    @classmethod
    def of(
        cls,
        boxes: np.ndarray | Iterable,
        scores: np.ndarray | Iterable | None = None,
        class_ids: np.ndarray | Iterable | None = None,
        ids: np.ndarray | Iterable | None = None,
    ) -> FrameBoxes:
        """Validated container from array-likes (``boxes`` may be empty)."""
        b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
        n = b.shape[0]
        columns = {
            "scores": np.ones(n) if scores is None else np.asarray(scores, dtype=np.float64),
            "class_ids": (
                np.zeros(n, np.int64)
                if class_ids is None
                else np.asarray(class_ids, dtype=np.int64)
            ),
            "ids": np.full(n, -1, np.int64) if ids is None else np.asarray(ids, dtype=np.int64),
        }
        for name, column in columns.items():
            if column.shape != (n,):
                raise ValueError(f"{name} has shape {column.shape}, expected ({n},) for {n} boxes")
        return cls(b, columns["scores"], columns["class_ids"], columns["ids"])

    @classmethod
    def empty(cls) -> FrameBoxes:
        """No boxes."""
        return cls.of(np.zeros((0, 4)))

    def __len__(self) -> int:
        return int(self.boxes.shape[0])

    def select(self, mask: np.ndarray) -> FrameBoxes:
        """Subset by boolean mask or index array."""
        return FrameBoxes(self.boxes[mask], self.scores[mask], self.class_ids[mask], self.ids[mask])


@dataclass(frozen=True)
class FrameMatch:
    """Result of :func:`match_frame`; all indices refer to the input arrays.

    ``det_indices[i]`` is matched to ``gt_indices[i]`` with similarity ``nwd[i]``.
    ``unmatched_detections`` are candidates (score > threshold) left without a GT box;
    ``unmatched_gt`` are GT boxes left without a detection.
    """

    det_indices: np.ndarray
    gt_indices: np.ndarray
    nwd: np.ndarray
    unmatched_detections: np.ndarray
    unmatched_gt: np.ndarray
    n_candidates: int


def match_frame(
    detections: FrameBoxes,
    ground_truth: FrameBoxes,
    score_thr: float = 0.5,
    nwd_thr: float = 0.5,
    constant: float = NWD_CONSTANT,
) -> FrameMatch:
    """One-to-one Hungarian matching of one frame's detections to its GT boxes (class-agnostic).

    A pair is valid when ``score > score_thr`` and ``NWD > nwd_thr``; the assignment maximises
    the number of valid pairs, then their total NWD (see the module docstring).
    """
    candidates = np.flatnonzero(detections.scores > score_thr)
    n_gt = len(ground_truth)
    empty = np.zeros(0, np.int64)
    if candidates.size == 0 or n_gt == 0:
        return FrameMatch(
            empty, empty, np.zeros(0), candidates, np.arange(n_gt), int(candidates.size)
        )
    sim = nwd_matrix(detections.boxes[candidates], ground_truth.boxes, constant)
    valid = sim > nwd_thr
    invalid_cost = float(min(sim.shape) + 1)
    cost = np.where(valid, 1.0 - sim, invalid_cost)
    rows, cols = linear_sum_assignment(cost)
    keep = valid[rows, cols]
    rows, cols = rows[keep], cols[keep]
    det_indices = candidates[rows]
    return FrameMatch(
        det_indices=det_indices,
        gt_indices=cols.astype(np.int64),
        nwd=sim[rows, cols],
        unmatched_detections=np.setdiff1d(candidates, det_indices),
        unmatched_gt=np.setdiff1d(np.arange(n_gt), cols),
        n_candidates=int(candidates.size),
    )


def ground_truth_by_image(
    dataset: VideoDataset, category_ids: Iterable[int] | None = None
) -> dict[int, FrameBoxes]:
    """GT boxes of every image (xyxy; class = category id; id = track id or -1).

    ``category_ids`` keeps only those categories. Crowd annotations (``iscrowd``) are left out.
    Boxes are clipped to their image, and those with nothing left inside it (outside, or of no
    width or height) are left out with one warning: a raw dataset file's box hanging over the
    edge turned a correct detection into a false one, one outside the image into a miss.
    Every image gets an entry, empty when it has no boxes.
    """
    keep = None if category_ids is None else set(category_ids)
    sizes = {im.id: (im.width, im.height) for im in dataset.images}
    result = {}
    dropped = 0
    for image_id, anns in dataset.annotations_by_image().items():
        chosen = [a for a in anns if not a.iscrowd and (keep is None or a.category_id in keep)]
        boxes = xywh_to_xyxy(np.array([a.bbox for a in chosen], dtype=np.float64).reshape(-1, 4))
        width, height = sizes.get(image_id, (None, None))
        if width and height:
            boxes[:, 0::2] = boxes[:, 0::2].clip(0.0, float(width))
            boxes[:, 1::2] = boxes[:, 1::2].clip(0.0, float(height))
        inside = (boxes[:, 2] > boxes[:, 0]) & (boxes[:, 3] > boxes[:, 1])
        dropped += int((~inside).sum())
        result[image_id] = FrameBoxes.of(
            boxes[inside],
            class_ids=[a.category_id for a, ok in zip(chosen, inside, strict=True) if ok],
            ids=[
                -1 if a.track_id is None else a.track_id
                for a, ok in zip(chosen, inside, strict=True)
                if ok
            ],
        )
    if dropped:
        log.warning(
            "%d ground-truth boxes lie outside their image or have no size: not scored", dropped
        )
    return result
