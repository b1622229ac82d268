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

**Measured on the simulator's maritime scenes** (4K, ds 2, N 25, T 16, ego-motion estimated;
module recall R@0.1 / R@0.5 with NWD, C = 12.8; maritime_val 120 frames / 980 GT, maritime_test
40 frames). The RPN's post-processing is not what limits recall there; what does is the ranking
of ``R`` itself: about half of the swimmers have ``R = 0`` (their correlation blob is a few map
pixels wide and does not outweigh the dense wave and foam correlation under the lobula's
surround, whose negative integral is about 8 times the positive one), and foam streaks outrank
most of the others::

                                          maritime_val      maritime_test
    default (nms 3, shift 0.3 S)          0.234  0.133      0.556  0.198
    nms window 5 / 7 / 9 / 11             0.234  0.133      0.556  0.198  (nms 7)
    no proposal within 4 map px of edge   0.237  0.134      0.554  0.193
    lobula BORDER_REPLICATE               0.231  0.132      0.549  0.198
    lobula BORDER_REFLECT_101             0.228  0.131      0.549  0.195
    R / (G(s2) * C + mean C)              0.194  0.116
    shift 0 / 0.15 S / 0.5 S              0.235  0.097      0.556  0.244
                                          0.236  0.121      0.556  0.228
                                          0.232  0.119      0.556  0.147

``R`` is smooth at the DoG scale, so its maxima are already further apart than the 3x3 window
and a window scaled with T / ds changes nothing. Pixels outside the map count as zero in the
lobula, but the resulting edge bias is mild (1.6 % of the proposals lie within 2 map px of the
edge, which covers 0.6 % of the map) and neither a proposal margin nor a replicated or reflected
border changes recall beyond a few GT boxes. A divisive normalisation by the local correlation
level loses recall. The forward shift helps R@0.5 on one split and hurts it on the other, so
the paper's 0.3 S stays the default (``shift_ratio``).
"""

from __future__ import annotations

import cv2
import numpy as np

from sarmission.perception.types import MotionMaps, Proposals
from sarmission.perception.vstmd import direction_at, map_to_full


class TTMRPN:
    """Motion region proposals from one frame's :class:`MotionMaps`.

    Args:
        topn: most proposals per frame (N).
        box_size: box side S in full-resolution pixels.
        shift_ratio: forward shift of the box centre along theta, as a fraction of S.
        nms_size: odd side (1/ds map pixels) of the local-maximum window.
        min_score: responses at or below this are never proposed (R is rectified, so 0 means no
            motion; the default sits above float32 round-off of the lobula filters).
    """

    def __init__(self, topn: int = 25, box_size: float = 16.0, shift_ratio: float = 0.3,
                 nms_size: int = 3, min_score: float = 1e-7) -> None:
        if topn < 1:
            raise ValueError(f"topn must be at least 1, got {topn}")
        if not box_size > 0:
            raise ValueError(f"box_size must be positive, got {box_size}")
        if nms_size < 1 or nms_size % 2 == 0:
            raise ValueError(f"nms_size must be a positive odd number, got {nms_size}")
        if min_score < 0:
            raise ValueError(f"min_score must be non-negative, got {min_score}")
        self.topn = int(topn)
        self.box_size = float(box_size)
        self.shift_ratio = float(shift_ratio)
        self.nms_size = int(nms_size)
        self.min_score = float(min_score)
        self._window = np.ones((self.nms_size, self.nms_size), np.uint8)

    def peaks(self, response: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Top-N local maxima of ``response`` → ``(rows, cols, scores)``, best first."""
        flat = response.ravel()
        above = np.flatnonzero(flat > self.min_score)
        if above.size == 0:
            empty = np.zeros(0, np.int64)
            return empty, empty, np.zeros(0, np.float32)
        dilated = cv2.dilate(response, self._window, borderType=cv2.BORDER_CONSTANT,
                             borderValue=0)
        cand = above[flat[above] == dilated.ravel()[above]]
        scores = flat[cand]
        # Keep a margin over N so that plateau duplicates removed below cannot starve the list.
        keep = min(cand.size, 2 * self.topn)
        if cand.size > keep:
            part = np.argpartition(-scores, keep - 1)[:keep]
            cand, scores = cand[part], scores[part]
        order = np.lexsort((cand, -scores))
        cand, scores = cand[order], scores[order]
        rows, cols = np.divmod(cand, response.shape[1])
        kept = self._drop_plateau_twins(rows, cols, scores)[: self.topn]
        return rows[kept], cols[kept], scores[kept]

    def _drop_plateau_twins(self, rows: np.ndarray, cols: np.ndarray,
                            scores: np.ndarray) -> np.ndarray:
        """Indices of ranked maxima without an equal-scored, better-ranked one in its window."""
        half = self.nms_size // 2
        kept: list[int] = []
        for k in range(rows.size):
            twin = any(scores[q] == scores[k] and abs(int(rows[q]) - int(rows[k])) <= half
                       and abs(int(cols[q]) - int(cols[k])) <= half for q in kept)
            if not twin:
                kept.append(k)
        return np.asarray(kept, dtype=np.int64)

    def propose(self, motion: MotionMaps) -> Proposals:
        """Proposals (full-resolution pixels) for one frame's maps."""
        rows, cols, scores = self.peaks(motion.response)
        if rows.size == 0:
            return Proposals()
        theta = direction_at(motion, cols, rows).astype(np.float64)
        polarity = (motion.temporal_change[rows, cols] > 0).astype(np.float32)
        x = map_to_full(cols.astype(np.float64), motion.ds)
        y = map_to_full(rows.astype(np.float64), motion.ds)
        shift = self.shift_ratio * self.box_size
        cx = x + shift * np.cos(theta)
        cy = y - shift * np.sin(theta)
        half = 0.5 * self.box_size
        boxes = np.stack([cx - half, cy - half, cx + half, cy + half], axis=1)
        return Proposals(points=np.stack([x, y], axis=1).astype(np.float32),
                         boxes=boxes.astype(np.float32), scores=scores.astype(np.float32),
                         theta=theta.astype(np.float32), polarity=polarity)

    def flops(self, map_h: int, map_w: int) -> int:
        """Operations per frame on ``map_h x map_w`` maps: threshold 1/px, separable max filter
        ``2 (k - 1)``/px, and per proposal the 3x3 direction (9 G ratios, 2 x 9 MACs, atan2 ~20),
        polarity 1, coordinate restore 4, shift 6 and box corners 4 (about 80 in all).
        """
        per_px = 1 + 2 * (self.nms_size - 1)
        per_proposal = 9 + 2 * 2 * 9 + 20 + 1 + 4 + 6 + 4
        return int(map_h * map_w * per_px + self.topn * per_proposal)
