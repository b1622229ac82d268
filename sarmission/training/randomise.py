"""Crop-level domain randomisation for training the MITE-Net head.

The head's crops (``[N, 4, S, S]``: RGB in [0, 1], then the enhanced motion response E; see
:mod:`sarmission.perception.crops`) come from one renderer. So that the head learns what a person
looks like rather than how that renderer draws one, each transform below changes a random share
``probability`` of the crops of a batch, with parameters drawn per crop from a seeded
``numpy.random.Generator`` (the only source of randomness: the same generator state gives the same
output). Photometric transforms touch the RGB channels only (the motion channel is computed from
the video, not from the crop); the geometric one moves all four channels and the box targets.

Transforms (:data:`TRANSFORMS`), in the order they are applied:

* ``tone``: brightness, contrast and gamma: ``x' = clip((x - m) * c + m + b) ** g`` with ``m``
  the crop's mean, ``c, g ~ exp(U(-0.4, 0.4))``, ``b ~ U(-0.15, 0.15)``.
* ``white_balance``: a gain per channel, ``exp(U(-0.2, 0.2))`` each (colour casts of light,
  water and camera).
* ``haze`` (not in ``all``: asked for by name): veiling light that washes colours out,
  ``x' = t x + (1 - t) A`` with transmission ``t ~ U(0.5, 1)`` and a pale airlight ``A``
  (a grey level ``U(0.55, 1)`` per crop, each channel within 0.05 of it): haze, glare on the
  lens, an exposure set for a darker scene. Colours come out brighter and less saturated, which
  ``tone`` (it scales a crop about its own mean) does not reach.
* ``hue``: the chroma of each pixel (YIQ ``I, Q``) rotated by ``U(-180, 180)`` degrees, weighted
  by its saturation ``w = clip((|IQ| - 0.03) / 0.08, 0, 1)``: grey water, rock and road keep
  their colour, saturated (clothing-like) colours take any hue.
* ``blur``: separable Gaussian, sigma ``U(0.4, 1.3)`` px (defocus, haze, motion).
* ``noise``: Poisson-Gaussian sensor noise, ``sigma^2 = r^2 + k x`` with ``r ~ U(0.003, 0.03)``,
  ``k ~ U(0, 0.004)``.
* ``blocks``: compression artefacts: 4:2:0 chroma (2x2 averaged ``Cb, Cr``) and 8x8 DCT blocks
  quantised with the JPEG tables at a quality ``U(15, 75)``, on a block grid offset by 0-7 px
  (a crop does not start on the encoder's grid).
* ``geometry``: rotation by ``U(-15, 15)`` degrees and scale ``exp(U(-0.15, 0.15))`` about the
  crop centre (bilinear, border padding). A positive's ``l, t, r, b`` become the axis-aligned
  envelope of its box's corners under the same map; the crop's ``scale`` (full-resolution pixels
  per crop pixel) is unchanged, so a scaled crop stands for a larger or smaller person in the same
  proposal box.

Labels never change; negatives keep all-zero targets.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor

TRANSFORMS: tuple[str, ...] = (
    "tone",
    "white_balance",
    "haze",
    "hue",
    "blur",
    "noise",
    "blocks",
    "geometry",
)
#: Transforms that ``all`` leaves out, so that a recipe written with ``all`` trains as it did
#: before they existed (a transform draws from the generator only when it is asked for).
OPT_IN: frozenset[str] = frozenset({"haze"})
#: What ``all`` means.
ALL: tuple[str, ...] = tuple(n for n in TRANSFORMS if n not in OPT_IN)
#: Colour channels of a head crop (RGB) ...
RGB = slice(0, 3)
#: ... and its motion channel, the enhanced motion response E.
MOTION = 3


@dataclass(frozen=True)
class Randomisation:
    """Which transforms run (names from :data:`TRANSFORMS`) and on what share of the crops."""

    transforms: tuple[str, ...] = ()
    probability: float = 0.5

    def validate(self) -> None:
        """Raise ``ValueError`` for unknown transforms or a probability outside [0, 1]."""
        unknown = sorted(set(self.transforms) - set(TRANSFORMS))
        if unknown:
            raise ValueError(
                f"unknown randomisation {', '.join(unknown)}; known: {', '.join(TRANSFORMS)}"
            )
        if not 0.0 <= self.probability <= 1.0:
            raise ValueError(f"probability must be in [0, 1], got {self.probability}")

    @classmethod
    def parse(cls, text: str, probability: float = 0.5) -> Randomisation:
        """From a comma-separated list of transform names, ``none``/empty, or ``all``
        (:data:`ALL`), which may be followed by opt-in names (``all,haze``)."""
        names = [t.strip() for t in text.split(",") if t.strip()]
        if names == ["none"]:
            names = []
        elif "all" in names:
            names = [n for n in names if n != "all"] + list(ALL)
        config = cls(
            tuple(n for n in TRANSFORMS if n in names)
            + tuple(n for n in names if n not in TRANSFORMS),
            probability,
        )
        config.validate()
        return config


def _u(rng: np.random.Generator, lo: float, hi: float, n: int) -> Tensor:
    return torch.from_numpy(rng.uniform(lo, hi, size=n).astype(np.float32))


def tone(rgb: Tensor, rng: np.random.Generator) -> Tensor:
    """Brightness, contrast and gamma per crop (module docstring)."""
    n = rgb.shape[0]
    c = torch.exp(_u(rng, -0.4, 0.4, n)).view(n, 1, 1, 1)
    b = _u(rng, -0.15, 0.15, n).view(n, 1, 1, 1)
    g = torch.exp(_u(rng, -0.4, 0.4, n)).view(n, 1, 1, 1)
    m = rgb.mean(dim=(1, 2, 3), keepdim=True)
    return ((rgb - m) * c + m + b).clamp(0.0, 1.0) ** g


def white_balance(rgb: Tensor, rng: np.random.Generator) -> Tensor:
    """A gain per colour channel per crop."""
    n = rgb.shape[0]
    gains = torch.exp(torch.from_numpy(rng.uniform(-0.2, 0.2, size=(n, 3)).astype(np.float32)))
    return (rgb * gains.view(n, 3, 1, 1)).clamp(0.0, 1.0)


def haze(rgb: Tensor, rng: np.random.Generator) -> Tensor:
    """Veiling light per crop: a pale airlight mixed in (module docstring)."""
    n = rgb.shape[0]
    t = _u(rng, 0.5, 1.0, n).view(n, 1, 1, 1)
    level = _u(rng, 0.55, 1.0, n).view(n, 1, 1, 1)
    tint = torch.from_numpy(rng.uniform(-0.05, 0.05, size=(n, 3)).astype(np.float32))
    airlight = (level + tint.view(n, 3, 1, 1)).clamp(0.0, 1.0)
    return (t * rgb + (1.0 - t) * airlight).clamp(0.0, 1.0)


_RGB_TO_YIQ = torch.tensor([[0.299, 0.587, 0.114], [0.596, -0.274, -0.322], [0.211, -0.523, 0.312]])
_YIQ_TO_RGB = torch.linalg.inv(_RGB_TO_YIQ)


def hue(rgb: Tensor, rng: np.random.Generator) -> Tensor:
    """Rotate the chroma of saturated pixels (module docstring)."""
    n = rgb.shape[0]
    yiq = torch.einsum("ij,njhw->nihw", _RGB_TO_YIQ, rgb)
    angle = _u(rng, -math.pi, math.pi, n).view(n, 1, 1)
    i, q = yiq[:, 1], yiq[:, 2]
    weight = ((torch.sqrt(i * i + q * q) - 0.03) / 0.08).clamp(0.0, 1.0)
    cos, sin = torch.cos(angle), torch.sin(angle)
    i2, q2 = i * cos - q * sin, i * sin + q * cos
    out = torch.stack([yiq[:, 0], i + weight * (i2 - i), q + weight * (q2 - q)], dim=1)
    return torch.einsum("ij,njhw->nihw", _YIQ_TO_RGB, out).clamp(0.0, 1.0)


def blur(rgb: Tensor, rng: np.random.Generator) -> Tensor:
    """Separable Gaussian blur, one sigma per crop."""
    n, c, h, w = rgb.shape
    sigma = _u(rng, 0.4, 1.3, n).view(n, 1)
    offsets = torch.arange(-3, 4, dtype=torch.float32).view(1, 7)
    kernel = torch.exp(-0.5 * (offsets / sigma) ** 2)
    kernel = kernel / kernel.sum(dim=1, keepdim=True)  # [n, 7]
    x = F.pad(rgb.reshape(1, n * c, h, w), (3, 3, 3, 3), mode="replicate")
    k = kernel.repeat_interleave(c, dim=0)
    x = F.conv2d(x, k.view(n * c, 1, 1, 7), groups=n * c)
    x = F.conv2d(x, k.view(n * c, 1, 7, 1), groups=n * c)
    return x.view(n, c, h, w)


def noise(rgb: Tensor, rng: np.random.Generator) -> Tensor:
    """Poisson-Gaussian sensor noise per crop."""
    n = rgb.shape[0]
    read = _u(rng, 0.003, 0.03, n).view(n, 1, 1, 1)
    shot = _u(rng, 0.0, 0.004, n).view(n, 1, 1, 1)
    z = torch.from_numpy(rng.standard_normal(size=tuple(rgb.shape)).astype(np.float32))
    return (rgb + z * torch.sqrt(read * read + shot * rgb)).clamp(0.0, 1.0)


#: JPEG's luminance and chrominance quantisation tables (ITU-T T.81 Annex K), 0-255 units.
_Q_LUMA = torch.tensor(
    [
        [16, 11, 10, 16, 24, 40, 51, 61],
        [12, 12, 14, 19, 26, 58, 60, 55],
        [14, 13, 16, 24, 40, 57, 69, 56],
        [14, 17, 22, 29, 51, 87, 80, 62],
        [18, 22, 37, 56, 68, 109, 103, 77],
        [24, 35, 55, 64, 81, 104, 113, 92],
        [49, 64, 78, 87, 103, 121, 120, 101],
        [72, 92, 95, 98, 112, 100, 103, 99],
    ],
    dtype=torch.float32,
)
_Q_CHROMA = torch.full((8, 8), 99.0)
_Q_CHROMA[:4, :4] = torch.tensor(
    [[17, 18, 24, 47], [18, 21, 26, 66], [24, 26, 56, 99], [47, 66, 99, 99]], dtype=torch.float32
)
_DCT = torch.tensor(
    [
        [
            (math.sqrt(1 / 8) if k == 0 else math.sqrt(2 / 8))
            * math.cos(math.pi * (2 * i + 1) * k / 16)
            for i in range(8)
        ]
        for k in range(8)
    ]
)


def _quantise_blocks(plane: Tensor, table: Tensor) -> Tensor:
    """8x8 DCT, quantise with ``table`` ``[n, 8, 8]`` (0-1 units), inverse; plane ``[n, H, W]``
    with ``H, W`` multiples of 8."""
    n, h, w = plane.shape
    blocks = plane.view(n, h // 8, 8, w // 8, 8).permute(0, 1, 3, 2, 4)
    coeff = _DCT @ blocks @ _DCT.T
    t = table.view(n, 1, 1, 8, 8)
    coeff = torch.round(coeff / t) * t
    back = _DCT.T @ coeff @ _DCT
    return back.permute(0, 1, 3, 2, 4).reshape(n, h, w)


def blocks(rgb: Tensor, rng: np.random.Generator) -> Tensor:
    """4:2:0 chroma and quantised 8x8 DCT blocks on a shifted grid (module docstring)."""
    n, _, h, w = rgb.shape
    quality = _u(rng, 15.0, 75.0, n)
    factor = torch.where(quality < 50, 50.0 / quality, 2.0 - quality / 50.0).view(n, 1, 1)
    q_luma = (_Q_LUMA * factor).clamp(min=1.0) / 255.0
    q_chroma = (_Q_CHROMA * factor).clamp(min=1.0) / 255.0
    dy, dx = (int(v) for v in rng.integers(0, 8, size=2))
    ph, pw = -(-(h + dy) // 8) * 8, -(-(w + dx) // 8) * 8
    x = F.pad(rgb, (dx, pw - w - dx, dy, ph - h - dy), mode="replicate")
    r, g, b = x[:, 0], x[:, 1], x[:, 2]
    y = 0.299 * r + 0.587 * g + 0.114 * b
    cb = (b - y) * 0.564
    cr = (r - y) * 0.713
    chroma = torch.stack([cb, cr], dim=1)
    chroma = F.interpolate(F.avg_pool2d(chroma, 2), scale_factor=2, mode="nearest")
    y = _quantise_blocks(y, q_luma)
    cb = _quantise_blocks(chroma[:, 0], q_chroma)
    cr = _quantise_blocks(chroma[:, 1], q_chroma)
    r = y + cr / 0.713
    b = y + cb / 0.564
    g = (y - 0.299 * r - 0.114 * b) / 0.587
    out = torch.stack([r, g, b], dim=1)[:, :, dy : dy + h, dx : dx + w]
    return out.clamp(0.0, 1.0)


def geometry(
    crops: Tensor, ltrb: Tensor, labels: Tensor, rng: np.random.Generator
) -> tuple[Tensor, Tensor]:
    """Rotate and scale all channels about the crop centre; move positives' targets with them."""
    n, _, h, w = crops.shape
    angle = _u(rng, -math.radians(15.0), math.radians(15.0), n)
    scale = torch.exp(_u(rng, -0.15, 0.15, n))
    cos, sin = torch.cos(angle), torch.sin(angle)
    # content map A = s R(angle) (pixel axes, y down); grid_sample needs A^-1 per output point
    inverse = torch.stack([torch.stack([cos, sin], 1), torch.stack([-sin, cos], 1)], 1)
    inverse = inverse / scale.view(n, 1, 1)
    theta = torch.cat([inverse, torch.zeros(n, 2, 1)], dim=2)
    grid = F.affine_grid(theta, [n, crops.shape[1], h, w], align_corners=False)
    out = F.grid_sample(crops, grid, mode="bilinear", padding_mode="border", align_corners=False)
    left, top, right, bottom = ltrb.unbind(1)
    xs = torch.stack([-left, right, right, -left], 1)
    ys = torch.stack([-top, -top, bottom, bottom], 1)
    s, c_, si = scale.view(n, 1), cos.view(n, 1), sin.view(n, 1)
    x2 = s * (c_ * xs - si * ys)
    y2 = s * (si * xs + c_ * ys)
    moved = torch.stack([-x2.amin(1), -y2.amin(1), x2.amax(1), y2.amax(1)], dim=1)
    positive = (labels >= 0).view(n, 1)
    return out, torch.where(positive, moved, ltrb)


_PHOTOMETRIC = {
    "tone": tone,
    "white_balance": white_balance,
    "haze": haze,
    "hue": hue,
    "blur": blur,
    "noise": noise,
    "blocks": blocks,
}


def randomise_crops(
    crops: Tensor, ltrb: Tensor, labels: Tensor, config: Randomisation, rng: np.random.Generator
) -> tuple[Tensor, Tensor]:
    """Apply ``config``'s transforms to a batch: ``crops [N, 4, S, S]`` float32, ``ltrb [N, 4]``,
    ``labels [N]``. Returns new ``(crops, ltrb)``; the inputs are not modified.

    Each transform picks its crops (probability ``config.probability`` each) and then draws their
    parameters from ``rng``, in :data:`TRANSFORMS` order.
    """
    crops, ltrb = crops.clone(), ltrb.clone()
    n = crops.shape[0]
    for name in TRANSFORMS:
        if name not in config.transforms:
            continue
        chosen = torch.from_numpy(np.flatnonzero(rng.random(n) < config.probability))
        if not len(chosen):
            continue
        if name == "geometry":
            crops[chosen], ltrb[chosen] = geometry(crops[chosen], ltrb[chosen], labels[chosen], rng)
        else:
            crops[chosen, RGB] = _PHOTOMETRIC[name](crops[chosen, RGB], rng)
    return crops, ltrb
