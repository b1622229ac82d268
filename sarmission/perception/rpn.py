"""TTM-RPN: learning-free motion proposals from the vSTMD maps (paper section 3.1).

1. Local maxima of the response ``R`` (1/ds map): ``R(i, j) == max_{nms window} R`` and
   ``R(i, j) > min_score``. Equal-valued neighbours (plateaus) keep only their first pixel in
   raster order after ranking.
2. Top-N by score (``np.argpartition`` on the candidate list, then a sort of those N only).
3. Direction ``theta`` at each point (:func:`~sarmission.perception.vstmd.direction_at`) and
   polarity ``p = 1`` where ``L > 0`` at the point, else 0.
4. Points go back to full resolution (``x = (j + 0.5) * ds - 0.5``) and the box centre moves
   forward along the motion, since the response peaks on the trailing edge of a moving target::

       Delta = shift_ratio * S,   cx = x + Delta * cos(theta),   cy = y - Delta * sin(theta)
       box   = [cx - S/2, cy - S/2, cx + S/2, cy + S/2]          (S = box_size, full-res px)

**Colour proposals.** Given a chromatic anomaly map (:mod:`~sarmission.perception.chroma`), a
share of the N proposals (``colour_share``, default 0.4: 10 of 25) goes to its strongest local
maxima (``colour_nms`` window, 1/8-resolution map pixels) that lie at least ``colour_spacing``
full-resolution pixels from every motion proposal kept; they are boxes of side S centred on the
maximum (no forward shift), with theta and polarity read from the motion maps at that point. The
motion maxima fill the list first up to ``N - round(colour_share * N)`` and take back any colour
slot left empty, so a frame without colour anomalies still gets N motion proposals.
What the colour proposals and the RPN's variants were measured to do: docs/experiments.md.
"""

from __future__ import annotations

import cv2
import numpy as np

from sarmission.perception.chroma import CHROMA_SCALE
from sarmission.perception.types import (
    COLOUR,
    DEFAULT_COLOUR_SHARE,
    MOTION,
    MotionMaps,
    Proposals,
)
from sarmission.perception.vstmd import direction_at, full_to_map_index, map_to_full


class TTMRPN:
    """Motion region proposals from one frame's :class:`MotionMaps`.

    Args:
        topn: most proposals per frame (N).
        box_size: box side S in full-resolution pixels.
        shift_ratio: forward shift of the box centre along theta, as a fraction of S.
        nms_size: odd side (1/ds map pixels) of the local-maximum window.
        min_score: responses at or below this are never proposed (R is rectified, so 0 means no
            motion; the default sits above float32 round-off of the lobula filters).
        colour_share: share of N reserved for chromatic anomaly maxima when :meth:`propose`
            gets a chroma map (0 = motion only).
        colour_nms: odd side (chroma map pixels) of the colour local-maximum window.
        colour_spacing: least distance (full-resolution px) of a colour proposal from every
            motion proposal; None = 0.75 S.
    """

    def __init__(
        self,
        topn: int = 25,
        box_size: float = 16.0,
        shift_ratio: float = 0.3,
        nms_size: int = 3,
        min_score: float = 1e-7,
        colour_share: float = DEFAULT_COLOUR_SHARE,
        colour_nms: int = 3,
        colour_spacing: float | None = None,
    ) -> None:
        if topn < 1:
            raise ValueError(f"topn must be at least 1, got {topn}")
        if not box_size > 0:
            raise ValueError(f"box_size must be positive, got {box_size}")
        if nms_size < 1 or nms_size % 2 == 0:
            raise ValueError(f"nms_size must be a positive odd number, got {nms_size}")
        if min_score < 0:
            raise ValueError(f"min_score must be non-negative, got {min_score}")
        if not 0.0 <= colour_share <= 1.0:
            raise ValueError(f"colour_share must be in [0, 1], got {colour_share}")
        if colour_nms < 1 or colour_nms % 2 == 0:
            raise ValueError(f"colour_nms must be a positive odd number, got {colour_nms}")
        self.topn = int(topn)
        self.box_size = float(box_size)
        self.shift_ratio = float(shift_ratio)
        self.nms_size = int(nms_size)
        self.min_score = float(min_score)
        self.colour_share = float(colour_share)
        self.colour_nms = int(colour_nms)
        self.colour_spacing = 0.75 * self.box_size if colour_spacing is None else colour_spacing
        self._window = np.ones((self.nms_size, self.nms_size), np.uint8)
        self._colour_window = np.ones((self.colour_nms, self.colour_nms), np.uint8)

    @property
    def colour_slots(self) -> int:
        """Proposals reserved for colour maxima when a chroma map is given."""
        return int(round(self.colour_share * self.topn))

    def peaks(
        self, response: np.ndarray, count: int | None = None, window: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Top ``count`` (default N) local maxima of ``response`` → ``(rows, cols, scores)``,
        best first (``window``: the local-maximum structuring element, default nms_size)."""
        count = self.topn if count is None else count
        window = self._window if window is None else window
        flat = response.ravel()
        positive = flat > self.min_score
        n_positive = int(np.count_nonzero(positive))
        if n_positive == 0 or count < 1:
            empty = np.zeros(0, np.int64)
            return empty, empty, np.zeros(0, np.float32)
        dilated = cv2.dilate(
            response, window, borderType=cv2.BORDER_CONSTANT, borderValue=0
        ).ravel()
        if n_positive > flat.size // 16:  # dense (a chroma map): compare whole arrays
            positive &= flat == dilated
            cand = np.flatnonzero(positive)
        else:  # sparse (the rectified R): compare at the positive pixels only
            above = np.flatnonzero(positive)
            cand = above[flat[above] == dilated[above]]
        scores = flat[cand]
        # Keep a margin over N so that plateau duplicates removed below cannot starve the list.
        keep = min(cand.size, 2 * count)
        if cand.size > keep:
            part = np.argpartition(-scores, keep - 1)[:keep]
            cand, scores = cand[part], scores[part]
        order = np.lexsort((cand, -scores))
        cand, scores = cand[order], scores[order]
        rows, cols = np.divmod(cand, response.shape[1])
        kept = self._drop_plateau_twins(rows, cols, scores, window.shape[0] // 2)[:count]
        return rows[kept], cols[kept], scores[kept]

    @staticmethod
    def _drop_plateau_twins(
        rows: np.ndarray, cols: np.ndarray, scores: np.ndarray, half: int
    ) -> np.ndarray:
        """Indices of ranked maxima without an equal-scored, better-ranked one in its window
        (scores are sorted best first, so only runs of equal scores need checking)."""
        tied = np.zeros(scores.size, bool)
        tied[1:] = scores[1:] == scores[:-1]
        kept: list[int] = []
        for k in range(rows.size):
            twin = tied[k] and any(
                scores[q] == scores[k]
                and abs(int(rows[q]) - int(rows[k])) <= half
                and abs(int(cols[q]) - int(cols[k])) <= half
                for q in kept
            )
            if not twin:
                kept.append(k)
        return np.asarray(kept, dtype=np.int64)

    def propose(self, motion: MotionMaps, chroma: np.ndarray | None = None) -> Proposals:
        """Proposals (full-resolution pixels) for one frame's maps; with a chromatic anomaly map
        (:func:`~sarmission.perception.chroma.chroma_anomaly` of the same frame) part of them come
        from its maxima (see the module docstring). Motion proposals come first."""
        rows, cols, scores = self.peaks(motion.response)
        slots = self.colour_slots if chroma is not None else 0
        n_motion = min(rows.size, self.topn - slots)
        x = map_to_full(cols.astype(np.float64), motion.ds)
        y = map_to_full(rows.astype(np.float64), motion.ds)
        cx, cy, cs = (
            self._colour_points(chroma, x[:n_motion], y[:n_motion], self.topn - n_motion)
            if slots
            else (np.zeros(0),) * 3
        )
        n_motion = min(rows.size, self.topn - cx.size)
        if n_motion + cx.size == 0:
            return Proposals()
        h, w = motion.response.shape
        map_rows = np.concatenate([rows[:n_motion], full_to_map_index(cy, motion.ds, h)])
        map_cols = np.concatenate([cols[:n_motion], full_to_map_index(cx, motion.ds, w)])
        theta = direction_at(motion, map_cols, map_rows).astype(np.float64)
        polarity = (motion.temporal_change[map_rows, map_cols] > 0).astype(np.float32)
        source = np.concatenate(
            [np.full(n_motion, MOTION, np.uint8), np.full(cx.size, COLOUR, np.uint8)]
        )
        px, py = np.concatenate([x[:n_motion], cx]), np.concatenate([y[:n_motion], cy])
        # Motion boxes move forward along theta (the peak trails the target); colour ones do not.
        shift = np.where(source == MOTION, self.shift_ratio * self.box_size, 0.0)
        bx, by = px + shift * np.cos(theta), py - shift * np.sin(theta)
        half = 0.5 * self.box_size
        boxes = np.stack([bx - half, by - half, bx + half, by + half], axis=1)
        points = np.stack([px, py], axis=1)
        return Proposals(
            points=points.astype(np.float32),
            boxes=boxes.astype(np.float32),
            scores=np.concatenate([scores[:n_motion], cs]).astype(np.float32),
            theta=theta.astype(np.float32),
            polarity=polarity,
            source=source,
        )

    def _colour_points(
        self, chroma: np.ndarray, motion_x: np.ndarray, motion_y: np.ndarray, count: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Up to ``count`` chroma maxima (full-res x, y, score) away from the motion points."""
        rows, cols, scores = self.peaks(chroma, count + motion_x.size, self._colour_window)
        x = map_to_full(cols.astype(np.float64), CHROMA_SCALE)
        y = map_to_full(rows.astype(np.float64), CHROMA_SCALE)
        if motion_x.size and x.size:
            gap = np.hypot(x[:, None] - motion_x[None], y[:, None] - motion_y[None]).min(axis=1)
            far = gap >= self.colour_spacing
            x, y, scores = x[far], y[far], scores[far]
        return x[:count], y[:count], scores[:count].astype(np.float64)

    def flops(self, map_h: int, map_w: int, chroma_shape: tuple[int, int] | None = None) -> int:
        """Operations per frame on ``map_h x map_w`` maps: threshold 1/px, separable max filter
        ``2 (k - 1)``/px, and per proposal the 3x3 direction (9 G ratios, 2 x 9 MACs, atan2 ~20),
        polarity 1, coordinate restore 4, shift 6 and box corners 4 (about 80 in all); with a
        chroma map of ``chroma_shape`` also its threshold and max filter and, per colour
        proposal, the distance to every motion proposal (4 each).
        """
        per_px = 1 + 2 * (self.nms_size - 1)
        per_proposal = 9 + 2 * 2 * 9 + 20 + 1 + 4 + 6 + 4
        total = map_h * map_w * per_px + self.topn * per_proposal
        if chroma_shape is not None and self.colour_slots:
            total += chroma_shape[0] * chroma_shape[1] * (1 + 2 * (self.colour_nms - 1))
            total += self.colour_slots * 4 * self.topn
        return int(total)
