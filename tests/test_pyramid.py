"""The shared half-resolution frame."""

from __future__ import annotations

import numpy as np
import pytest

from sarmission.perception.pyramid import half_resolution


def test_half_resolution_is_the_2x2_block_mean_and_drops_an_odd_edge() -> None:
    rng = np.random.default_rng(1)
    frame = rng.integers(0, 256, (9, 13, 3), dtype=np.uint8)
    half = half_resolution(frame)
    assert half.shape == (4, 6, 3) and half.dtype == np.uint8
    expected = frame[:8, :12].astype(np.float64).reshape(4, 2, 6, 2, 3).mean(axis=(1, 3))
    assert np.abs(half - expected).max() <= 0.5 + 1e-9  # one rounding to uint8
    gray = frame[..., 0].astype(np.float32)
    np.testing.assert_allclose(
        half_resolution(gray), gray[:8, :12].reshape(4, 2, 6, 2).mean(axis=(1, 3)), atol=1e-4
    )
    with pytest.raises(ValueError, match="too small"):
        half_resolution(np.zeros((1, 8, 3), np.uint8))
