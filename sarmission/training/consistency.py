"""Rounding consistency: a head whose scores stay put when its input is rounded differently.

The same video decoded by two decoders (YUV planes against FFmpeg's BGR) differs by a grey level
here and there. The colour channels of a head crop barely move (one level at most), but the
motion channel E does: its temporal change is divided by the crop's own largest value, so a
level of rounding in a faint change is stretched. Measured on a ``maritime_test`` clip
(``tools/rounding_gap.py``'s): E moves by 0.016 at the median pixel, 0.16 at the 90th
percentile, up to 1; neighbouring pixels move together (correlation 0.7); the crop's largest
change is 0.27 at the median. A head's score gap between the two decodings comes almost all from
E. And the RPN's peaks move with it: a proposal of the one decoding lies a pixel or two from
the other's (up to 2.7 px on ``tests/test_yuv_video.py``'s clip); for some heads the largest
score gaps (0.3) are those of shifted proposals (identical ones stay below 0.1), for others
they sit on identical proposals (docs/generalisation_rounding.md).

:func:`rounding_perturbation` makes a copy of a batch with those kinds of change:

* the whole crop shifted by ``U(-MAX_SHIFT, MAX_SHIFT)`` px along each axis (bilinear, border
  padding), as a proposal moved by a pixel or two;
* RGB: ``x + U(-1, 1) / 255`` per value (the decoders' rounding);
* E: ``E + a * n``, ``n`` white Gaussian noise blurred with a Gaussian of sigma 1 px and scaled
  to unit deviation (smooth, as measured), ``a`` log-uniform in [0.01, 0.3] per crop (most
  crops move little, some a lot); clamped to E's range [-1, 2].

:func:`consistency_loss` is the squared difference of the class probabilities of a crop and its
copy, summed over classes and averaged over crops (stability training: the head is taught that
the copy is the same thing). ``TrainConfig.rounding_consistency`` weights it; training puts a
batch and its copy through the head together, so batch statistics cover both.
"""

from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor

#: Range of the motion channel E = V/max|V| + L terms in [0, 1] (sarmission.perception.crops).
E_RANGE = (-1.0, 2.0)
#: Per-crop amplitude of the motion channel's change, log-uniform between these.
AMPLITUDE = (0.01, 0.3)
#: Largest shift of a crop along each axis, in crop pixels (a proposal moved by rounding).
MAX_SHIFT = 2.5
_BLUR = torch.tensor([math.exp(-0.5 * i * i) for i in range(-2, 3)], dtype=torch.float32)
_BLUR = _BLUR / _BLUR.sum()


def _smooth_unit_noise(n: int, h: int, w: int, rng: np.random.Generator) -> Tensor:
    """``[n, h, w]`` Gaussian noise blurred with sigma 1 px, each map at unit deviation."""
    z = torch.from_numpy(rng.standard_normal(size=(n, 1, h + 4, w + 4)).astype(np.float32))
    z = F.conv2d(z, _BLUR.view(1, 1, 1, 5))
    z = F.conv2d(z, _BLUR.view(1, 1, 5, 1))[:, 0]
    return z / z.flatten(1).std(dim=1).clamp(min=1e-6).view(n, 1, 1)


def rounding_perturbation(crops: Tensor, rng: np.random.Generator) -> Tensor:
    """A copy of ``crops`` ``[N, 4, S, S]`` (RGB in [0, 1], then E) as another decoder's rounding
    would give it (module docstring); the input is not modified."""
    n, c, h, w = crops.shape
    shift = torch.from_numpy(rng.uniform(-MAX_SHIFT, MAX_SHIFT, size=(n, 2)).astype(np.float32))
    theta = torch.zeros(n, 2, 3)
    theta[:, 0, 0] = theta[:, 1, 1] = 1.0
    theta[:, 0, 2] = 2.0 * shift[:, 0] / w  # normalised coordinates span 2 over the crop
    theta[:, 1, 2] = 2.0 * shift[:, 1] / h
    grid = F.affine_grid(theta, [n, c, h, w], align_corners=False)
    out = F.grid_sample(crops, grid, mode="bilinear", padding_mode="border", align_corners=False)
    rgb_step = rng.uniform(-1.0, 1.0, size=(n, 3, h, w)).astype(np.float32) / 255.0
    out[:, :3] = (out[:, :3] + torch.from_numpy(rgb_step)).clamp(0.0, 1.0)
    lo, hi = math.log(AMPLITUDE[0]), math.log(AMPLITUDE[1])
    amplitude = torch.from_numpy(np.exp(rng.uniform(lo, hi, size=n)).astype(np.float32))
    change = amplitude.view(n, 1, 1) * _smooth_unit_noise(n, h, w, rng)
    out[:, 3] = (out[:, 3] + change).clamp(*E_RANGE)
    return out


def consistency_loss(cls_logits: Tensor, perturbed_logits: Tensor) -> Tensor:
    """Mean over crops of the summed squared difference of class probabilities."""
    gap = torch.sigmoid(cls_logits) - torch.sigmoid(perturbed_logits)
    return (gap * gap).sum(dim=1).mean()
