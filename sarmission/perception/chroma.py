"""Chromatic anomaly map: where a frame's colour stands out from its neighbourhood.

vSTMD only sees motion relative to the background, so a person who drifts with the water (the
camera's motion compensated away) and is larger than the lobula's preferred size leaves little or
no response. Colour is the other cue searchers use: skin, hair, clothing and life jackets differ in
hue from water, while foam, glint and wave shading are nearly achromatic. This map scores that
difference as a local anomaly in the chroma plane (an isotropic form of the Reed-Xiaoli detector
used on search-and-rescue imagery), computed on a 1/8-resolution copy of the frame::

    S  = pool_8(I)                           (uint8 BGR 8 x 8 block means: three exact 2x
                                             INTER_AREA halvings, the first shared with vSTMD)
    c  = (Cr, Cb)(S)                         (OpenCV YCrCb, 8-bit units, computed in float32)
    m  = box_w(c)                            (the local mean chroma, w x w window)
    V  = box_w(|c - m|^2) + floor            (its typical squared deviation)
    A  = max over the 8 x 8 windows W centred in the block of |c(W) - m|^2 / V

``A`` is about 1 where the chroma varies as much as around it and large where one small patch
differs from its surroundings. Intensity is left out on purpose: brightness anomalies on the sea
are mostly foam and glint. Pixel ``(i, j)`` of the map stands for the frame block
``i*8 .. i*8+7, j*8 .. j*8+7``, like a vSTMD map at ds 8 (the last ``H % 8`` rows and ``W % 8``
columns are ignored); ``m`` and ``V`` are per block, but the windows lie on a 4-px grid (the
block itself and the windows 4 px up, left, or both, from 4 x 4 block means), so a target that a
block edge cuts in two still fills one window.

Reading a 4K frame (25 MB) costs more than the rest of the map, so the first halving is the
frame's :func:`~sarmission.perception.pyramid.half_resolution`, which
:class:`~sarmission.perception.mitenet.MiteNet` computes once for vSTMD and this map. What the
map reaches and costs: docs/experiments.md.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from sarmission.perception.pyramid import half_resolution, halve
from sarmission.yuv import YuvImage, picture_size

#: Pooling factor of the chroma map (full-resolution pixels per map pixel).
CHROMA_SCALE = 8

#: ``(rows, cols)`` of the 4 x 4 block grid to the ``(Cr, Cb)`` float32 planes of the 8 x 8 block
#: means of that part of it.
BlockChroma = Callable[[slice, slice], list]


@dataclass(frozen=True)
class ChromaParams:
    """Window ``w`` (map pixels, odd; 15 map px = 120 full-resolution px) and the variance
    ``floor`` (squared 8-bit chroma units) that keeps flat regions from dividing by zero."""

    window: int = 15
    floor: float = 1.0

    def __post_init__(self) -> None:
        if self.window < 3 or self.window % 2 == 0:
            raise ValueError(f"window must be an odd number >= 3, got {self.window}")
        if not self.floor > 0:
            raise ValueError(f"floor must be positive, got {self.floor}")


def _quarter(frame_bgr: np.ndarray, half: np.ndarray | None = None) -> np.ndarray:
    """``frame_bgr``'s 4 x 4 block means (uint8 BGR), from ``half`` when given."""
    h, w = frame_bgr.shape[0] // CHROMA_SCALE, frame_bgr.shape[1] // CHROMA_SCALE
    if h < 1 or w < 1:
        raise ValueError(
            f"frame {frame_bgr.shape[1]}x{frame_bgr.shape[0]} is smaller than the "
            f"chroma scale {CHROMA_SCALE}"
        )
    return halve((half if half is not None else half_resolution(frame_bgr))[: 4 * h, : 4 * w], 1)


def pooled_colour(frame_bgr: np.ndarray, half: np.ndarray | None = None) -> np.ndarray:
    """``frame_bgr`` reduced by :data:`CHROMA_SCALE` (8) to 8 x 8 block means (uint8), from
    ``half`` = :func:`~sarmission.perception.pyramid.half_resolution` of the frame when given."""
    return halve(_quarter(frame_bgr, half), 1)


def chroma_anomaly(
    frame_bgr: np.ndarray | YuvImage,
    params: ChromaParams | None = None,
    half: np.ndarray | None = None,
) -> np.ndarray:
    """Chromatic anomaly map ``A`` (float32, ``H // 8 x W // 8``) of a BGR uint8 frame (``half``:
    its :func:`~sarmission.perception.pyramid.half_resolution`, when already computed), or of a
    :class:`~sarmission.yuv.YuvImage`, whose 4:2:0 U and V planes are already the half-resolution
    chroma (rescaled to ``BGR2YCrCb``'s units: the same map, to within rounding)."""
    if isinstance(frame_bgr, YuvImage):
        shape, planes_at = _yuv_blocks(frame_bgr)
    else:
        if not (
            isinstance(frame_bgr, np.ndarray)
            and frame_bgr.ndim == 3
            and frame_bgr.shape[2] == 3
            and frame_bgr.dtype == np.uint8
        ):
            raise ValueError("frame must be BGR uint8 [H, W, 3]")
        quarter = _quarter(frame_bgr, half)

        def planes_at(rows: slice, cols: slice) -> list[np.ndarray]:
            return _chroma_planes(halve(quarter[rows, cols], 1))

        shape = quarter.shape[:2]
    return _anomaly(shape, planes_at, params or ChromaParams())


def _yuv_blocks(image: YuvImage) -> tuple[tuple[int, int], BlockChroma]:
    """The 4 x 4 block grid of a YUV picture and its :data:`BlockChroma` (U and V are pooled
    one plane at a time: OpenCV's fast 2x area path takes one, three or four channels)."""
    h, w = image.height // CHROMA_SCALE, image.width // CHROMA_SCALE
    if h < 1 or w < 1:
        raise ValueError(
            f"frame {image.width}x{image.height} is smaller than the chroma scale {CHROMA_SCALE}"
        )
    u, v = (halve(plane[: 4 * h, : 4 * w], 1) for plane in (image.u, image.v))

    def planes_at(rows: slice, cols: slice) -> list[np.ndarray]:
        return list(image.to_crcb(halve(u[rows, cols], 1), halve(v[rows, cols], 1)))

    return (2 * h, 2 * w), planes_at


def _anomaly(shape: tuple[int, int], planes_at: BlockChroma, p: ChromaParams) -> np.ndarray:
    """The map from a picture's 4 x 4 block grid of ``shape`` and its ``planes_at``."""
    window = (p.window, p.window)
    border = cv2.BORDER_REFLECT_101
    chroma = planes_at(slice(0, shape[0]), slice(0, shape[1]))
    means = [cv2.boxFilter(plane, -1, window, borderType=border) for plane in chroma]
    energy = _deviation_energy(chroma, means)
    local = cv2.boxFilter(energy, -1, window, borderType=border)
    local += np.float32(p.floor)
    anomaly = cv2.divide(energy, local, dst=energy)
    # The 8 x 8 windows 4 px down, right, or both: a target cut by a block edge fills one of them.
    for dy, dx in ((1, 0), (0, 1), (1, 1)):
        shifted = planes_at(slice(dy, shape[0] - dy), slice(dx, shape[1] - dx))
        # Window k of the shifted grid is centred on the top / left edge of block k + 1.
        blocks_at = (slice(dy, None), slice(dx, None))
        shifted_energy = _deviation_energy(shifted, [mean[blocks_at] for mean in means])
        cv2.max(
            anomaly[blocks_at], cv2.divide(shifted_energy, local[blocks_at]), dst=anomaly[blocks_at]
        )
    return anomaly


def _chroma_planes(bgr: np.ndarray) -> list[np.ndarray]:
    """The Cr and Cb planes (float32, 8-bit units) of a BGR uint8 image."""
    ycc = cv2.cvtColor(bgr, cv2.COLOR_BGR2YCrCb)
    return [cv2.extractChannel(ycc, channel).astype(np.float32) for channel in (1, 2)]


def _deviation_energy(planes: list[np.ndarray], means: list[np.ndarray]) -> np.ndarray:
    """``sum_c (plane_c - mean_c)^2`` over the chroma planes."""
    energy = None
    for plane, mean in zip(planes, means, strict=True):
        deviation = cv2.subtract(plane, mean)
        if energy is None:
            energy = cv2.multiply(deviation, deviation)
        else:
            cv2.accumulateSquare(deviation, energy)
    return energy


def chroma_applies(height: int, width: int) -> bool:
    """Whether a ``height x width`` frame is large enough for a chroma map (one map pixel)."""
    return min(height, width) >= CHROMA_SCALE


def chroma_if_wanted(
    frame_bgr: np.ndarray | YuvImage, wanted: bool, half: np.ndarray | None = None
) -> np.ndarray | None:
    """:func:`chroma_anomaly` of the frame when ``wanted`` and :func:`chroma_applies`, else
    ``None`` (no colour proposals)."""
    if not (wanted and chroma_applies(*picture_size(frame_bgr))):
        return None
    return chroma_anomaly(frame_bgr, half=half)


def chroma_flops(height: int, width: int) -> int:
    """Operations per frame after the shared half-resolution frame: pooling 3 channels x (4/3)
    per half-resolution px (a 2x2 mean per output pixel of each halving), then per map px YCrCb
    12, the two running-sum box means 2 x 4, deviations 2, energy 3, local box 4 and the floor
    and divide 2."""
    maps = (height // CHROMA_SCALE) * (width // CHROMA_SCALE)
    return int(height * width // 4 * 4 + maps * (12 + 8 + 2 + 3 + 4 + 2))
