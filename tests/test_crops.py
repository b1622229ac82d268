"""RoIAlign (bit for bit torch's grid_sample, without torch) and the motion-enhanced crops."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from sarmission.perception.crops import (
    _sample,
    crop_flops,
    enhanced_response,
    motion_enhanced_crops,
    roi_align,
)
from sarmission.perception.types import MotionMaps


def _reference(image: np.ndarray, boxes: np.ndarray, scale: float = 1.0) -> torch.Tensor:
    """grid_sample on the whole image, one box at a time (aligned=True RoIAlign, ratio 1)."""
    h, w = image.shape[:2]
    full = torch.from_numpy(image.reshape(h, w, -1).astype(np.float32)).permute(2, 0, 1)[None]
    out = []
    for x1, y1, x2, y2 in np.asarray(boxes, np.float64) * scale:
        xs = x1 - 0.5 + (np.arange(16) + 0.5) * (x2 - x1) / 16
        ys = y1 - 0.5 + (np.arange(16) + 0.5) * (y2 - y1) / 16
        gx, gy = np.meshgrid((2 * xs + 1) / w - 1, (2 * ys + 1) / h - 1)
        grid = torch.from_numpy(np.stack([gx, gy], -1)[None].astype(np.float32))
        out.append(F.grid_sample(full, grid, align_corners=False)[0])
    return torch.stack(out)


def _blob(h: int, w: int, cx: float, cy: float, sigma: float) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    return np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * sigma**2)).astype(np.float32)


def _centroid(crop: np.ndarray) -> np.ndarray:
    c = crop.astype(np.float64)
    yy, xx = np.mgrid[0 : c.shape[0], 0 : c.shape[1]]
    return np.array([(c * xx).sum(), (c * yy).sum()]) / c.sum()


def _avg_pool(a: np.ndarray, ds: int) -> np.ndarray:
    h, w = a.shape[0] // ds, a.shape[1] // ds
    return a[: h * ds, : w * ds].reshape(h, ds, w, ds).mean(axis=(1, 3)).astype(np.float32)


def test_roi_align_matches_analytic_bilinear_values():
    # f = 2x + 3y + 0.1xy + 5 is reproduced exactly by bilinear interpolation inside the image.
    yy, xx = np.mgrid[0:60, 0:80].astype(np.float64)
    image = (2 * xx + 3 * yy + 0.1 * xx * yy + 5).astype(np.float32)
    boxes = np.array([[10.0, 12.0, 26.0, 28.0], [20.3, 7.7, 44.3, 31.7], [30.0, 20.0, 38.0, 28.0]])
    crops = roi_align(image, boxes, 16, sampling_ratio=1)[:, 0]
    for crop, (x1, y1, x2, y2) in zip(crops, boxes, strict=True):
        xs = x1 - 0.5 + (np.arange(16) + 0.5) * (x2 - x1) / 16
        ys = y1 - 0.5 + (np.arange(16) + 0.5) * (y2 - y1) / 16
        gx, gy = np.meshgrid(xs, ys)
        np.testing.assert_allclose(crop, 2 * gx + 3 * gy + 0.1 * gx * gy + 5, rtol=1e-5)
    # A 16 px box at integer corners samples the pixel centres: the crop is the pixels themselves.
    np.testing.assert_allclose(crops[0], image[12:28, 10:26], rtol=1e-6)


def test_roi_align_equals_whole_image_grid_sample_including_borders():
    rng = np.random.default_rng(1)
    image = rng.random((40, 50, 3)).astype(np.float32)
    boxes = np.array(
        [
            [10, 12, 26, 28],
            [-5, -3, 11, 13],
            [40, 30, 56, 46],
            [3.3, 7.7, 19.3, 23.7],
            [-30, -30, -14, -14],
        ],
        np.float32,
    )
    got = roi_align(image, boxes, 16, sampling_ratio=1)
    # The grid is normalised to the whole image here, to each box's window in roi_align: the
    # same positions up to float32 rounding of the normalised coordinates.
    np.testing.assert_allclose(got, _reference(image, boxes).numpy(), atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize("seed", range(3))
def test_sampling_is_torch_grid_sample_bit_for_bit(seed: int):
    """The crops kernel repeats torch's float32 arithmetic: the head sees the same inputs as
    with grid_sample and avg_pool2d, so detections do not change."""
    rng = np.random.default_rng(seed)
    n, k, m, c = 40, 13, 16, 3
    scale = np.float32(10.0) ** rng.integers(-3, 3, (n, 1, 1, 1))
    windows = (rng.standard_normal((n, k, k, c)) * scale).astype(np.float32)
    grid_x = rng.uniform(-1.1, 1.1, (n, m)).astype(np.float32)  # a little outside: zero padding
    grid_y = rng.uniform(-1.1, 1.1, (n, m)).astype(np.float32)
    grid = np.empty((n, m, m, 2), np.float32)
    grid[..., 0], grid[..., 1] = grid_x[:, None, :], grid_y[:, :, None]
    expected = F.grid_sample(
        torch.from_numpy(windows).permute(0, 3, 1, 2),
        torch.from_numpy(grid),
        mode="bilinear",
        padding_mode="zeros",
        align_corners=False,
    )
    np.testing.assert_array_equal(_sample(windows, None, grid_x, grid_y, 1), expected.numpy())
    np.testing.assert_array_equal(
        _sample(windows, None, grid_x, grid_y, 2), F.avg_pool2d(expected, 2).numpy()
    )


def test_border_boxes_are_zero_padded():
    image = np.full((32, 48, 3), 200, np.uint8)
    boxes = np.array([[-8, -8, 8, 8], [40, 24, 56, 40], [100, 100, 116, 116]], np.float32)
    crops = roi_align(image, boxes)
    assert crops.shape == (3, 3, 16, 16)
    top_left = crops[0, 0]
    assert np.all(top_left[:8, :] == 0) and np.all(top_left[:, :8] == 0)
    np.testing.assert_allclose(top_left[8:, 8:], 200.0)
    bottom_right = crops[1, 0]
    np.testing.assert_allclose(bottom_right[:8, :8], 200.0)
    assert np.all(bottom_right[8:, :] == 0) and np.all(bottom_right[:, 8:] == 0)
    assert np.all(crops[2] == 0)


def test_sampling_ratio_averages_sub_samples():
    rng = np.random.default_rng(2)
    image = rng.random((64, 64)).astype(np.float32)
    boxes = np.array([[5.5, 9.0, 37.5, 41.0], [-4.0, 20.0, 28.0, 52.0]])
    coarse = roi_align(image, boxes, 16, sampling_ratio=2)
    fine = F.avg_pool2d(torch.from_numpy(roi_align(image, boxes, 32, sampling_ratio=1)), 2)
    np.testing.assert_array_equal(coarse, fine.numpy())
    # Adaptive ratio for 32 px boxes is 2.
    np.testing.assert_array_equal(roi_align(image, boxes, 16), coarse)


@pytest.mark.parametrize("ds", [2, 4])
def test_downsampled_motion_crops_register_with_full_resolution(ds: int):
    h, w = 96, 128
    cx, cy = 61.3, 44.8  # a blob off the box centre and off the pixel grid
    blob = _blob(h, w, cx, cy, sigma=2.5)
    frame = np.zeros((h, w, 3), np.uint8)
    frame[..., 1] = np.round(blob * 255).astype(np.uint8)
    box = np.array([[52.0, 38.0, 68.0, 54.0]], np.float32)  # 16 px, centre (60, 46)

    def maps(d: int) -> MotionMaps:
        small = _avg_pool(blob, d)
        return MotionMaps(d, small, small, small, small * small, small)

    full = motion_enhanced_crops(frame, maps(1), box, np.ones(1))
    down = motion_enhanced_crops(frame, maps(ds), box, np.ones(1))
    c_full, c_down = _centroid(full[0, 3]), _centroid(down[0, 3])
    c_rgb = _centroid(full[0, 1])
    expected = np.array([cx - 52.0, cy - 38.0])  # crop px j samples array index 52 + j
    assert np.abs(c_full - expected).max() < 0.1
    assert np.abs(c_rgb - expected).max() < 0.1
    assert np.abs(c_down - expected).max() < 0.3  # a half-pixel slip would be >= 0.5 crop px


def test_colour_channels_are_rgb_in_unit_range():
    frame = np.zeros((20, 20, 3), np.uint8)
    frame[..., 0], frame[..., 1], frame[..., 2] = 10, 128, 255  # B, G, R
    z = np.zeros((10, 10), np.float32)
    crops = motion_enhanced_crops(
        frame, MotionMaps(2, z, z, z, z, z), np.array([[2, 2, 18, 18]], np.float32), np.zeros(1)
    )
    assert crops.shape == (1, 4, 16, 16) and crops.dtype == np.float32
    np.testing.assert_allclose(crops[0, :3, 8, 8], [1.0, 128 / 255, 10 / 255], atol=1e-6)
    assert np.all(crops[0, 3] == 0)  # zero motion: normalisation guard keeps E at 0


def test_enhanced_response_hand_made():
    l_crop = np.array([[[2.0, -1.0], [0.0, -4.0]], [[2.0, -1.0], [0.0, -4.0]]], np.float32)
    v_crop = np.array([[[0.5, 1.0], [0.0, 0.25]], [[0.0, 0.0], [0.0, 0.0]]], np.float32)
    e = enhanced_response(l_crop, v_crop, np.array([1.0, 0.0]))
    # ON polarity: V / 1 + L_on / 2
    np.testing.assert_allclose(e[0], [[0.5 + 1.0, 1.0], [0.0, 0.25]])
    # OFF polarity, V all zero: L_off / 4
    np.testing.assert_allclose(e[1], [[0.0, 0.25], [0.0, 1.0]])


def test_empty_boxes_and_flops():
    frame = np.zeros((20, 20, 3), np.uint8)
    z = np.zeros((10, 10), np.float32)
    crops = motion_enhanced_crops(
        frame, MotionMaps(2, z, z, z, z, z), np.zeros((0, 4)), np.zeros(0)
    )
    assert crops.shape == (0, 4, 16, 16)
    assert crop_flops(25) == 25 * crop_flops(1) > 0


def test_motion_floor_keeps_faint_change_faint():
    """Below the floor the temporal change is divided by the floor, not stretched to 1; above it
    the floor changes nothing; V is never floored."""
    faint = np.array([[[0.005, -0.002], [0.0, 0.001]]], np.float32)
    strong = faint * 10  # max 0.05, above a 0.02 floor
    v = np.array([[[1e-6, 0.0], [0.0, 0.0]]], np.float32)
    on = np.array([1.0])
    np.testing.assert_allclose(
        enhanced_response(faint, v, on, motion_floor=0.02)[0],
        [[1.0 + 0.25, 0.0], [0.0, 0.05]],
        rtol=1e-6,
    )
    np.testing.assert_allclose(
        enhanced_response(faint, v, on)[0], [[1.0 + 1.0, 0.0], [0.0, 0.2]], rtol=1e-6
    )
    np.testing.assert_allclose(
        enhanced_response(strong, v, on, motion_floor=0.02), enhanced_response(strong, v, on)
    )
    off = enhanced_response(faint, np.zeros_like(v), np.array([0.0]), motion_floor=0.02)
    np.testing.assert_allclose(off[0], [[0.0, 0.1], [0.0, 0.0]], rtol=1e-6)


def test_motion_floor_reaches_the_crops():
    frame = np.zeros((20, 20, 3), np.uint8)
    z = np.zeros((10, 10), np.float32)
    change = np.full((10, 10), 0.004, np.float32)
    maps = MotionMaps(2, change, z, z, z, z)
    box, on = np.array([[2, 2, 18, 18]], np.float32), np.ones(1)
    plain = motion_enhanced_crops(frame, maps, box, on)
    floored = motion_enhanced_crops(frame, maps, box, on, motion_floor=0.02)
    np.testing.assert_allclose(plain[0, 3, 8, 8], 1.0, rtol=1e-6)
    np.testing.assert_allclose(floored[0, 3, 8, 8], 0.2, rtol=1e-5)
    np.testing.assert_array_equal(plain[:, :3], floored[:, :3])
