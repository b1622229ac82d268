"""Tileable fractal noise: white noise shaped by a power law in the Fourier domain.

A tile wraps at its edges, so it can be sampled at any ground position (modulo its size) and
scrolled without seams; the sea and the land's material blends are built from such tiles.
"""

from __future__ import annotations

import numpy as np


def fractal_tile(rng: np.random.Generator, size: int = 256, slope: float = 2.0) -> np.ndarray:
    """A ``size`` x ``size`` float32 tile with zero mean and unit standard deviation whose power
    falls as ``frequency ** -slope`` (2 = cloud-like, 3 = smoother)."""
    white = rng.standard_normal((size, size))
    fy = np.fft.fftfreq(size)[:, None]
    fx = np.fft.fftfreq(size)[None, :]
    radius = np.sqrt(fx * fx + fy * fy)
    radius[0, 0] = 1.0
    shaped = np.fft.ifft2(np.fft.fft2(white) * radius ** (-slope / 2.0)).real
    shaped -= shaped.mean()
    return (shaped / (shaped.std() + 1e-9)).astype(np.float32)


def smoothstep(x: np.ndarray, low: float, high: float) -> np.ndarray:
    """0 below ``low``, 1 above ``high``, a smooth cubic between."""
    t = np.clip((x - low) / max(high - low, 1e-6), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)
