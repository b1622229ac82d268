"""The numba loop of the crops: bilinear sampling with torch's CPU ``grid_sample`` arithmetic.

Kept apart from :mod:`~sarmission.perception.crops` so that detection can run it compiled ahead
of time without importing numba (:mod:`~sarmission.perception.kernels`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def bilinear(windows, grid_x, grid_y, out):  # pragma: no cover - numba
    """``grid_sample(windows, grid, "bilinear", "zeros", align_corners=False)`` into ``out``
    ``[N, C, M, M]``, with torch's CPU arithmetic: ``x = fma(g + 1, K / 2, -0.5)``, weights
    ``(1 - dy)(1 - dx)`` ..., then ``v_nw * w_nw`` and three fused multiply-adds (emulated in
    float64: a product of two float32 is exact there, the sum is rounded once to float32).
    No fastmath: every float32 step must round as torch's does."""
    n, k, _, channels = windows.shape
    m = grid_x.shape[1]
    one = np.float32(1.0)
    half = np.float64(np.float32(k) / np.float32(2.0))
    xs = np.empty(m, np.int64)
    xe = np.empty(m, np.float32)
    for b in range(n):
        for j in range(m):
            x = np.float32(np.float64(grid_x[b, j] + one) * half - 0.5)
            low = np.float32(math.floor(x))
            xs[j] = np.int64(low)
            xe[j] = x - low
        for i in range(m):
            y = np.float32(np.float64(grid_y[b, i] + one) * half - 0.5)
            low_y = np.float32(math.floor(y))
            r0 = np.int64(low_y)
            south = y - low_y
            north = one - south
            r_ok0 = 0 <= r0 < k
            r_ok1 = 0 <= r0 + 1 < k
            for j in range(m):
                c0 = xs[j]
                east = xe[j]
                west = one - east
                c_ok0 = 0 <= c0 < k
                c_ok1 = 0 <= c0 + 1 < k
                w_nw, w_ne = north * west, north * east
                w_sw, w_se = south * west, south * east
                for c in range(channels):
                    v_nw = windows[b, r0, c0, c] if r_ok0 and c_ok0 else np.float32(0.0)
                    v_ne = windows[b, r0, c0 + 1, c] if r_ok0 and c_ok1 else np.float32(0.0)
                    v_sw = windows[b, r0 + 1, c0, c] if r_ok1 and c_ok0 else np.float32(0.0)
                    v_se = windows[b, r0 + 1, c0 + 1, c] if r_ok1 and c_ok1 else np.float32(0.0)
                    acc = v_nw * w_nw
                    acc = np.float32(np.float64(v_ne) * np.float64(w_ne) + np.float64(acc))
                    acc = np.float32(np.float64(v_sw) * np.float64(w_sw) + np.float64(acc))
                    acc = np.float32(np.float64(v_se) * np.float64(w_se) + np.float64(acc))
                    out[b, c, i, j] = acc
