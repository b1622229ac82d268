"""How large the object under a detection is, measured against its surroundings.

The head boxes what fits in its 16 x 16 crop: its boxes are never more than about twice the
crop's side (~31 px at the first scale), so a boat 150 px long that the head calls a swimmer
gets a person-sized box, and a size gate on that box cannot tell it from a person.
:func:`object_extent` measures the object itself: in a square window around the detection, the
pixels whose colour (CIE Lab) lies more than ``threshold`` robust standard deviations from the
window's border band, closed over small gaps; the connected region that covers most of the
detection's box is the object. The window grows (doubling) while the region, or another
background, reaches its edge; windows wider than 256 px are sampled, at a cost that stays that
of a 256 px window.

The measurement refuses (None) rather than guess when its premise fails: the border band is
still not one background (more than ``max_border_share`` of it stands out, e.g. a road's edge
through grass) or the region still reaches the window's edge when the window is ``max_half_px``
or meets the frame's edge (what lies beyond is unknown), or nothing under the box stands out.
The region holds what differs from the background next to it: a person's shadow, splash or
ring of disturbed water counts with the person, a boat's crew against its deck is measured as
the crew.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from sarmission.perception import kernels
from sarmission.yuv import YuvImage, picture_size

#: Robust standard deviations (1.4826 x MAD per Lab channel) from the border's median.
DEFAULT_THRESHOLD = 3.5
#: The first window's half side in pixels (at least twice the box's longer side).
DEFAULT_MIN_HALF_PX = 64
#: The largest window's half side in pixels.
DEFAULT_MAX_HALF_PX = 512
#: Share of the border band that may stand out before the background counts as mixed.
DEFAULT_MAX_BORDER_SHARE = 0.1
#: Windows wider than twice this are sampled every (half // this)-th pixel: a window's cost
#: stays that of a (2 x this) px square, and objects that need it are large.
SAMPLED_HALF_PX = 128
#: Lab units added to each channel's spread: a flat background does not make noise an object.
SPREAD_FLOOR = 3.0
#: Result codes of :func:`sarmission.perception.extent_kernels.region` (its ``NOTHING`` and
#: ``MIXED``), spelled here so that this module never imports numba.
_NOTHING, _MIXED = 0, 1


def _window_bgr(
    picture: np.ndarray | YuvImage, x0: int, y0: int, x1: int, y1: int, step: int
) -> np.ndarray:
    """Every ``step``-th pixel of the window, as BGR."""
    if isinstance(picture, YuvImage):
        rows, cols = np.arange(y0, y1, step)[:, None], np.arange(x0, x1, step)[None, :]
        return picture.bgr_at(rows, cols)
    window = picture[y0:y1:step, x0:x1:step]
    if window.ndim == 2:
        return cv2.cvtColor(np.ascontiguousarray(window), cv2.COLOR_GRAY2BGR)
    return np.ascontiguousarray(window)


def _region(
    window_bgr: np.ndarray, inner: tuple[int, int, int, int], threshold: float, border_share: float
) -> tuple[tuple[int, int, int, int], bool] | bool:
    """``((x0, y0, x1, y1), touches_edge)`` of the region under ``inner`` in window pixels;
    True when the border is mixed (an object across it, or two backgrounds), False when
    nothing under ``inner`` stands out. The loop is :func:`extent_kernels.region
    <sarmission.perception.extent_kernels.region>`: the border band's robust spread per Lab
    channel, the pixels beyond ``threshold`` of it closed over one-pixel gaps, the 8-connected
    region covering most of ``inner``."""
    lab = cv2.cvtColor(window_bgr, cv2.COLOR_BGR2LAB)
    code, left, top, right, bottom, touches = kernels.extent_region(
        lab, *inner, float(threshold), SPREAD_FLOOR, float(border_share)
    )
    if code == _MIXED:
        return True
    if code == _NOTHING:
        return False
    return (int(left), int(top), int(right), int(bottom)), bool(touches)


def object_extent(
    picture: np.ndarray | YuvImage,
    box: np.ndarray | tuple[float, float, float, float],
    threshold: float = DEFAULT_THRESHOLD,
    min_half_px: int = DEFAULT_MIN_HALF_PX,
    max_half_px: int = DEFAULT_MAX_HALF_PX,
    max_border_share: float = DEFAULT_MAX_BORDER_SHARE,
) -> np.ndarray | None:
    """The ``[x1, y1, x2, y2]`` box (full-resolution pixels) of the object under the detection
    ``box`` of ``picture`` (BGR or gray uint8, or the decoder's planes), or None when it cannot
    be measured (module docstring). A box that is not finite, is empty or lies outside the
    picture gives None; a picture that is not uint8 BGR or gray raises ValueError."""
    coords = np.asarray(box, dtype=np.float64).reshape(-1)
    if coords.size != 4 or not np.isfinite(coords).all():
        return None
    x1, y1, x2, y2 = (float(v) for v in coords)
    if not isinstance(picture, YuvImage) and (
        picture.dtype != np.uint8 or picture.ndim not in (2, 3)
    ):
        raise ValueError(f"expected a uint8 image, got {picture.dtype} with shape {picture.shape}")
    height, width = picture_size(picture)
    if not (x2 > x1 and y2 > y1) or x2 <= 0 or y2 <= 0 or x1 >= width or y1 >= height:
        return None
    cx, cy = (x1 + x2) / 2, (y1 + y2) / 2
    half = max(int(min_half_px), int(math.ceil(2 * max(x2 - x1, y2 - y1))))
    while True:
        x0, y0 = int(max(0, cx - half)), int(max(0, cy - half))
        xe, ye = int(min(width, cx + half + 1)), int(min(height, cy + half + 1))
        step = max(1, half // SAMPLED_HALF_PX)
        if (xe - x0) // step < 8 or (ye - y0) // step < 8:
            return None
        inner = (
            int(max(0, math.floor(x1) - x0)) // step,
            int(max(0, math.floor(y1) - y0)) // step,
            int(min(xe - x0, math.ceil(x2) - x0 + 1) + step - 1) // step,
            int(min(ye - y0, math.ceil(y2) - y0 + 1) + step - 1) // step,
        )
        window = _window_bgr(picture, x0, y0, xe, ye, step)
        found = _region(window, inner, threshold, max_border_share)
        if found is False:
            return None
        if found is not True:
            (left, top, right, bottom), touches = found
            if not touches:
                return np.array(
                    [x0 + left * step, y0 + top * step, x0 + right * step, y0 + bottom * step],
                    np.float64,
                )
        # the object or another background reaches the window's edge: look wider
        cut = x0 == 0 or y0 == 0 or xe == width or ye == height
        if cut or half >= max_half_px:
            return None
        half = min(2 * half, int(max_half_px))


def prepare() -> None:
    """Build now what the first measurement would otherwise build mid-flight: OpenCV's Lab
    tables (about 0.17 s on first use, a stall of several frames) and the region loop."""
    lab = cv2.cvtColor(np.zeros((8, 8, 3), np.uint8), cv2.COLOR_BGR2LAB)
    kernels.extent_region(
        lab, 2, 2, 6, 6, DEFAULT_THRESHOLD, SPREAD_FLOOR, DEFAULT_MAX_BORDER_SHARE
    )


#: The first window's half side when a detection's box is fitted: a box is at most about
#: 2 S (32 px at S 16) long, so a 65 px window holds it with its background around it.
FIT_MIN_HALF_PX = 32


def fit_boxes(
    picture: np.ndarray | YuvImage, boxes: np.ndarray, max_side_px: float
) -> tuple[np.ndarray, int]:
    """``boxes`` (``[n, 4]`` xyxy) with each replaced by the object's extent under it
    (:func:`object_extent`) where that extent holds the box's centre, is longer than the box
    and at most ``max_side_px`` long; the others are kept as they are. Also returns how many
    were replaced.

    Why: the head boxes what its 16 x 16 crop shows, so a person 30-50 px long (lying on their
    back, swimming the crawl) gets a torso-sized box. The extent's cap keeps a boat, or a person
    merged with a foam streak, from widening a person's box without bound."""
    fitted = np.array(boxes, dtype=np.float32, copy=True).reshape(-1, 4)
    replaced = 0
    for i, box in enumerate(fitted):
        side = max(box[2] - box[0], box[3] - box[1])
        # A region under the box that still reaches the edge of a window this wide spans more
        # than max_side_px: looking wider could not give a box to keep.
        widest = int(math.ceil(max_side_px + side / 2))
        extent = object_extent(
            picture, box, min_half_px=min(FIT_MIN_HALF_PX, widest), max_half_px=widest
        )
        if extent is None:
            continue
        cx, cy = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2
        extent_side = max(extent[2] - extent[0], extent[3] - extent[1])
        holds_centre = extent[0] <= cx <= extent[2] and extent[1] <= cy <= extent[3]
        if holds_centre and side < extent_side <= max_side_px:
            fitted[i] = extent
            replaced += 1
    return fitted, replaced
