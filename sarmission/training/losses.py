"""Loss of the MITE-Net head (paper section 3.4).

For a batch with positives ``P`` (``N_pos = |P|``) and negatives, the sampled set ``S`` is ``P``
plus the ``3 N_pos`` negatives with the highest logit (:func:`~.sampling.hardest_negatives`)::

    L = 1.0 * L_cls + 5.0 * L_nwd + 0.5 * L_dfl

    L_cls = 1 / max(N_pos, 1) * sum_{i in S} sum_c BCE(z_ic, y_ic)
            BCE(z, y) = -[y log sigmoid(z) + (1 - y) log(1 - sigmoid(z))]
            y_ic = 1 when proposal i is a positive of class c, else 0 (one-hot; multi-label BCE)
    L_nwd = 1 / N_pos * sum_{i in P} (1 - NWD(pred_i, gt_i))
    L_dfl = 1 / N_pos * sum_{i in P} sum_{e in l,t,r,b}
            -[(d_{k+1} - d) log S_k + (d - d_k) log S_{k+1}],   k = floor(d), d_k = k
            d = clamp(target distance of edge e, 0, reg_max - 0.01),  S = softmax(bin logits)

Distances are in crop pixels from the crop centre (what :func:`~sarmission.perception.head.
ltrb_to_boxes` decodes). The NWD is computed in full-resolution pixels: a crop pixel is
``scale = (sx, sy)`` full-resolution pixels (proposal side / crop size), and for distances
``(l, t, r, b)`` the box relative to the crop centre is::

    cx = (r - l) / 2 * sx,   cy = (b - t) / 2 * sy,   w = (l + r) * sx,   h = (t + b) * sy
    NWD = exp(-sqrt(dcx^2 + dcy^2 + (dw^2 + dh^2) / 4 + eps) / C),   C = 12.8

The NWD target uses the unclamped distances (a GT edge beyond the bins still pulls the box);
with no positive in the batch ``L_nwd = L_dfl = 0``.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import Tensor

from sarmission.boxes import NWD_CONSTANT
from sarmission.training.sampling import hardest_negatives

_SQRT_EPS = 1e-7


@dataclass(frozen=True)
class LossWeights:
    """Weights of the three terms and the negative sampling (paper defaults)."""

    cls: float = 1.0
    nwd: float = 5.0
    dfl: float = 0.5
    neg_ratio: int = 3
    min_negatives: int = 16


@dataclass(frozen=True)
class LossTerms:
    """The weighted total (to back-propagate) and its unweighted parts."""

    total: Tensor
    cls: Tensor
    nwd: Tensor
    dfl: Tensor
    num_pos: int
    num_neg: int


def dfl_loss(bin_logits: Tensor, target: Tensor, reg_max: int) -> Tensor:
    """Distribution Focal Loss summed over the 4 edges → ``[P]``.

    ``bin_logits [P, 4, reg_max + 1]``, ``target [P, 4]`` in bins, clamped to
    ``[0, reg_max - 0.01]``; ``-[(k + 1 - d) log S_k + (d - k) log S_{k+1}]`` with ``k = floor(d)``.
    """
    d = target.clamp(0.0, reg_max - 0.01)
    left = d.floor().long()
    w_left = left.float() + 1.0 - d
    log_p = F.log_softmax(bin_logits, dim=-1)
    lp_left = log_p.gather(-1, left[..., None])[..., 0]
    lp_right = log_p.gather(-1, (left + 1)[..., None])[..., 0]
    return -(w_left * lp_left + (1.0 - w_left) * lp_right).sum(dim=-1)


def ltrb_nwd(pred: Tensor, target: Tensor, scale: Tensor, constant: float = NWD_CONSTANT) -> Tensor:
    """NWD ``[P]`` between boxes given as ``l, t, r, b`` from a common centre, ``[P, 4]`` each,
    with ``scale [P, 2]`` full-resolution pixels per crop pixel (formula in the module docstring).
    """
    sx, sy = scale[:, 0], scale[:, 1]

    def cxcywh(b: Tensor) -> tuple[Tensor, Tensor, Tensor, Tensor]:
        left, top, right, bottom = b.unbind(dim=1)
        return (
            (right - left) * 0.5 * sx,
            (bottom - top) * 0.5 * sy,
            (left + right) * sx,
            (top + bottom) * sy,
        )

    pcx, pcy, pw, ph = cxcywh(pred)
    gcx, gcy, gw, gh = cxcywh(target)
    w2 = (pcx - gcx) ** 2 + (pcy - gcy) ** 2 + ((pw - gw) ** 2 + (ph - gh) ** 2) / 4.0
    return torch.exp(-torch.sqrt(w2 + _SQRT_EPS) / constant)


def head_loss(
    cls_logits: Tensor,
    bin_logits: Tensor,
    ltrb: Tensor,
    labels: Tensor,
    target_ltrb: Tensor,
    scale: Tensor,
    weights: LossWeights | None = None,
) -> LossTerms:
    """The head loss of one batch (module docstring), with hard negative mining inside.

    Args:
        cls_logits: ``[N, C]`` class logits.
        bin_logits: ``[N, 4, reg_max + 1]`` DFL logits.
        ltrb: ``[N, 4]`` decoded distances (crop pixels).
        labels: ``[N]`` class index of positives, -1 for negatives.
        target_ltrb: ``[N, 4]`` GT distances (crop pixels; rows of negatives are ignored).
        scale: ``[N, 2]`` full-resolution pixels per crop pixel.
        weights: term weights and sampling ratio.
    """
    w = weights or LossWeights()
    pos = labels >= 0
    pos_idx = torch.nonzero(pos).flatten()
    neg_idx = torch.nonzero(~pos).flatten()
    n_pos = int(pos_idx.numel())
    neg_keep = neg_idx[hardest_negatives(cls_logits[neg_idx], n_pos, w.neg_ratio, w.min_negatives)]
    sampled = torch.cat([pos_idx, neg_keep])
    y = torch.zeros_like(cls_logits[sampled])
    y[torch.arange(n_pos), labels[pos_idx]] = 1.0
    bce = F.binary_cross_entropy_with_logits(cls_logits[sampled], y, reduction="sum")
    l_cls = bce / max(n_pos, 1)
    if n_pos:
        reg_max = bin_logits.shape[-1] - 1
        l_nwd = (1.0 - ltrb_nwd(ltrb[pos_idx], target_ltrb[pos_idx], scale[pos_idx])).mean()
        l_dfl = dfl_loss(bin_logits[pos_idx], target_ltrb[pos_idx], reg_max).mean()
    else:
        l_nwd = l_dfl = cls_logits.sum() * 0.0
    total = w.cls * l_cls + w.nwd * l_nwd + w.dfl * l_dfl
    return LossTerms(
        total, l_cls.detach(), l_nwd.detach(), l_dfl.detach(), n_pos, int(neg_keep.numel())
    )
