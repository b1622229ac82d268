"""Motion-enhanced crops for the MITE-Net head (paper section 3.1, "TTM Motion-Enhanced Crop").

RoIAlign (``aligned=True`` convention) is done with ``torch.nn.functional.grid_sample`` on a
sampling grid built here. Coordinates are continuous pixel coordinates in which pixel ``j`` of a
map covers ``[j, j + 1)``: a box ``[x1, y1, x2, y2]`` in full-resolution pixels maps to
``x * spatial_scale`` on the sampled map, and bin ``i`` of ``S`` samples at continuous
``x1' + (i + 0.5) * (x2' - x1') / S``, i.e. at array index ``x1' - 0.5 + (i + 0.5) * bin``.
On a map pooled by ``ds`` (``spatial_scale = 1/ds``), map pixel ``j`` is centred at
``(j + 0.5) * ds - 0.5`` in full-resolution array indices, so the same box lands on the same
content in the colour crop and in the 1/ds motion crops.

Speed: nothing is converted at full resolution. For each box a small window (the sampled
footprint plus the bilinear neighbours) is gathered with numpy fancy indexing, the windows are
stacked and only that stack goes through ``grid_sample``. Pixels outside the map read as 0 (zero
padding), exactly as ``grid_sample(full_map, grid, padding_mode="zeros", align_corners=False)``
would on the whole map.

Head input channels (``[N, 4, S, S]`` float32):

* 0..2: the colour crop in **RGB** order (the BGR frame's channels reversed), scaled to [0, 1]
  by /255;
* 3: the enhanced response ``E = V + p * L_on + (1 - p) * L_off`` where ``L_on = max(L, 0)``,
  ``L_off = max(-L, 0)`` and each of ``V``, ``L_on``, ``L_off`` is divided by its own max-abs over
  the crop (a crop whose max is 0 stays 0), ``p`` the proposal polarity (1 = ON). E lies in [-1, 2].
"""

from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor

from sarmission.perception.types import MotionMaps

CROP_SIZE = 16


def _sample_coords(lo: np.ndarray, hi: np.ndarray, output_size: int, ratio: int) -> np.ndarray:
    """Sample positions (array-index coords) ``[N, output_size * ratio]`` of RoIAlign bins."""
    bin_size = (hi - lo) / output_size
    steps = (np.arange(output_size * ratio, dtype=np.float64) + 0.5) / ratio
    return lo[:, None] - 0.5 + steps[None, :] * bin_size[:, None]


def _adaptive_ratio(boxes: np.ndarray, output_size: int) -> int:
    """torchvision's adaptive sampling ratio ``ceil(side / output_size)``, one for the batch."""
    side = float(np.max(np.maximum(boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1])))
    return max(1, math.ceil(side / output_size - 1e-3))


def _roi_geometry(boxes: np.ndarray, height: int, width: int, output_size: int,
                  ratio: int) -> tuple[np.ndarray, np.ndarray | None, Tensor]:
    """Windows and sampling grid for boxes already scaled onto a ``height x width`` map.

    Returns the flat pixel index of every window pixel ``[N, K, K]`` (clipped into the map), the
    in-map mask ``[N, K, K]`` (``None`` when every window lies inside) and the ``grid_sample`` grid
    ``[N, S * ratio, S * ratio, 2]`` in the windows' normalised coordinates (align_corners=False).
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
    n, m = sx.shape
    grid = np.empty((n, m, m, 2), dtype=np.float32)
    grid[..., 0] = ((2.0 * (sx - x0[:, None]) + 1.0) / k - 1.0)[:, None, :]
    grid[..., 1] = ((2.0 * (sy - y0[:, None]) + 1.0) / k - 1.0)[:, :, None]
    return flat, mask, torch.from_numpy(grid)


def _sample(windows: np.ndarray, mask: np.ndarray | None, grid: Tensor, ratio: int) -> Tensor:
    """Bilinear-sample windows ``[N, K, K, C]`` on ``grid``, averaging ``ratio**2`` samples."""
    if mask is not None:
        windows = windows * mask[..., None].astype(windows.dtype)
    t = torch.from_numpy(np.ascontiguousarray(windows, dtype=np.float32)).permute(0, 3, 1, 2)
    out = F.grid_sample(t, grid, mode="bilinear", padding_mode="zeros", align_corners=False)
    return F.avg_pool2d(out, ratio) if ratio > 1 else out


def roi_align(image: np.ndarray, boxes: np.ndarray, output_size: int = CROP_SIZE,
              spatial_scale: float = 1.0, sampling_ratio: int | None = None) -> Tensor:
    """RoIAlign (aligned=True) of an ``[H, W]`` or ``[H, W, C]`` array → float32 ``[N, C, S, S]``.

    ``boxes`` are ``[N, 4]`` ``x1, y1, x2, y2`` in the coordinates that ``spatial_scale`` maps onto
    ``image``. Each output bin averages ``sampling_ratio**2`` bilinear samples; ``None`` picks
    ``ceil(largest box side on the map / output_size)`` for the whole batch (torchvision's adaptive
    rule, shared by all boxes). Values keep the image's units (uint8 → 0..255 as float).
    """
    img = image if image.ndim == 3 else image[:, :, None]
    h, w, c = img.shape
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4) * spatial_scale
    if b.shape[0] == 0:
        return torch.zeros((0, c, output_size, output_size), dtype=torch.float32)
    ratio = sampling_ratio or _adaptive_ratio(b, output_size)
    flat, mask, grid = _roi_geometry(b, h, w, output_size, ratio)
    return _sample(img.reshape(h * w, c)[flat], mask, grid, ratio)


def _normalise_max_abs(x: Tensor) -> Tensor:
    """Divide each crop ``[N, S, S]`` by its max-abs; all-zero crops stay zero."""
    m = x.abs().amax(dim=(1, 2), keepdim=True)
    return x / torch.where(m > 0, m, torch.ones_like(m))


def enhanced_response(l_crop: Tensor, v_crop: Tensor, polarity: np.ndarray | Tensor) -> Tensor:
    """``E = V/max|V| + p * L_on/max(L_on) + (1 - p) * L_off/max(L_off)``, crops ``[N, S, S]``."""
    p = torch.as_tensor(np.asarray(polarity, dtype=np.float32)).reshape(-1, 1, 1)
    l_on = _normalise_max_abs(torch.clamp(l_crop, min=0.0))
    l_off = _normalise_max_abs(torch.clamp(-l_crop, min=0.0))
    return _normalise_max_abs(v_crop) + p * l_on + (1.0 - p) * l_off


def motion_enhanced_crops(frame_bgr: np.ndarray, motion: MotionMaps, boxes: np.ndarray,
                          polarity: np.ndarray, output_size: int = CROP_SIZE,
                          sampling_ratio: int | None = None) -> Tensor:
    """Head input ``[N, 4, S, S]``: RGB crop in [0, 1] from the full-resolution BGR uint8 frame and
    the enhanced response E from ``motion.temporal_change`` (L) and ``motion.response`` (V) at 1/ds.

    ``boxes`` ``[N, 4]`` are full-resolution ``x1, y1, x2, y2``; ``polarity`` ``[N]`` is 1 for ON.
    """
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 4)
    if b.shape[0] == 0:
        return torch.zeros((0, 4, output_size, output_size), dtype=torch.float32)
    bgr = roi_align(frame_bgr, b, output_size, 1.0, sampling_ratio)
    rgb = bgr.flip(1) * (1.0 / 255.0)
    bm = b / motion.ds
    ratio = sampling_ratio or _adaptive_ratio(bm, output_size)
    h, w = motion.response.shape
    flat, mask, grid = _roi_geometry(bm, h, w, output_size, ratio)
    lv = np.stack([motion.temporal_change.reshape(-1)[flat], motion.response.reshape(-1)[flat]], -1)
    lv_crop = _sample(lv, mask, grid, ratio)
    e = enhanced_response(lv_crop[:, 0], lv_crop[:, 1], polarity)
    return torch.cat([rgb, e[:, None]], dim=1)


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
