"""Training samples for the MITE-Net head (paper section 3.3): GT jittering, NWD label assignment
and hard negative mining.

**GT jittering.** vSTMD learns nothing, so extra positive RoIs are made by perturbing ground truth
boxes the way an imperfect motion proposal would be off. For a GT box with centre ``(cx, cy)`` and
size ``(w, h)`` each copy draws, uniformly and independently::

    s_x, s_y ~ U(-scale, scale)      u_x, u_y ~ U(-shift, shift)
    w' = W * (1 + s_x),  h' = H * (1 + s_y)       (W = H = side for square proposals, else w, h)
    cx' = cx + u_x * w',  cy' = cy + u_y * h'

With ``side`` set (the RPN's square box side S) the copies are squares (``s_y = s_x``), so their
crops have the RPN's pixel scale up to ±``scale``.

**NWD label assignment.** Each proposal takes the GT box with the highest
``NWD = exp(-W2 / C)`` (:func:`sarmission.boxes.nwd_matrix`, C = 12.8) and is positive when that
NWD is at least ``pos_threshold``.

**Hard negative mining.** Of the negatives of a batch only the ``ratio * N_pos`` with the highest
classification logit (1:3 positive:negative by default) enter the loss; with no positive in the
batch, the ``min_negatives`` hardest do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from sarmission.boxes import NWD_CONSTANT, cxcywh_to_xyxy, nwd_matrix, xyxy_to_cxcywh


def jitter_boxes(
    boxes_xyxy: np.ndarray,
    rng: np.random.Generator,
    copies: int,
    scale: float = 0.2,
    shift: float = 0.25,
    side: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``copies`` jittered boxes per input box (formulas in the module docstring).

    Args:
        boxes_xyxy: ``[N, 4]`` GT boxes ``x1, y1, x2, y2``.
        rng: seeded numpy generator (the only source of randomness).
        copies: jittered boxes per GT box.
        scale: largest relative size change (0.2 = ±20 %).
        shift: largest centre shift per axis as a fraction of the jittered box's side.
        side: when given, square boxes of this side (times ``1 ± scale``) around the shifted
            centre; otherwise the GT's own width and height are scaled.

    Returns:
        ``(boxes [N * copies, 4], source [N * copies])``: the jittered boxes (float64) and the
        index of the GT box each came from, in GT order.
    """
    if copies < 0:
        raise ValueError(f"copies must be non-negative, got {copies}")
    if not 0.0 <= scale < 1.0:
        raise ValueError(f"scale must be in [0, 1), got {scale}")
    if not (0.0 <= shift and math.isfinite(shift)):
        raise ValueError(f"shift must be a finite number >= 0, got {shift}")
    if side is not None and not side > 0:
        raise ValueError(f"side must be positive, got {side}")
    gt = xyxy_to_cxcywh(np.asarray(boxes_xyxy, dtype=np.float64).reshape(-1, 4))
    source = np.repeat(np.arange(gt.shape[0]), copies)
    base = gt[source]
    n = source.size
    s = rng.uniform(-scale, scale, size=(n, 2))
    if side is not None:
        s[:, 1] = s[:, 0]
        base[:, 2:] = side
    size = base[:, 2:] * (1.0 + s)
    centre = base[:, :2] + rng.uniform(-shift, shift, size=(n, 2)) * size
    return cxcywh_to_xyxy(np.concatenate([centre, size], axis=1)), source


@dataclass(frozen=True)
class Assignment:
    """Result of :func:`assign_by_nwd` for ``N`` proposals.

    ``gt_index[i]`` is the GT box with the highest NWD to proposal ``i`` (-1 when there is no GT),
    ``nwd[i]`` that NWD (0 without GT), ``positive[i]`` whether ``nwd[i] >= pos_threshold``.
    """

    gt_index: np.ndarray
    nwd: np.ndarray
    positive: np.ndarray


def assign_by_nwd(
    proposals_xyxy: np.ndarray,
    gt_xyxy: np.ndarray,
    pos_threshold: float = 0.4,
    constant: float = NWD_CONSTANT,
) -> Assignment:
    """Give each proposal its best GT by NWD; positive when ``NWD >= pos_threshold``.

    Ties between GT boxes go to the lower GT index.
    """
    p = np.asarray(proposals_xyxy, dtype=np.float64).reshape(-1, 4)
    g = np.asarray(gt_xyxy, dtype=np.float64).reshape(-1, 4)
    if g.shape[0] == 0 or p.shape[0] == 0:
        n = p.shape[0]
        return Assignment(np.full(n, -1, np.int64), np.zeros(n), np.zeros(n, bool))
    sim = nwd_matrix(p, g, constant)
    best = sim.argmax(axis=1)
    nwd = sim[np.arange(p.shape[0]), best]
    return Assignment(best.astype(np.int64), nwd, nwd >= pos_threshold)


def hardest_negatives(
    negative_logits: Tensor, num_positives: int, ratio: int = 3, min_negatives: int = 16
) -> Tensor:
    """Indices of the negatives that enter the loss, highest logit first.

    ``negative_logits`` is ``[M]`` (one score per negative, e.g. its largest class logit) or
    ``[M, C]`` (reduced by max over classes). Keeps ``k = ratio * num_positives`` negatives, or
    ``k = min_negatives`` when ``num_positives == 0``; all of them when ``M <= k``.
    """
    if num_positives < 0 or ratio < 0 or min_negatives < 0:
        raise ValueError("num_positives, ratio and min_negatives must be non-negative")
    scores = negative_logits.detach()
    if scores.ndim == 2:
        scores = scores.amax(dim=1)
    k = ratio * num_positives if num_positives > 0 else min_negatives
    k = min(k, int(scores.shape[0]))
    if k == 0:
        return torch.zeros(0, dtype=torch.long)
    return torch.topk(scores, k, largest=True, sorted=True).indices


#: Context crops are squares of this many times S at most: the widest crop inference cuts
#: (:data:`sarmission.perception.types.MAX_CROP_SCALE`).
CONTEXT_MAX_SCALE = 8.0
#: ... and of twice S at least: the first wider crop of the default crop scales.
CONTEXT_MIN_SCALE = 2.0


def context_boxes(
    boxes_xyxy: np.ndarray, rng: np.random.Generator, copies: int, side: float
) -> tuple[np.ndarray, np.ndarray]:
    """``copies`` wide squares per box larger than ``side`` (a proposal's S) on either axis,
    the way inference's wider crops see a large object: centred on a random point of the box's
    central 70 % (a proposal lands on part of a boat, not on its centre), of side
    ``max(w, h) * U(1.2, 2.5)`` clipped to ``[2, 8] * side`` (the wider crop scales).

    Returns ``(boxes [K, 4] xyxy, source [K])`` as :func:`jitter_boxes`; boxes that fit in a
    proposal get none (the S-sized jittered samples cover them)."""
    if copies < 0:
        raise ValueError(f"copies must be non-negative, got {copies}")
    if not side > 0:
        raise ValueError(f"side must be positive, got {side}")
    gt = xyxy_to_cxcywh(np.asarray(boxes_xyxy, dtype=np.float64).reshape(-1, 4))
    large = np.flatnonzero(np.maximum(gt[:, 2], gt[:, 3]) > side)
    source = np.repeat(large, copies)
    base = gt[source]
    n = source.size
    extent = np.maximum(base[:, 2], base[:, 3]) * rng.uniform(1.2, 2.5, n)
    square = np.clip(extent, CONTEXT_MIN_SCALE * side, CONTEXT_MAX_SCALE * side)
    centre = base[:, :2] + rng.uniform(-0.35, 0.35, (n, 2)) * base[:, 2:]
    sizes = np.repeat(square[:, None], 2, axis=1)
    return cxcywh_to_xyxy(np.concatenate([centre, sizes], axis=1)), source


def context_negative_boxes(
    shape: tuple[int, int],
    targets_xyxy: np.ndarray,
    count: int,
    side: float,
    rng: np.random.Generator,
    tries: int = 4,
) -> np.ndarray:
    """Up to ``count`` squares of side ``side * 2^U(1, 3)`` (the wider crops' sides, log-uniform)
    inside a frame of ``shape`` (height, width), none holding the centre of a box of
    ``targets_xyxy`` ``[M, 4]``: what a wide crop of open background looks like, so that a
    wide crop is not learnt as the sign of a large object. ``[K, 4]`` xyxy, ``K <= count``."""
    height, width = shape
    if count <= 0:
        return np.zeros((0, 4))
    n = count * tries
    sides = side * np.exp2(rng.uniform(1.0, 3.0, n))
    half = sides / 2
    fits = (2 * half <= width) & (2 * half <= height)
    cx = half + rng.uniform(0.0, 1.0, n) * np.maximum(width - 2 * half, 0.0)
    cy = half + rng.uniform(0.0, 1.0, n) * np.maximum(height - 2 * half, 0.0)
    boxes = np.stack([cx - half, cy - half, cx + half, cy + half], axis=1)
    t = np.asarray(targets_xyxy, dtype=np.float64).reshape(-1, 4)
    if len(t):
        tx = (t[:, 0] + t[:, 2]) / 2
        ty = (t[:, 1] + t[:, 3]) / 2
        holds = (
            (tx[None, :] >= boxes[:, :1])
            & (tx[None, :] <= boxes[:, 2:3])
            & (ty[None, :] >= boxes[:, 1:2])
            & (ty[None, :] <= boxes[:, 3:4])
        ).any(axis=1)
        fits &= ~holds
    return boxes[fits][:count]
