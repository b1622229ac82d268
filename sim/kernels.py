"""Compiled per-pixel loops of the renderer (numba): sea colour and part rasterisation.

Both are plain loops over pixels so that a frame costs no Python work per pixel or per part.
"""

from __future__ import annotations

import math

import numba
import numpy as np

#: Columns of the part table given to :func:`rasterize_parts`.
PART_COLUMNS = (
    "is_box",
    "x",
    "y",
    "a",
    "b",
    "cos",
    "sin",
    "b_",
    "g",
    "r",
    "alpha",
    "shade",
    "radius",
)


@numba.njit(cache=True, nogil=True, fastmath=True, parallel=True)
def compose_sea(
    layers: np.ndarray,
    weights: np.ndarray,
    glint: np.ndarray,
    fresnel: np.ndarray,
    sea: np.ndarray,
    water: np.ndarray,
    sky: np.ndarray,
    gain: float,
    foam_threshold: float,
    bias: float,
    out: np.ndarray,
) -> None:
    """Sea colour from warped wave layers ``layers`` [L, H, W, 3] uint8 (slope, height, foam
    texture, each 128-centred with unit std = 40) into ``out`` [H, W, 3] uint8.

    ``c = water + gain * slope * (0.8, 0.9, 1.0)``, mixed towards ``sky`` by the Fresnel term
    (or fully where ``sea`` is 0), brightened by the glint envelope, covered by foam where the
    summed height (unit std) exceeds ``foam_threshold``; minus ``bias``.
    """
    n_layers, height, width = layers.shape[0], layers.shape[1], layers.shape[2]
    norm = 0.0
    for k in range(n_layers):
        norm += weights[k] * weights[k]
    norm = 1.0 / (40.0 * math.sqrt(norm))
    tint = (0.8, 0.9, 1.0)
    for i in numba.prange(height):
        for j in range(width):
            slope = 0.0
            h = 0.0
            tex = 0.0
            for k in range(n_layers):
                w = weights[k]
                slope += w * (layers[k, i, j, 0] - 128.0)
                h += w * (layers[k, i, j, 1] - 128.0)
                tex += w * (layers[k, i, j, 2] - 128.0)
            slope *= 1.0 / 40.0
            h *= norm
            tex *= norm
            s = sea[i, j]
            foam = min(max((h - foam_threshold) * 2.0, 0.0), 1.0)
            foam *= min(max(0.6 + 0.25 * tex, 0.0), 1.0) * s
            fres = 1.0 - s * (1.0 - fresnel[i, j])
            g = 0.85 * glint[i, j]
            for ch in range(3):
                c = water[ch] + gain * slope * tint[ch]
                c = c + fres * (sky[ch] - c)
                c = c + g * (255.0 - c)
                c = c + foam * (232.0 - c) - bias
                out[i, j, ch] = min(max(c + 0.5, 0.0), 255.0)


@numba.njit(cache=True, nogil=True, fastmath=True)
def rasterize_parts(
    patch: np.ndarray, hinv: np.ndarray, u0: int, v0: int, parts: np.ndarray, metres_per_px: float
) -> None:
    """Blend parts (rows of :data:`PART_COLUMNS`) over ``patch`` [h, w, 3] float32 in place.

    Pixel ``(u0 + j, v0 + i)`` maps to local metres through ``hinv``; a part covers it by
    ``clip(0.5 - d / metres_per_px, 0, 1) * alpha`` with ``d`` the signed distance to its outline
    (exact for rounded boxes, first-order for ellipses), and is darkened by ``shade`` towards its
    rim.
    """
    ph, pw = patch.shape[0], patch.shape[1]
    inv_m = 1.0 / metres_per_px
    for i in range(ph):
        v = v0 + i
        for j in range(pw):
            u = u0 + j
            w = hinv[2, 0] * u + hinv[2, 1] * v + hinv[2, 2]
            x = (hinv[0, 0] * u + hinv[0, 1] * v + hinv[0, 2]) / w
            y = (hinv[1, 0] * u + hinv[1, 1] * v + hinv[1, 2]) / w
            for k in range(parts.shape[0]):
                dx = x - parts[k, 1]
                dy = y - parts[k, 2]
                c, s = parts[k, 5], parts[k, 6]
                px = c * dx + s * dy
                py = -s * dx + c * dy
                a, b = parts[k, 3], parts[k, 4]
                if parts[k, 0] > 0.5:
                    rad = parts[k, 12]
                    qx = abs(px) - (a - rad)
                    qy = abs(py) - (b - rad)
                    ox, oy = max(qx, 0.0), max(qy, 0.0)
                    sd = math.sqrt(ox * ox + oy * oy) + min(max(qx, qy), 0.0) - rad
                    rim = max(abs(px) / a, abs(py) / b)
                else:
                    eu, ev = px / a, py / b
                    r = math.sqrt(eu * eu + ev * ev)
                    grad = math.sqrt((eu / a) ** 2 + (ev / b) ** 2)
                    sd = (r - 1.0) * r / max(grad, 1e-6)
                    rim = r
                cover = min(max(0.5 - sd * inv_m, 0.0), 1.0) * parts[k, 10]
                if cover <= 0.0:
                    continue
                dark = 1.0 - parts[k, 11] * min(rim * rim, 1.0)
                for ch in range(3):
                    col = dark * parts[k, 7 + ch]
                    patch[i, j, ch] += cover * (col - patch[i, j, ch])
