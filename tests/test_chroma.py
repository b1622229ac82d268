"""Chromatic anomaly map: geometry, response to a coloured patch, none on grey scenes."""

from __future__ import annotations

import numpy as np
import pytest
from motion_scenes import textured_background, to_bgr

from sarmission.perception.chroma import (
    CHROMA_SCALE,
    ChromaParams,
    chroma_anomaly,
    chroma_if_wanted,
    pooled_colour,
)
from sarmission.perception.pyramid import half_resolution

ORANGE = (20, 110, 240)  # BGR, a life-jacket colour


def sea_with_patch(
    height: int, width: int, cx: int, cy: int, side: int, colour: tuple[int, int, int] = ORANGE
) -> np.ndarray:
    """Blue-green textured water with a ``side`` px square of ``colour`` centred at (cx, cy)."""
    texture = textured_background(height, width, seed=3, mean=0.35)
    frame = np.empty((height, width, 3), np.uint8)
    for channel, gain in enumerate((0.95, 0.75, 0.35)):
        frame[..., channel] = np.clip(texture * gain * 255, 0, 255).astype(np.uint8)
    half = side // 2
    frame[cy - half : cy - half + side, cx - half : cx - half + side] = colour
    return frame


def test_pooling_averages_8x8_blocks_and_ignores_the_remainder() -> None:
    rng = np.random.default_rng(0)
    frame = rng.integers(0, 256, (70, 93, 3), dtype=np.uint8)
    pooled = pooled_colour(frame)
    assert pooled.shape == (70 // 8, 93 // 8, 3)
    expected = frame[:64, :88].astype(np.float64).reshape(8, 8, 11, 8, 3).mean(axis=(1, 3))
    # Three rounded uint8 halvings: within 1.5 grey levels of the exact mean.
    assert np.abs(pooled.astype(np.float64) - expected).max() <= 1.5
    # The shared half-resolution frame gives the same map.
    np.testing.assert_array_equal(pooled_colour(frame, half_resolution(frame)), pooled)


def test_a_coloured_patch_is_the_strongest_anomaly() -> None:
    frame = sea_with_patch(360, 480, cx=300, cy=140, side=20)
    anomaly = chroma_anomaly(frame)
    assert anomaly.shape == (360 // CHROMA_SCALE, 480 // CHROMA_SCALE)
    assert anomaly.dtype == np.float32
    row, col = np.unravel_index(int(np.argmax(anomaly)), anomaly.shape)
    x, y = (col + 0.5) * CHROMA_SCALE - 0.5, (row + 0.5) * CHROMA_SCALE - 0.5
    assert abs(x - 300) <= 12 and abs(y - 140) <= 12
    # Far above the typical level of the textured water around it.
    assert anomaly.max() > 20 * np.median(anomaly)


def test_a_patch_cut_by_block_edges_scores_as_high_as_one_inside_a_block() -> None:
    """A 6 px patch straddling the corner of four 8 x 8 blocks fills a window 4 px off the
    block grid, so it is not diluted to a quarter of its colour."""
    inside = chroma_anomaly(sea_with_patch(360, 480, cx=307, cy=147, side=6))  # rows 144-149
    straddling = chroma_anomaly(sea_with_patch(360, 480, cx=307 + 4, cy=147 + 4, side=6))
    assert inside.max() > 20 * np.median(inside)
    assert straddling.max() >= 0.7 * inside.max()
    row, col = np.unravel_index(int(np.argmax(straddling)), straddling.shape)
    assert (row, col) in {(18, 38), (18, 39), (19, 38), (19, 39)}  # one of the four blocks


def test_grey_frames_have_no_anomaly_and_the_helper_skips_small_frames() -> None:
    grey = to_bgr(textured_background(120, 160, seed=5))
    assert np.all(chroma_anomaly(grey) == 0.0)
    assert chroma_if_wanted(grey, wanted=False) is None
    assert chroma_if_wanted(grey[: CHROMA_SCALE - 1], wanted=True) is None
    assert chroma_if_wanted(grey, wanted=True).shape == (120 // 8, 160 // 8)


def test_bad_input_and_parameters_raise() -> None:
    with pytest.raises(ValueError, match="BGR uint8"):
        chroma_anomaly(np.zeros((64, 64), np.uint8))
    with pytest.raises(ValueError, match="BGR uint8"):
        chroma_anomaly(np.zeros((64, 64, 3), np.float32))
    with pytest.raises(ValueError, match="smaller than"):
        pooled_colour(np.zeros((4, 64, 3), np.uint8))
    with pytest.raises(ValueError, match="window"):
        ChromaParams(window=4)
    with pytest.raises(ValueError, match="floor"):
        ChromaParams(floor=0.0)
