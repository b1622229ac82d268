"""Value noise anchored to the world: a hash of integer lattice cells, smoothly interpolated.

The value at a world point depends only on the point, the cell size and the seed, so a texture
made from it stays put on the ground while the camera moves over it.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

_M1, _M2, _M3 = (
    np.uint64(0x9E3779B97F4A7C15),
    np.uint64(0xBF58476D1CE4E5B9),
    np.uint64(0x94D049BB133111EB),
)


def _hash01(ix: np.ndarray, iy: np.ndarray, seed: int) -> np.ndarray:
    """A uniform value in [0, 1) per integer cell (splitmix64 finaliser of the cell's key)."""
    with np.errstate(over="ignore"):
        key = (
            ix.astype(np.int64).astype(np.uint64) * _M1
            ^ iy.astype(np.int64).astype(np.uint64) * _M2
            ^ np.uint64(seed) * _M3
        )
        key ^= key >> np.uint64(30)
        key *= _M2
        key ^= key >> np.uint64(27)
        key *= _M3
        key ^= key >> np.uint64(31)
    return (key >> np.uint64(40)).astype(np.float32) / np.float32(1 << 24)


def value_noise(x: np.ndarray, y: np.ndarray, cell: float, seed: int) -> np.ndarray:
    """Smooth noise in about [0, 1) at world points (metres), features about ``cell`` metres
    wide: the hashed values of the lattice cells around the points, interpolated bicubically."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    shape = x.shape
    gx, gy = (
        (x / cell).reshape(-1, x.shape[-1] if x.ndim else 1),
        (y / cell).reshape(-1, y.shape[-1] if y.ndim else 1),
    )
    ix0, iy0 = math.floor(float(gx.min())) - 2, math.floor(float(gy.min())) - 2
    nx, ny = math.floor(float(gx.max())) - ix0 + 4, math.floor(float(gy.max())) - iy0 + 4
    if nx * ny > 40_000_000:
        raise ValueError(f"noise lattice of {nx}x{ny} cells is too large")
    lattice = _hash01(*np.meshgrid(np.arange(ix0, ix0 + nx), np.arange(iy0, iy0 + ny)), seed)
    values = cv2.remap(
        lattice,
        (gx - ix0).astype(np.float32),
        (gy - iy0).astype(np.float32),
        cv2.INTER_CUBIC,
        borderMode=cv2.BORDER_REPLICATE,
    )
    return values.reshape(shape)


def fractal_noise(
    x: np.ndarray, y: np.ndarray, cell: float, seed: int, octaves: int = 4, gain: float = 0.5
) -> np.ndarray:
    """Octaves of :func:`value_noise` (each half the cell, ``gain`` the weight), in [0, 1)."""
    total = np.zeros(np.shape(x), np.float32)
    weight, norm = 1.0, 0.0
    for octave in range(octaves):
        total += weight * value_noise(x, y, cell / 2**octave, seed + 7919 * octave)
        norm += weight
        weight *= gain
    return total / norm
