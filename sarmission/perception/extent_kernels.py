"""The numba loop of :func:`sarmission.perception.extent.object_extent`'s region, in one pass.

Done with numpy and OpenCV, a 65 px window costs a dozen small calls (histograms, a table, two
lookups, a closing, connected components): about 0.4 ms per detection, most of it the calls'
own overhead. This loop gives the same region. Ties between
components that cover the box equally go to the one OpenCV labels first (its 8-connected
labelling scans rows in pairs, column by column). Import it through
:mod:`~sarmission.perception.kernels`, which compiles it ahead of time.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Result codes of :func:`region`.
NOTHING, MIXED, FOUND = 0, 1, 2


@njit(cache=False, nogil=True)
def _lower_median(counts):  # pragma: no cover - numba
    total = 0
    for v in range(counts.shape[0]):
        total += counts[v]
    half = (total + 1) // 2
    running = 0
    for v in range(counts.shape[0]):
        running += counts[v]
        if running >= half:
            return v
    return counts.shape[0] - 1


@njit(cache=False, nogil=True)
def _square3(image, grow):  # pragma: no cover - numba
    """The maximum (``grow``) or minimum of each pixel's 3 x 3 neighbourhood inside ``image``."""
    h, w = image.shape
    rows = np.empty((h, w), np.uint8)
    for y in range(h):
        for x in range(w):
            a = image[y, max(0, x - 1)]
            b = image[y, min(w - 1, x + 1)]
            c = image[y, x]
            rows[y, x] = max(a, b, c) if grow else min(a, b, c)
    out = np.empty((h, w), np.uint8)
    for y in range(h):
        up, down = max(0, y - 1), min(h - 1, y + 1)
        for x in range(w):
            a, b, c = rows[up, x], rows[y, x], rows[down, x]
            out[y, x] = max(a, b, c) if grow else min(a, b, c)
    return out


@njit(cache=False, nogil=True)
def region(lab, ix0, iy0, ix1, iy1, threshold, spread_floor, border_share):  # pragma: no cover
    """``(code, left, top, right, bottom, touches)`` of the region of ``lab`` (uint8
    ``[h, w, 3]``) that covers most of the box ``ix0:ix1, iy0:iy1``; ``code`` is
    :data:`NOTHING`, :data:`MIXED` (the border band is not one background) or :data:`FOUND`.
    A pixel stands out where a channel lies more than ``threshold`` robust deviations
    (1.4826 x MAD + ``spread_floor``) from the border band's median."""
    h, w = lab.shape[0], lab.shape[1]
    band = max(2, min(h, w) // 16)
    counts = np.zeros((3, 256), np.int64)
    n_border = 0
    for y in range(h):
        edge_row = y < band or y >= h - band
        for x in range(w):
            if edge_row or x < band or x >= w - band:
                n_border += 1
                for c in range(3):
                    counts[c, lab[y, x, c]] += 1
    outlying = np.zeros((3, 256), np.uint8)
    for c in range(3):
        median = _lower_median(counts[c])
        spread = np.zeros(256, np.int64)
        for v in range(256):
            spread[abs(v - median)] += counts[c, v]
        scale = 1.4826 * _lower_median(spread) + spread_floor
        for v in range(256):
            outlying[c, v] = abs(v - median) / scale > threshold
    mask = np.zeros((h, w), np.uint8)
    standing_out = 0  # of the border band's pixels
    for y in range(h):
        edge_row = y < band or y >= h - band
        for x in range(w):
            mask[y, x] = (
                outlying[0, lab[y, x, 0]] | outlying[1, lab[y, x, 1]] | outlying[2, lab[y, x, 2]]
            )
            if edge_row or x < band or x >= w - band:
                standing_out += mask[y, x]
    if standing_out / n_border > border_share:
        return MIXED, 0, 0, 0, 0, False
    # closing with a 3 x 3 square (separable); pixels outside the window neither add nor erode
    closed = _square3(_square3(mask, True), False)
    # 8-connected components of the pixels under the box, filled one at a time
    seen = np.zeros((h, w), np.uint8)
    stack_y = np.empty(h * w, np.int64)
    stack_x = np.empty(h * w, np.int64)
    best_count, best_key = 0, -1
    best = (0, 0, 0, 0)
    for sy in range(iy0, iy1):
        for sx in range(ix0, ix1):
            if closed[sy, sx] == 0 or seen[sy, sx]:
                continue
            seen[sy, sx] = 1
            stack_y[0], stack_x[0] = sy, sx
            size = 1
            under, key = 0, (sy // 2) * 2 * w + 2 * sx + sy % 2
            left, top, right, bottom = sx, sy, sx, sy
            while size:
                size -= 1
                y, x = stack_y[size], stack_x[size]
                if iy0 <= y < iy1 and ix0 <= x < ix1:
                    under += 1
                key = min(key, (y // 2) * 2 * w + 2 * x + y % 2)
                left, right = min(left, x), max(right, x)
                top, bottom = min(top, y), max(bottom, y)
                for yy in range(max(0, y - 1), min(h, y + 2)):
                    for xx in range(max(0, x - 1), min(w, x + 2)):
                        if closed[yy, xx] and not seen[yy, xx]:
                            seen[yy, xx] = 1
                            stack_y[size], stack_x[size] = yy, xx
                            size += 1
            if under > best_count or (under == best_count and key < best_key):
                best_count, best_key = under, key
                best = (left, top, right + 1, bottom + 1)
    if best_count == 0:
        return NOTHING, 0, 0, 0, 0, False
    left, top, right, bottom = best
    touches = left <= 0 or top <= 0 or right >= w or bottom >= h
    return FOUND, left, top, right, bottom, touches
