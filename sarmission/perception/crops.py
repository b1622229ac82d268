"""Motion-enhanced crops for the MITE-Net head (paper section 3.1, "TTM Motion-Enhanced Crop").

RoIAlign (``aligned=True`` convention) is bilinear sampling on a grid built here, by a small
compiled loop (:mod:`~sarmission.perception.crop_kernels`) that repeats the float32 arithmetic of
torch's CPU ``grid_sample`` (bilinear, zero padding, ``align_corners=False``) step for step,
fused multiply-adds included: the crops are bit for bit what that call gives, without torch on
the inference path.

Coordinates are continuous pixel coordinates in which pixel ``j`` of a map covers ``[j, j + 1)``:
a box ``[x1, y1, x2, y2]`` in full-resolution pixels maps to ``x * spatial_scale`` on the sampled
map, and bin ``i`` of ``S`` samples at continuous ``x1' + (i + 0.5) * (x2' - x1') / S``, i.e. at
array index ``x1' - 0.5 + (i + 0.5) * bin``. On a map pooled by ``ds`` (``spatial_scale =
1/ds``), map pixel ``j`` is centred at ``(j + 0.5) * ds - 0.5`` in full-resolution array indices,
so the same box lands on the same content in the colour crop and in the 1/ds motion crops.

Speed: nothing is converted at full resolution. For each box a small window (the sampled
footprint plus the bilinear neighbours) is gathered with numpy fancy indexing, the windows are
stacked and only that stack is sampled. Pixels outside the map read as 0 (zero padding), exactly
as ``grid_sample(full_map, grid, padding_mode="zeros", align_corners=False)`` would on the whole
map.

Head input channels (``[N, 4, S, S]`` float32):

* 0..2: the colour crop in **RGB** order (the BGR frame's channels reversed), scaled to [0, 1]
  by /255;
* 3: the enhanced response ``E = V + p * L_on + (1 - p) * L_off`` where ``L_on = max(L, 0)``,
  ``L_off = max(-L, 0)`` and each of ``V``, ``L_on``, ``L_off`` is divided by its own max-abs over
  the crop (a crop whose max is 0 stays 0), ``p`` the proposal polarity (1 = ON). E lies in [-1, 2].
  With a *motion floor* ``f > 0`` (the head's :attr:`~sarmission.perception.head_config.HeadConfig.
  motion_floor`), ``L_on`` and ``L_off`` are divided by ``max(max-abs, f)`` instead: a crop whose
  temporal change stays below ``f`` (sensor noise, compression, rounding, a still scene) keeps a
  faint E rather than having that noise stretched to full scale.
"""

from __future__ import annotations

import math

import numpy as np

from sarmission.perception import kernels
from sarmission.perception.types import MotionMaps
from sarmission.yuv import YuvImage

CROP_SIZE = 16
_ONE = np.float32(1.0)


def _sample_coords(lo: np.ndarray, hi: np.ndarray, output_size: int, ratio: int) -> np.ndarray:
    """Sample positions (array-index coords) ``[N, output_size * ratio]`` of RoIAlign bins."""
    bin_size = (hi - lo) / output_size
    steps = (np.arange(output_size * ratio, dtype=np.float64) + 0.5) / ratio
    return lo[:, None] - 0.5 + steps[None, :] * bin_size[:, None]


def _adaptive_ratio(boxes: np.ndarray, output_size: int) -> int:
    """torchvision's adaptive sampling ratio ``ceil(side / output_size)``, one for the batch."""
    side = float(np.max(np.maximum(boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1])))
    return max(1, math.ceil(side / output_size - 1e-3))


def _roi_geometry(
    boxes: np.ndarray, height: int, width: int, output_size: int, ratio: int
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, np.ndarray]:
    """Windows and sampling grid for boxes already scaled onto a ``height x width`` map.

    Returns the flat pixel index of every window pixel ``[N, K, K]`` (clipped into the map), the
    in-map mask ``[N, K, K]`` (``None`` when every window lies inside) and the grid's x and y
    ``[N, S * ratio]`` (float32) in the windows' normalised coordinates (align_corners=False),
    as ``grid_sample`` would be given them: the grid is separable, x per column, y per row.
    """
    sx = _sample_coords(boxes[:, 0], boxes[:, 2], output_size, ratio)
    sy = _sample_coords(boxes[:, 1], boxes[:, 3], output_size, ratio)
    x0 = np.floor(sx.min(axis=1)).astype(np.int64)
    y0 = np.floor(sy.min(axis=1)).astype(np.int64)
    k = int(max((np.floor(sx.max(axis=1)) - x0).max(), (np.floor(sy.max(axis=1)) - y0).max())) + 2
    xs = x0[:, None] + np.arange(k)[None, :]
    ys = y0[:, None] + np.arange(k)[None, :]
    x_ok = (xs >= 0) & (xs < width)
    y_ok = (ys >= 0) & (ys < height)
    mask = None
    if not (x_ok.all() and y_ok.all()):
        mask = y_ok[:, :, None] & x_ok[:, None, :]
        xs = np.clip(xs, 0, width - 1)
        ys = np.clip(ys, 0, height - 1)
    flat = ys[:, :, None] * width + xs[:, None, :]
    grid_x = ((2.0 * (sx - x0[:, None]) + 1.0) / k - 1.0).astype(np.float32)
    grid_y = ((2.0 * (sy - y0[:, None]) + 1.0) / k - 1.0).astype(np.float32)
    return flat, mask, grid_x, grid_y


def _sample(
    windows: np.ndarray, mask: np.ndarray | None, grid_x: np.ndarray, grid_y: np.ndarray, ratio: int
) -> np.ndarray:
    """Bilinear-sample windows ``[N, K, K, C]`` on the grid → ``[N, C, S, S]`` float32, averaging
    ``ratio**2`` samples per bin (``grid_sample`` then ``avg_pool2d``, operation for operation)."""
    if mask is not None:
        windows = windows * mask[..., None].astype(windows.dtype)
    windows = np.ascontiguousarray(windows, dtype=np.float32)
    n, m = grid_x.shape
    out = np.empty((n, windows.shape[3], m, m), np.float32)
    kernels.bilinear(windows, grid_x, grid_y, out)
    if ratio == 1:
        return out
    c = out.shape[1]
    bins = out.reshape(n, c, m // ratio, ratio, m // ratio, ratio)
    total = bins[:, :, :, 0, :, 0].copy()
    for dy in range(ratio):
        for dx in range(ratio):
            if dy or dx:
                total += bins[:, :, :, dy, :, dx]
    return total / np.float32(ratio * ratio)


def roi_align(
    image: np.ndarray | YuvImage,
    boxes: np.ndarray,
    output_size: int = CROP_SIZE,
    spatial_scale: float = 1.0,
    sampling_ratio: int | None = None,
) -> np.ndarray:
    """RoIAlign (aligned=True) of an ``[H, W]`` or ``[H, W, C]`` array → float32 ``[N, C, S, S]``.

    ``boxes`` are ``[N, 4]`` ``x1, y1, x2, y2`` in the coordinates that ``spatial_scale`` maps onto
    ``image``. Each output bin averages ``sampling_ratio**2`` bilinear samples; ``None`` picks
    ``ceil(largest box side on the map / output_size)`` for the whole batch (torchvision's adaptive
    rule, shared by all boxes). Values keep the image's units (uint8 → 0..255 as float).
    A :class:`~sarmission.yuv.YuvImage` is sampled as its BGR picture, of which only the
    windows under the boxes are converted.
    """
    if isinstance(image, YuvImage):
        h, w, c = image.height, image.width, 3
    else:
        img = image if image.ndim == 3 else image[:, :, None]
        h, w, c = img.shape
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4) * spatial_scale
    if b.shape[0] == 0:
        return np.zeros((0, c, output_size, output_size), dtype=np.float32)
    ratio = sampling_ratio or _adaptive_ratio(b, output_size)
    flat, mask, grid_x, grid_y = _roi_geometry(b, h, w, output_size, ratio)
    if isinstance(image, YuvImage):
        windows = image.bgr_at(*np.divmod(flat, w))
    else:
        windows = img.reshape(h * w, c)[flat]
    return _sample(windows, mask, grid_x, grid_y, ratio)


def _normalise_max_abs(x: np.ndarray, floor: float = 0.0) -> np.ndarray:
    """Divide each crop ``[N, S, S]`` by its max-abs, or by ``floor`` where that is larger;
    all-zero crops stay zero."""
    m = np.abs(x).max(axis=(1, 2), keepdims=True)
    if floor > 0:
        m = np.maximum(m, np.float32(floor))
    return x / np.where(m > 0, m, _ONE)


def enhanced_response(
    l_crop: np.ndarray, v_crop: np.ndarray, polarity: np.ndarray, motion_floor: float = 0.0
) -> np.ndarray:
    """``E = V/max|V| + p * L_on/max(L_on, f) + (1 - p) * L_off/max(L_off, f)``, crops
    ``[N, S, S]``, ``f`` the motion floor (0: the paper's per-crop max-abs)."""
    l_crop = np.asarray(l_crop, dtype=np.float32)
    p = np.asarray(polarity, dtype=np.float32).reshape(-1, 1, 1)
    l_on = _normalise_max_abs(np.maximum(l_crop, np.float32(0)), motion_floor)
    l_off = _normalise_max_abs(np.maximum(-l_crop, np.float32(0)), motion_floor)
    v = _normalise_max_abs(np.asarray(v_crop, dtype=np.float32))
    return v + p * l_on + (_ONE - p) * l_off


def motion_enhanced_crops(
    frame_bgr: np.ndarray | YuvImage,
    motion: MotionMaps,
    boxes: np.ndarray,
    polarity: np.ndarray,
    output_size: int = CROP_SIZE,
    sampling_ratio: int | None = None,
    motion_floor: float = 0.0,
) -> np.ndarray:
    """Head input ``[N, 4, S, S]`` (float32): RGB crop in [0, 1] from the full-resolution BGR
    uint8 frame (or a :class:`~sarmission.yuv.YuvImage`, converted under the boxes only) and the
    enhanced response E from ``motion.temporal_change`` (L) and ``motion.response`` (V) at 1/ds.

    ``boxes`` ``[N, 4]`` are full-resolution ``x1, y1, x2, y2``; ``polarity`` ``[N]`` is 1 for ON;
    ``motion_floor`` the head's motion floor (module docstring).
    """
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    if b.shape[0] == 0:
        return np.zeros((0, 4, output_size, output_size), dtype=np.float32)
    bgr = roi_align(frame_bgr, b, output_size, 1.0, sampling_ratio)
    rgb = bgr[:, ::-1] * np.float32(1.0 / 255.0)
    bm = b / motion.ds
    ratio = sampling_ratio or _adaptive_ratio(bm, output_size)
    h, w = motion.response.shape
    flat, mask, grid_x, grid_y = _roi_geometry(bm, h, w, output_size, ratio)
    lv = np.stack([motion.temporal_change.reshape(-1)[flat], motion.response.reshape(-1)[flat]], -1)
    lv_crop = _sample(lv, mask, grid_x, grid_y, ratio)
    e = enhanced_response(lv_crop[:, 0], lv_crop[:, 1], polarity, motion_floor)
    return np.concatenate([rgb, e[:, None]], axis=1)


def crop_flops(num_boxes: int, output_size: int = CROP_SIZE, sampling_ratio: int = 1) -> int:
    """Analytic FLOPs of :func:`motion_enhanced_crops` for ``num_boxes`` crops.

    Bilinear sampling costs 4 multiplies + 3 adds per sample and channel (5 channels: 3 colour,
    L, V), plus ``ratio**2`` averaging; the colour scaling 1 per value, the ON/OFF split, the three
    max-abs normalisations and the E combination about 10 per pixel.
    """
    samples = output_size * output_size * sampling_ratio * sampling_ratio
    per_box = samples * 5 * 7 + (samples if sampling_ratio > 1 else 0) * 5
    per_box += output_size * output_size * (3 + 10)
    return int(num_boxes * per_box)
