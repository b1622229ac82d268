"""The numba loops of vSTMD: lamina, medulla and correlation fused in one pass per map pixel
(with or without the camera shift resampled inside it), the lobula's rectified combination, and
the normal equations of the shift estimate.

They are kept apart from the front-end so that each can be checked against the equations
(docs/vstmd.md) on its own; they take and fill preallocated float32 arrays and never allocate.
The front-end calls them through :mod:`~sarmission.perception.kernels`, compiled ahead of time.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, fastmath=True, inline="always")
def _exp_small(x):
    """``exp(x)`` for ``0 <= x <~ 2`` as ``(sum_{k<=5} (x/8)^k / k!)^8``; relative error < 1e-5
    (|L| <= 1 for frames in [0, 1]). Vectorises, unlike the libm call.
    """
    y = x * np.float32(0.125)
    p = np.float32(1.0) + y * (
        np.float32(1.0)
        + y
        * (
            np.float32(0.5)
            + y
            * (np.float32(1.0 / 6.0) + y * (np.float32(1.0 / 24.0) + y * np.float32(1.0 / 120.0)))
        )
    )
    p = p * p
    p = p * p
    return p * p


@njit(cache=True, fastmath=True, inline="always")
def _cell(p, q, l_prev, a, b, a0, decay, g_leak, v_rest, v_exc):
    """One map pixel: lamina ``L = a0 (p - q) + decay L_prev``, ON/OFF split and the cIDP update
    of ``(a, b) = (V_on, V_off)``. Returns ``(L, V_on, V_off)``.
    """
    zero = np.float32(0.0)
    lt = a0 * (p - q) + decay * l_prev
    on = max(lt, zero)
    off = max(-lt, zero)
    a = a + _exp_small(off) * g_leak * (v_rest - a) + on * (v_exc - a)
    b = b + _exp_small(on) * g_leak * (v_rest - b) + off * (v_exc - b)
    return lt, a, b


@njit(cache=True, fastmath=True)
def lamina_medulla(
    pooled,
    scale,
    p_state,
    l_state,
    von_state,
    voff_state,
    corr,
    a0,
    decay,
    g_leak,
    v_rest,
    v_exc,
):  # pragma: no cover - numba
    """One fused pass at 1/ds: lamina recursion, ON/OFF split, cIDP update and ``C``.

    The state (``P'``, ``L``, ``V_on``, ``V_off``) holds last frame's values and is updated in
    place: each pixel reads only its own.
    """
    h, w = pooled.shape
    for i in range(h):
        src = pooled[i]
        pp = p_state[i]
        ll = l_state[i]
        aa = von_state[i]
        bb = voff_state[i]
        co = corr[i]
        for j in range(w):
            p = np.float32(src[j]) * scale
            lt, a, b = _cell(p, pp[j], ll[j], aa[j], bb[j], a0, decay, g_leak, v_rest, v_exc)
            pp[j] = p
            ll[j] = lt
            aa[j] = a
            bb[j] = b
            co[j] = a * b


@njit(cache=True, fastmath=True)
def lamina_medulla_shifted(
    pooled,
    scale,
    p_state,
    l_state,
    von_state,
    voff_state,
    corr,
    ring,
    column,
    kx,
    ky,
    fx,
    fy,
    cx,
    cy,
    a0,
    decay,
    g_leak,
    v_rest,
    v_exc,
):  # pragma: no cover - numba
    """:func:`lamina_medulla` with last frame's state carried by the shift ``s = k + f``
    (integer ``k``, fraction ``f`` in [0, 1)) into this frame's coordinates, in place.

    The source of map pixel ``(i, j)`` is ``(i - s_y, j - s_x)``, between columns
    ``c = j - kx`` and ``c - 1``. ``P~`` is a Catmull-Rom cubic over columns ``c + 1 .. c - 2``
    (weights ``cx``, rows likewise with ``cy``); ``L``, ``V_on``, ``V_off`` are bilinear
    (weights ``1 - fx`` on ``c``, ``fx`` on ``c - 1``). Where a tap falls outside the map
    ``P~ = P'_t`` and ``L~ = V~ = 0``. Rows are written top to bottom; before row ``i`` is
    overwritten its old values go to slot ``i % R`` of ``ring`` (float32 ``[4, R, w]``,
    ``R >= kernels.ring_rows(ky, h)``), where the rows below it still read them. ``column`` is
    scratch of at least ``w + 3`` values.
    """
    h, w = pooled.shape
    zero = np.float32(0.0)
    one = np.float32(1.0)
    rows = ring.shape[1]
    keep = ky > -3  # else every row read lies below the one written
    jlo = min(max(0, kx + 2), w)
    jhi = max(min(w, w + kx - 1), jlo)
    wx0, wx1 = one - fx, fx
    wy0, wy1 = one - fy, fy
    x0, x1, x2, x3 = cx[0], cx[1], cx[2], cx[3]
    y0, y1, y2, y3 = cy[0], cy[1], cy[2], cy[3]
    for i in range(h):
        if keep:
            slot = i % rows
            ring[0, slot, :] = p_state[i]
            ring[1, slot, :] = l_state[i]
            ring[2, slot, :] = von_state[i]
            ring[3, slot, :] = voff_state[i]
        src = pooled[i]
        po = p_state[i]
        lo = l_state[i]
        ao = von_state[i]
        bo = voff_state[i]
        co = corr[i]
        r0 = i - ky
        inside = r0 - 2 >= 0 and r0 + 1 <= h - 1
        start = jlo if inside else w
        stop = jhi if inside else w
        for j in range(start):
            p = np.float32(src[j]) * scale
            lt, a, b = _cell(p, p, zero, zero, zero, a0, decay, g_leak, v_rest, v_exc)
            po[j] = p
            lo[j] = lt
            ao[j] = a
            bo[j] = b
            co[j] = a * b
        for j in range(stop, w):
            p = np.float32(src[j]) * scale
            lt, a, b = _cell(p, p, zero, zero, zero, a0, decay, g_leak, v_rest, v_exc)
            po[j] = p
            lo[j] = lt
            ao[j] = a
            bo[j] = b
            co[j] = a * b
        if stop <= start:
            continue
        # Last frame's rows r0 + 1 .. r0 - 2: kept aside once overwritten (rows <= i).
        # Row views aligned so that every index is the loop counter plus a constant >= 0 (lets
        # LLVM drop numba's negative-index wraparound checks and vectorise).
        base = start - kx - 2
        ra = r0 + 1
        rb = r0
        rc = r0 - 1
        rd = r0 - 2
        qa = ring[0, ra % rows, base:] if ra <= i else p_state[ra, base:]
        qb = ring[0, rb % rows, base:] if rb <= i else p_state[rb, base:]
        qc = ring[0, rc % rows, base:] if rc <= i else p_state[rc, base:]
        qd = ring[0, rd % rows, base:] if rd <= i else p_state[rd, base:]
        l0 = ring[1, rb % rows, base + 1 :] if rb <= i else l_state[rb, base + 1 :]
        l1 = ring[1, rc % rows, base + 1 :] if rc <= i else l_state[rc, base + 1 :]
        a0r = ring[2, rb % rows, base + 1 :] if rb <= i else von_state[rb, base + 1 :]
        a1r = ring[2, rc % rows, base + 1 :] if rc <= i else von_state[rc, base + 1 :]
        b0r = ring[3, rb % rows, base + 1 :] if rb <= i else voff_state[rb, base + 1 :]
        b1r = ring[3, rc % rows, base + 1 :] if rc <= i else voff_state[rc, base + 1 :]
        src = src[start:]
        po = po[start:]
        lo = lo[start:]
        ao = ao[start:]
        bo = bo[start:]
        co = co[start:]
        count = stop - start
        for n in range(count + 3):  # vertical cubic pass, then the horizontal one below
            column[n] = y0 * qa[n] + y1 * qb[n] + y2 * qc[n] + y3 * qd[n]
        for n in range(count):
            q = x0 * column[n + 3] + x1 * column[n + 2] + x2 * column[n + 1] + x3 * column[n]
            lp = wy0 * (wx0 * l0[n + 1] + wx1 * l0[n]) + wy1 * (wx0 * l1[n + 1] + wx1 * l1[n])
            ap = wy0 * (wx0 * a0r[n + 1] + wx1 * a0r[n]) + wy1 * (wx0 * a1r[n + 1] + wx1 * a1r[n])
            bp = wy0 * (wx0 * b0r[n + 1] + wx1 * b0r[n]) + wy1 * (wx0 * b1r[n + 1] + wx1 * b1r[n])
            p = np.float32(src[n]) * scale
            lt, a, b = _cell(p, q, lp, ap, bp, a0, decay, g_leak, v_rest, v_exc)
            po[n] = p
            lo[n] = lt
            ao[n] = a
            bo[n] = b
            co[n] = a * b


@njit(cache=True, fastmath=True)
def translation_system(cur, prev, sx, sy, huber, level):  # pragma: no cover - numba
    """Gauss-Newton normal equations of ``min_s sum_x rho(cur(x) - prev(x - s))`` at ``s``.

    With ``r = cur(x) - prev(x - s)`` (bilinear) and ``g = grad cur(x)`` (central differences),
    ``cur(x) = prev(x - s - d)`` linearises to ``r = -g . d``, so ``d = -A^{-1} b`` with
    ``A = sum w g g^T``, ``b = sum w g r`` and Huber weights ``w = min(1, huber / |r|)``.
    Returns ``(A11, A12, A22, b1, b2, mean |r|, share of |r| > level, count)`` over the pixels
    whose samples are inside.
    """
    h, w = cur.shape
    kx = int(math.floor(sx))
    ky = int(math.floor(sy))
    fx = sx - kx
    fy = sy - ky
    a11 = a12 = a22 = b1 = b2 = err = changed = 0.0
    n = 0
    jlo = max(1, kx + 1)
    jhi = min(w - 1, w + kx)
    for i in range(max(1, ky + 1), min(h - 1, h + ky)):
        if jhi <= jlo:
            break
        # Views aligned to the loop counter m (column jlo + m), as in the lamina kernel.
        q0 = prev[i - ky, jlo - kx - 1 :]
        q1 = prev[i - ky - 1, jlo - kx - 1 :]
        up = cur[i - 1, jlo:]
        row = cur[i, jlo - 1 :]
        down = cur[i + 1, jlo:]
        for m in range(jhi - jlo):
            q = (1.0 - fy) * ((1.0 - fx) * q0[m + 1] + fx * q0[m]) + fy * (
                (1.0 - fx) * q1[m + 1] + fx * q1[m]
            )
            r = row[m + 1] - q
            gx = 0.5 * (row[m + 2] - row[m])
            gy = 0.5 * (down[m] - up[m])
            ar = abs(r)
            wt = 1.0 if ar <= huber else huber / ar
            a11 += wt * gx * gx
            a12 += wt * gx * gy
            a22 += wt * gy * gy
            b1 += wt * gx * r
            b2 += wt * gy * r
            err += ar
            changed += 1.0 if ar > level else 0.0
        n += jhi - jlo
    return a11, a12, a22, b1, b2, err / max(n, 1), changed / max(n, 1), n


@njit(cache=True, fastmath=True)
def combine_rectify(centre, surround, bump, out):  # pragma: no cover - numba
    """``out = max(centre - surround + bump, 0)`` (the pre-scaled lobula terms)."""
    h, w = out.shape
    zero = np.float32(0.0)
    for i in range(h):
        c = centre[i]
        s = surround[i]
        b = bump[i]
        o = out[i]
        for j in range(w):
            o[j] = max(c[j] - s[j] + b[j], zero)
