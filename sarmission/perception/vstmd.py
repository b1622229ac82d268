"""vSTMD: the learning-free small-target motion front-end of MITE-Net (streaming, one video).

Per frame it turns a grayscale image into 1/ds motion maps: retina blur, lamina (fractional
temporal difference), medulla (ON/OFF cross-inhibition potentials), their correlation ``C`` and
the lobula's size-selective centre-surround response ``R`` (:class:`MotionMaps`), which the
TTM-RPN proposes from. The camera's own motion is compensated first, so only what moves
against the background responds. Everything before the 1/ds map is linear, so the only
full-resolution work is one OpenCV pass per frame; the rest is one fused numba loop plus
separable lobula filters. The equations, geometry and approximations are in docs/vstmd.md, the
measurements behind the constants in docs/experiments.md.

Map pixel ``(i, j)`` averages frame rows ``i*ds .. i*ds+ds-1`` and columns ``j*ds .. j*ds+ds-1``
(:func:`map_to_full`). The arrays of a returned :class:`MotionMaps` belong to the model: they
stay valid through the next :meth:`VSTMD.step` and are overwritten by the one after.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit

from sarmission.perception.pyramid import half_resolution, halve
from sarmission.perception.types import MotionMaps

VALID_DS = (1, 2, 4, 8)
EGO_MOTION_MODES = ("estimate", "none")


@dataclass(frozen=True)
class VSTMDParams:
    """vSTMD constants: the vSTMD paper's and its public implementation's, except the lobula's
    surround strength ``dog_e`` (1.5 instead of 3: the reference suppresses swimmers on a
    textured sea, docs/experiments.md)."""

    retina_size: int = 3
    retina_sigma: float = 1.0
    alpha: float = 0.25
    lamina_width: int = 20
    g_leak: float = 0.35
    v_rest: float = 0.0
    v_exc: float = 1.0
    #: Lobula kernel ``W = A [D]^+ - B [D]^-``, ``D = G(s1) - e G(s2) - rho``. ``dog_e`` is the
    #: surround strength; it must stay below ``(s2/s1)^2`` for the kernel to have an excitatory
    #: centre. The default e departs from the reference e = 3 (docs/experiments.md).
    dog_a: float = 1.0
    dog_b: float = 3.0
    dog_e: float = 1.5
    dog_rho: float = 0.0
    #: Reference kernel at full resolution (sigmas, surround strength) and the target size
    #: (full-res px) it prefers. The size rule keeps its excitatory-lobe radius per target size,
    #: ``lobe_radius(s1_ref, s2_ref, e_ref) / size_ref``, for any ``dog_e``; ``s2 / s1`` stays
    #: ``sigma2_ref / sigma1_ref``.
    sigma1_ref: float = 5.0
    sigma2_ref: float = 10.0
    dog_e_ref: float = 3.0
    size_ref: float = 6.25
    #: Smallest centre sigma in map pixels (below this the Gaussian is a single tap).
    min_sigma: float = 0.5
    #: The lobula runs at 1/ds_L, ``ds_L = 2 ds`` clamped to this range (powers of two up to 8;
    #: ``(1, 1)`` = on the 1/ds map).
    lobula_ds_range: tuple[int, int] = (4, 8)
    #: ... and no coarser than where the centre sigma is at least this many pixels.
    lobula_min_sigma: float = 0.8
    #: Gaussian kernels are cut at this many sigmas.
    truncate: float = 3.0
    #: Ego-motion estimation: largest image (width, height) the shift is estimated on.
    ego_max_size: tuple[int, int] = (480, 270)
    #: Smallest drop of the mean absolute frame difference (intensity in [0, 1]) a shift must
    #: explain to be accepted (about half a grey level).
    ego_min_gain: float = 0.002
    #: Largest remaining share of the frame difference after the shift for it to be accepted.
    ego_max_ratio: float = 0.8
    #: Smallest share of the image whose frame difference exceeds ``ego_change_level`` for a
    #: shift to be accepted: the camera moves everything, a target only a small part.
    ego_min_changed: float = 0.2
    ego_change_level: float = 0.01
    #: Gauss-Newton refinement: most iterations and the step (estimation pixels) that stops it.
    ego_iterations: int = 5
    ego_tolerance: float = 0.005

    def __post_init__(self) -> None:
        ratio = self.sigma2_ref / self.sigma1_ref
        if not (self.sigma1_ref > 0 and ratio > 1):
            raise ValueError(f"need 0 < sigma1_ref < sigma2_ref, got {self.sigma1_ref}, "
                             f"{self.sigma2_ref}")
        for name in ("dog_e", "dog_e_ref"):
            e = getattr(self, name)
            if not 0 < e < ratio * ratio:
                raise ValueError(f"{name} must be in (0, (sigma2/sigma1)^2 = {ratio * ratio:g}) "
                                 f"for the kernel to have an excitatory centre, got {e}")
        low, high = self.lobula_ds_range
        if low not in VALID_DS or high not in VALID_DS or low > high:
            raise ValueError(f"lobula_ds_range must be two of {VALID_DS} in order, got "
                             f"{self.lobula_ds_range}")
        if not (self.dog_a > 0 and self.dog_b >= 0):
            raise ValueError(f"need dog_a > 0 and dog_b >= 0, got {self.dog_a}, {self.dog_b}")

    def lobe_per_size(self) -> float:
        """Excitatory-lobe radius per preferred target size of the reference kernel
        (``lobe_radius(s1_ref, s2_ref, e_ref) / size_ref``, about 0.70)."""
        return lobe_radius(self.sigma1_ref, self.sigma2_ref, self.dog_e_ref) / self.size_ref

    def lamina_coefficients(self) -> tuple[float, float]:
        """``(a0, decay)`` of the lamina recursion ``L_t = a0 * D_t + decay * L_{t-1}``."""
        rate = self.alpha / (1.0 - self.alpha)
        a0 = 1.0 / sum(math.exp(-rate * j) for j in range(self.lamina_width))
        return a0, math.exp(-rate)


def map_to_full(u: np.ndarray | float, ds: int) -> np.ndarray | float:
    """Full-resolution pixel coordinate of the centre of 1/ds map coordinate ``u``:
    ``(u + 0.5) * ds - 0.5`` (same rule for x/columns and y/rows).
    """
    return (u + 0.5) * ds - 0.5


def full_to_map_index(x: np.ndarray | float, ds: int, size: int) -> np.ndarray:
    """Nearest 1/ds map index of full-resolution coordinate ``x`` (the inverse of
    :func:`map_to_full`, rounded), clipped to ``[0, size - 1]``."""
    index = np.rint((np.asarray(x, dtype=np.float64) + 0.5) / ds - 0.5).astype(np.int64)
    return np.clip(index, 0, size - 1)


def lobe_radius(sigma1: float, sigma2: float, e: float) -> float:
    """Radius where ``G(s1) - e * G(s2)`` (2-D Gaussians, unit integral, ``rho = 0``) crosses zero.

    ``exp(-r^2 / 2 s1^2) / s1^2 = e * exp(-r^2 / 2 s2^2) / s2^2`` gives, with ``k = s2 / s1``::

        r = s1 * sqrt(2 k^2 ln(k^2 / e) / (k^2 - 1))       (k = 2: s1 * sqrt(8/3 * ln(4 / e)))

    defined for ``0 < e < k^2``: 0.88 s1 for e = 3, 1.62 s1 for e = 1.5, 1.92 s1 for e = 1.
    """
    k2 = (sigma2 / sigma1) ** 2
    if not (k2 > 1 and 0 < e < k2):
        raise ValueError(f"need sigma2 > sigma1 and 0 < e < (sigma2/sigma1)^2, got "
                         f"{sigma1}, {sigma2}, {e}")
    return sigma1 * math.sqrt(2.0 * k2 * math.log(k2 / e) / (k2 - 1.0))


def gaussian_1d(sigma: float, radius: int) -> np.ndarray:
    """Sampled Gaussian ``exp(-x^2 / (2 sigma^2))`` on ``x = -radius..radius``, unit sum."""
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    g = np.exp(-(x * x) / (2.0 * sigma * sigma))
    return g / g.sum()


def _check_ds(ds: int) -> int:
    if isinstance(ds, bool) or int(ds) != ds or int(ds) not in VALID_DS:
        raise ValueError(f"ds must be one of {VALID_DS} (average-pooling factor), got {ds!r}")
    return int(ds)


@njit(cache=True, fastmath=True, inline="always")
def _exp_small(x):
    """``exp(x)`` for ``0 <= x <~ 2`` as ``(sum_{k<=5} (x/8)^k / k!)^8``; relative error < 1e-5
    (|L| <= 1 for frames in [0, 1]). Vectorises, unlike the libm call.
    """
    y = x * np.float32(0.125)
    p = np.float32(1.0) + y * (np.float32(1.0) + y * (np.float32(0.5) + y * (
        np.float32(1.0 / 6.0) + y * (np.float32(1.0 / 24.0) + y * np.float32(1.0 / 120.0)))))
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
def _lamina_medulla(pooled, scale, p_prev, l_in, von_in, voff_in, l_out, von_out, voff_out,
                    corr, a0, decay, g_leak, v_rest, v_exc):  # pragma: no cover - numba
    """One fused pass at 1/ds: lamina recursion, ON/OFF split, cIDP update and ``C``.

    ``p_prev`` is updated in place; ``*_in`` are last frame's state, ``*_out`` this frame's.
    """
    h, w = pooled.shape
    for i in range(h):
        src = pooled[i]
        pp = p_prev[i]
        li = l_in[i]
        ai = von_in[i]
        bi = voff_in[i]
        lo = l_out[i]
        ao = von_out[i]
        bo = voff_out[i]
        co = corr[i]
        for j in range(w):
            p = np.float32(src[j]) * scale
            lt, a, b = _cell(p, pp[j], li[j], ai[j], bi[j], a0, decay, g_leak, v_rest, v_exc)
            pp[j] = p
            lo[j] = lt
            ao[j] = a
            bo[j] = b
            co[j] = a * b


def cubic_weights(frac: float) -> np.ndarray:
    """Catmull-Rom (Keys, a = -0.5) weights of the taps ``k + 1, k, k - 1, k - 2`` for the
    sample at ``k - frac`` (``frac`` in [0, 1)). With ``t = 1 - frac``::

        w = [t^3 - t^2,  -3t^3 + 4t^2 + t,  3t^3 - 5t^2 + 2,  -t^3 + 2t^2 - t] / 2
    """
    t = 1.0 - frac
    t2, t3 = t * t, t * t * t
    return np.array([t3 - t2, -3.0 * t3 + 4.0 * t2 + t, 3.0 * t3 - 5.0 * t2 + 2.0,
                     -t3 + 2.0 * t2 - t], np.float32) / np.float32(2.0)


@njit(cache=True, fastmath=True)
def _lamina_medulla_shifted(pooled, scale, p_in, l_in, von_in, voff_in, p_out, l_out, von_out,
                            voff_out, corr, column, kx, ky, fx, fy, cx, cy, a0, decay, g_leak,
                            v_rest, v_exc):  # pragma: no cover - numba
    """:func:`_lamina_medulla` with last frame's state carried by the shift ``s = k + f``
    (integer ``k``, fraction ``f`` in [0, 1)) into this frame's coordinates.

    The source of map pixel ``(i, j)`` is ``(i - s_y, j - s_x)``, between columns
    ``c = j - kx`` and ``c - 1``. ``P~`` is a Catmull-Rom cubic over columns ``c + 1 .. c - 2``
    (weights ``cx``, rows likewise with ``cy``); ``L``, ``V_on``, ``V_off`` are bilinear
    (weights ``1 - fx`` on ``c``, ``fx`` on ``c - 1``). Where a tap falls outside the map
    ``P~ = P'_t`` and ``L~ = V~ = 0``. Writes ``P'_t`` to ``p_out``; ``column`` is scratch of
    at least ``w + 3`` values.
    """
    h, w = pooled.shape
    zero = np.float32(0.0)
    one = np.float32(1.0)
    jlo = min(max(0, kx + 2), w)
    jhi = max(min(w, w + kx - 1), jlo)
    wx0, wx1 = one - fx, fx
    wy0, wy1 = one - fy, fy
    x0, x1, x2, x3 = cx[0], cx[1], cx[2], cx[3]
    y0, y1, y2, y3 = cy[0], cy[1], cy[2], cy[3]
    for i in range(h):
        src = pooled[i]
        po = p_out[i]
        lo = l_out[i]
        ao = von_out[i]
        bo = voff_out[i]
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
        # Row views aligned so that every index is the loop counter plus a constant >= 0 (lets
        # LLVM drop numba's negative-index wraparound checks and vectorise).
        base = start - kx - 2
        qa = p_in[r0 + 1, base:]
        qb = p_in[r0, base:]
        qc = p_in[r0 - 1, base:]
        qd = p_in[r0 - 2, base:]
        l0 = l_in[r0, base + 1:]
        l1 = l_in[r0 - 1, base + 1:]
        a0r = von_in[r0, base + 1:]
        a1r = von_in[r0 - 1, base + 1:]
        b0r = voff_in[r0, base + 1:]
        b1r = voff_in[r0 - 1, base + 1:]
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
def _translation_system(cur, prev, sx, sy, huber, level):  # pragma: no cover - numba
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
        q0 = prev[i - ky, jlo - kx - 1:]
        q1 = prev[i - ky - 1, jlo - kx - 1:]
        up = cur[i - 1, jlo:]
        row = cur[i, jlo - 1:]
        down = cur[i + 1, jlo:]
        for m in range(jhi - jlo):
            q = ((1.0 - fy) * ((1.0 - fx) * q0[m + 1] + fx * q0[m])
                 + fy * ((1.0 - fx) * q1[m + 1] + fx * q1[m]))
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
def _combine_rectify(centre, surround, bump, out):  # pragma: no cover - numba
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


class ShiftEstimator:
    """Dominant global translation between consecutive pooled retina images ``P'``.

    Every :meth:`update` area-pools ``P'`` by ``f = 2**k`` (the smallest ``k`` that fits the
    image in ``max_size``) into ``E_t`` and estimates the shift ``s`` with
    ``E_t(x) = E_{t-1}(x - s)``:

    1. coarse: ``cv2.phaseCorrelate`` of Hanning-windowed ``E`` pooled once more by 2; the
       whitened cross-power spectrum peaks at the translation of most of the image, whatever
       moves on top of it;
    2. fine: up to ``iterations`` robust Gauss-Newton steps on ``E`` (:func:`_translation_system`,
       Huber threshold ``1.345 * 1.253 * mean|r|``, i.e. 1.345 sigma for Gaussian residuals);
    3. gate: accept ``s`` only if ``e(0) - e(s) > min_gain``, ``e(s) < max_ratio * e(0)``
       (``e`` the mean absolute residual) and at least ``min_changed`` of the pixels differ by
       more than ``change_level`` at ``s = 0``; else report ``(0, 0)``.

    The result is in 1/ds map pixels (``f * s``).
    """

    def __init__(self, params: VSTMDParams | None = None) -> None:
        self.params = params or VSTMDParams()
        self.reset()

    def reset(self) -> None:
        """Forget the previous image: the next :meth:`update` returns ``(0, 0)``."""
        self._levels = 0
        self._prev: np.ndarray | None = None
        self._prev_coarse: np.ndarray | None = None
        self._window: np.ndarray | None = None

    def _images(self, pooled: np.ndarray, scale: np.float32) -> tuple[np.ndarray, np.ndarray]:
        """``(E, coarse E)`` as float32 in [0, 1]."""
        if self._window is None:
            max_w, max_h = self.params.ego_max_size
            h, w = pooled.shape
            levels = 0
            while (w >> levels) > max_w or (h >> levels) > max_h:
                levels += 1
            self._levels = levels
            ch, cw = (h >> levels) // 2, (w >> levels) // 2
            self._window = cv2.createHanningWindow((cw, ch), cv2.CV_32F)
        f = 1 << self._levels
        ch, cw = self._window.shape
        eh, ew = ch * 2, cw * 2
        est = halve(pooled[:eh * f, :ew * f], self._levels).astype(np.float32) * scale
        coarse = cv2.resize(est, (cw, ch), interpolation=cv2.INTER_AREA)
        return est, coarse

    def observe(self, pooled: np.ndarray, scale: np.float32) -> None:
        """Keep ``P'_t`` as the reference of the next estimate without estimating (used when the
        shift comes from elsewhere).
        """
        self._prev, self._prev_coarse = self._images(pooled, scale)

    def update(self, pooled: np.ndarray, scale: np.float32) -> tuple[float, float]:
        """Shift ``(dx, dy)`` in map pixels from the last image to ``P'_t`` (``(0, 0)`` on the
        first image and whenever the estimate is refused).
        """
        est, coarse = self._images(pooled, scale)
        prev, prev_coarse = self._prev, self._prev_coarse
        self._prev, self._prev_coarse = est, coarse
        if prev is None or prev_coarse is None or min(coarse.shape) < 4:
            return 0.0, 0.0
        (cx, cy), _ = cv2.phaseCorrelate(prev_coarse, coarse, self._window)
        p = self.params
        s = np.array([2.0 * cx, 2.0 * cy])
        level = p.ego_change_level
        *_, err0, changed, _ = _translation_system(est, prev, 0.0, 0.0, np.inf, level)
        if changed < p.ego_min_changed:
            return 0.0, 0.0
        huber = np.inf
        err, count = err0, 0
        for _ in range(p.ego_iterations):
            a11, a12, a22, b1, b2, err, _, count = _translation_system(est, prev, s[0], s[1],
                                                                       huber, level)
            det = a11 * a22 - a12 * a12
            if count == 0 or not det > 1e-12 * max(a11 * a22, 1e-30):
                return 0.0, 0.0
            step = -np.array([a22 * b1 - a12 * b2, a11 * b2 - a12 * b1]) / det
            s += step
            huber = max(1.345 * 1.253 * err, 1e-6)
            if float(np.hypot(*step)) < p.ego_tolerance:
                break
        *_, err, _, count = _translation_system(est, prev, s[0], s[1], np.inf, level)
        if count < 0.25 * est.size or not (err0 - err > p.ego_min_gain
                                          and err < p.ego_max_ratio * err0):
            return 0.0, 0.0
        f = float(1 << self._levels)
        return float(s[0]) * f, float(s[1]) * f

    def flops(self, height: int, width: int) -> int:
        """Upper estimate of the operations per update for a ``height x width`` map: pooling
        1/map px; per estimation px 3 x 20 (residual and gradient, twice for the gate) plus
        ``iterations`` x 25 (Gauss-Newton); per coarse px the phase correlation, 3 DFTs of
        ``5 n log2 n`` plus 10 (window, spectrum normalisation, peak).
        """
        levels = 0
        max_w, max_h = self.params.ego_max_size
        while (width >> levels) > max_w or (height >> levels) > max_h:
            levels += 1
        n_est = (height >> levels) * (width >> levels)
        n_coarse = max(n_est // 4, 1)
        return int(height * width + n_est * (60 + 25 * self.params.ego_iterations)
                   + n_coarse * (15 * math.log2(max(n_coarse, 2)) + 10))


class VSTMD:
    """Streaming vSTMD for one video (maths and geometry: docs/vstmd.md).

    Args:
        ds: average-pooling factor of the motion maps, one of 1, 2, 4, 8.
        target_size: expected target size in full-resolution pixels; sets the DoG sigmas
            (default 16: swimmers seen from 60-120 m).
        params: model constants (:class:`VSTMDParams`).
        ego_motion: ``"estimate"`` compensates the camera's global translation estimated from
            the frames (:class:`ShiftEstimator`); ``"none"`` leaves the state where it is (a
            static camera). A shift given to :meth:`step` overrides either.

    After each :meth:`step`, ``last_shift`` is the shift ``(dx, dy)`` that was compensated, in
    full-resolution pixels (content moved from ``x`` to ``x + shift``); ``(0.0, 0.0)`` when none.

    Frames are BGR uint8 ``[H, W, 3]``, grayscale uint8 ``[H, W]`` (both scaled by 1/255) or
    grayscale float32 ``[H, W]`` in [0, 1]. All frames of a stream must have the same size;
    :meth:`reset` starts a new stream.
    """

    def __init__(self, ds: int = 2, target_size: float = 16.0,
                 params: VSTMDParams | None = None, ego_motion: str = "estimate") -> None:
        self.ds = _check_ds(ds)
        if ego_motion not in EGO_MOTION_MODES:
            raise ValueError(f"ego_motion must be one of {EGO_MOTION_MODES}, got {ego_motion!r}")
        self.ego_motion = ego_motion
        if not target_size > 0:
            raise ValueError(f"target_size must be positive (full-resolution pixels), got "
                             f"{target_size}")
        self.target_size = float(target_size)
        self.params = params or VSTMDParams()
        p = self.params
        a0, decay = p.lamina_coefficients()
        self._a0, self._decay = np.float32(a0), np.float32(decay)
        #: The lobula's pooling of ``C`` (1 = none); its sigmas are in pooled map pixels.
        self.lobula_pool = self.lobula_pooling(self.ds, self.target_size, p)
        self.sigma1, self.sigma2 = self.dog_sigmas(self.ds * self.lobula_pool,
                                                   self.target_size, p)
        self._build_lobula_kernels()
        self._estimator = ShiftEstimator(p) if ego_motion == "estimate" else None
        self.reset()

    # ------------------------------------------------------------------ kernels
    @classmethod
    def lobula_pooling(cls, ds: int, target_size: float, params: VSTMDParams) -> int:
        """Factor ``f`` by which the lobula pools the 1/ds correlation map (docs/vstmd.md,
        "Lobula resolution"):
        ``ds_L = clamp(2 ds, *lobula_ds_range)``, halved while the centre sigma at 1/ds_L is
        below ``lobula_min_sigma``; ``f = max(ds_L / ds, 1)``."""
        low, high = params.lobula_ds_range
        lobula_ds = min(max(2 * ds, low), high)
        while (lobula_ds > ds and cls.dog_sigmas(lobula_ds, target_size, params)[0]
               < params.lobula_min_sigma):
            lobula_ds //= 2
        return max(1, lobula_ds // ds)

    @staticmethod
    def dog_sigmas(ds: int, target_size: float,
                   params: VSTMDParams | None = None) -> tuple[float, float]:
        """Size-selective DoG sigmas ``(s1, s2)`` in 1/ds map pixels: the excitatory lobe radius
        is ``kappa * T / ds`` (``kappa`` = :meth:`VSTMDParams.lobe_per_size`), so::

            s1 = max(kappa * T / ds / lobe_radius(1, k, e), s_min),   s2 = k * s1
            (k = sigma2_ref / sigma1_ref)

        With ``e = e_ref`` this is the reference rule ``s1 = s1_ref * T / T_ref / ds``.
        """
        p = params or VSTMDParams()
        k = p.sigma2_ref / p.sigma1_ref
        radius = p.lobe_per_size() * target_size / _check_ds(ds)
        s1 = max(radius / lobe_radius(1.0, k, p.dog_e), p.min_sigma)
        return s1, s1 * k

    def _build_lobula_kernels(self) -> None:
        p = self.params
        r1 = max(1, int(math.ceil(p.truncate * self.sigma1)))
        r2 = max(1, int(math.ceil(p.truncate * self.sigma2)))
        g1 = gaussian_1d(self.sigma1, r1)
        g2 = gaussian_1d(self.sigma2, r2)
        rad = max(r1, r2)
        d = self._centre_surround(g1, g2, rad)
        bump = np.maximum(d, 0.0)
        rows = np.flatnonzero(bump.any(axis=1))
        rb = int(max(rad - rows.min(), rows.max() - rad)) if rows.size else 0
        self._radius = rad
        # Pre-scaled terms: B*G1*C, B*e*G2*C (square kernel scaled on one axis) and (A-B)*D^+*C.
        self._g1 = g1.astype(np.float32)
        self._g1_scaled = (p.dog_b * g1).astype(np.float32)
        self._g2 = g2.astype(np.float32)
        self._g2_scaled = (p.dog_b * p.dog_e * g2).astype(np.float32)
        self._bump = ((p.dog_a - p.dog_b)
                      * bump[rad - rb:rad + rb + 1, rad - rb:rad + rb + 1]).astype(np.float32)
        self._rho_scaled = float(p.dog_b * p.dog_rho)

    def _centre_surround(self, g1: np.ndarray, g2: np.ndarray, rad: int) -> np.ndarray:
        """Dense ``G(s1) - e * G(s2) - rho`` on a ``(2*rad+1)^2`` support (float64)."""
        def pad(g: np.ndarray) -> np.ndarray:
            r = g.size // 2
            return np.pad(g, rad - r)

        p1, p2 = pad(g1), pad(g2)
        return np.outer(p1, p1) - self.params.dog_e * np.outer(p2, p2) - self.params.dog_rho

    def dog_kernel(self) -> np.ndarray:
        """Dense 2-D lobula kernel ``W = A [D]^+ - B [D]^-`` (float64, for checks and plots)."""
        p = self.params
        d = self._centre_surround(gaussian_1d(self.sigma1, self._g1.size // 2),
                                  gaussian_1d(self.sigma2, self._g2.size // 2), self._radius)
        return p.dog_a * np.maximum(d, 0.0) - p.dog_b * np.maximum(-d, 0.0)

    # ------------------------------------------------------------------ stream
    def reset(self) -> None:
        """Forget all state: the next frame is the first of a new stream (any size)."""
        self._shape: tuple[int, int] | None = None
        self._sets: list[dict[str, np.ndarray]] = []
        self._scratch: dict[str, np.ndarray] = {}
        self._p_prev = np.zeros((0, 0), np.float32)
        self._p_spare = np.zeros((0, 0), np.float32)
        self._parity = 0
        self._first = True
        self.last_shift: tuple[float, float] = (0.0, 0.0)
        if self._estimator is not None:
            self._estimator.reset()

    def map_shape(self, height: int, width: int) -> tuple[int, int]:
        """``(h, w)`` of the 1/ds maps for ``height x width`` frames."""
        return height // self.ds, width // self.ds

    def _allocate(self, h: int, w: int) -> None:
        names = ("temporal_change", "v_on", "v_off", "correlation", "response")
        self._sets = [{n: np.zeros((h, w), np.float32) for n in names} for _ in range(2)]
        f = self.lobula_pool
        hl, wl = h // f, w // f
        lobula = ("centre", "surround", "bump") + (("coarse",) if f > 1 else ())
        self._scratch = {n: np.empty((hl, wl), np.float32) for n in lobula}
        self._scratch["column"] = np.empty(w + 3, np.float32)
        self._p_prev = np.zeros((h, w), np.float32)
        self._p_spare = np.zeros((h, w), np.float32)

    def _pooled(self, frame: np.ndarray, h: int, w: int,
                half: np.ndarray | None) -> tuple[np.ndarray, np.float32]:
        """``P'`` at 1/ds and the scale to [0, 1] (docs/vstmd.md, "Linear shortcut")."""
        ds = self.ds
        k = self.params.retina_size
        if ds == 1:
            img, sigma = frame[:h, :w], self.params.retina_sigma
        else:  # from the half-resolution frame, where the retina's sigma is half as wide
            img = (half if half is not None else half_resolution(frame))[:h * ds // 2,
                                                                          :w * ds // 2]
            sigma = self.params.retina_sigma / 2
        if img.ndim == 3:
            img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        img = cv2.GaussianBlur(img, (k, k), sigma, borderType=cv2.BORDER_REFLECT_101)
        # The rest of the pooling as exact halvings (OpenCV's 2x INTER_AREA path is several times
        # faster than its general 4x one; the mean of block means is the block mean).
        img = halve(img, max(int(math.log2(ds)) - 1, 0))
        scale = np.float32(1.0 / 255.0) if img.dtype == np.uint8 else np.float32(1.0)
        return img, scale

    def _check_frame(self, frame: np.ndarray) -> tuple[int, int]:
        if not isinstance(frame, np.ndarray):
            raise ValueError(f"frame must be a numpy array, got {type(frame).__name__}")
        colour = frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
        gray = frame.ndim == 2 and frame.dtype in (np.uint8, np.float32)
        if not (colour or gray):
            raise ValueError("frame must be BGR uint8 [H, W, 3] or grayscale uint8/float32 "
                             f"[H, W], got {frame.dtype} {list(frame.shape)}")
        height, width = int(frame.shape[0]), int(frame.shape[1])
        if height < self.ds or width < self.ds:
            raise ValueError(f"frame {width}x{height} is smaller than ds={self.ds}")
        if self._shape is not None and (height, width) != self._shape:
            raise ValueError(f"frame size changed from {self._shape[1]}x{self._shape[0]} to "
                             f"{width}x{height}; call reset() to start a new stream")
        return height, width

    def step(self, frame: np.ndarray, shift_px: tuple[float, float] | None = None,
             half: np.ndarray | None = None) -> MotionMaps:
        """Advance the model by one frame and return this frame's 1/ds maps.

        ``shift_px = (dx, dy)``, if given, is the camera-induced translation of the scene since
        the previous frame in full-resolution pixels (e.g. from telemetry); it replaces the
        estimate (and applies with ``ego_motion="none"`` too). Ignored on a stream's first frame.
        ``half`` is :func:`~sarmission.perception.pyramid.half_resolution` of ``frame`` when the
        caller has it already (ds >= 2 starts from it).
        """
        height, width = self._check_frame(frame)
        h, w = self.map_shape(height, width)
        if self._shape is None:
            self._shape = (height, width)
            self._allocate(h, w)
        pooled, scale = self._pooled(frame, h, w, half)
        sx, sy = self._shift(pooled, scale, shift_px)
        self.last_shift = (sx * self.ds, sy * self.ds)
        if self._first:
            self._p_prev[...] = pooled * scale  # D = 0 on the first frame
            self._first = False
        old, new = self._sets[self._parity], self._sets[1 - self._parity]
        self._parity = 1 - self._parity
        p = self.params
        f32 = np.float32
        constants = (self._a0, self._decay, f32(p.g_leak), f32(p.v_rest), f32(p.v_exc))
        if sx == 0.0 and sy == 0.0:
            _lamina_medulla(pooled, scale, self._p_prev, old["temporal_change"], old["v_on"],
                            old["v_off"], new["temporal_change"], new["v_on"], new["v_off"],
                            new["correlation"], *constants)
        else:
            kx, ky = math.floor(sx), math.floor(sy)
            _lamina_medulla_shifted(pooled, scale, self._p_prev, old["temporal_change"],
                                    old["v_on"], old["v_off"], self._p_spare,
                                    new["temporal_change"], new["v_on"], new["v_off"],
                                    new["correlation"], self._scratch["column"], kx, ky,
                                    f32(sx - kx), f32(sy - ky), cubic_weights(sx - kx),
                                    cubic_weights(sy - ky), *constants)
            self._p_prev, self._p_spare = self._p_spare, self._p_prev
        self._lobula(new["correlation"], new["response"])
        return MotionMaps(ds=self.ds, temporal_change=new["temporal_change"], v_on=new["v_on"],
                          v_off=new["v_off"], correlation=new["correlation"],
                          response=new["response"])

    def _shift(self, pooled: np.ndarray, scale: np.float32,
               shift_px: tuple[float, float] | None) -> tuple[float, float]:
        """This frame's shift in map pixels: supplied, estimated or zero (first frame)."""
        moved = (0.0, 0.0)
        if shift_px is not None:
            dx, dy = (float(v) for v in shift_px)
            if not (math.isfinite(dx) and math.isfinite(dy)):
                raise ValueError(f"shift_px must be two finite numbers, got {shift_px!r}")
            moved = (dx / self.ds, dy / self.ds)
        if self._estimator is not None:
            if shift_px is None:
                moved = self._estimator.update(pooled, scale)
            else:
                self._estimator.observe(pooled, scale)
        return (0.0, 0.0) if self._first else moved

    def _lobula(self, corr: np.ndarray, out: np.ndarray) -> None:
        """``out = max(W * corr, 0)``, at the lobula's resolution (docs/vstmd.md)."""
        f = self.lobula_pool
        if f == 1:
            self._lobula_filter(corr, out)
            return
        s = self._scratch
        hl, wl = s["coarse"].shape
        if hl == 0 or wl == 0:
            out[...] = 0.0
            return
        self._lobula_filter(halve(corr[:hl * f, :wl * f], int(math.log2(f))), s["coarse"])
        size = (wl * f, hl * f)
        if out.shape == size[::-1]:
            cv2.resize(s["coarse"], size, dst=out, interpolation=cv2.INTER_LINEAR)
            return
        out[...] = 0.0
        out[:hl * f, :wl * f] = cv2.resize(s["coarse"], size, interpolation=cv2.INTER_LINEAR)

    def _lobula_filter(self, corr: np.ndarray, out: np.ndarray) -> None:
        """``out = max(W * corr, 0)`` via the separable decomposition of ``W``."""
        s = self._scratch
        border = cv2.BORDER_CONSTANT
        cv2.sepFilter2D(corr, -1, self._g1, self._g1_scaled, dst=s["centre"], borderType=border)
        cv2.sepFilter2D(corr, -1, self._g2, self._g2_scaled, dst=s["surround"],
                        borderType=border)
        if self._rho_scaled:
            size = 2 * self._radius + 1
            box = cv2.boxFilter(corr, -1, (size, size), normalize=False, borderType=border)
            s["surround"] += self._rho_scaled * box
        cv2.filter2D(corr, -1, self._bump, dst=s["bump"], borderType=border)
        _combine_rectify(s["centre"], s["surround"], s["bump"], out)

    # ------------------------------------------------------------------ cost
    def flops(self, height: int, width: int) -> int:
        """Arithmetic operations per frame for a BGR ``height x width`` frame (mul, add, max and
        compare each count 1; ``exp`` counts as its 14-operation polynomial)::

            at ds 1 gray 5/px and retina 3x3 separable 10/px at full resolution; at ds >= 2 the
            halving 3 x 1/px at full resolution, then gray 5 and retina 10 per half-resolution px
            (cropped to ds multiples);
            per map px: pooling (ds/2)^2 (ds > 2), scale 1, lamina 4, ON/OFF 2, cIDP 2 x (7 + 14),
            C 1; per lobula px: 2(2K1-1) + 2(2K2-1) + (2Kb^2 - 1) (+ 4 for rho != 0), combine 3;
            when the lobula pools C by f > 1, also the pooling (4/3 per map px) and the bilinear
            resize back (6 per map px); with ego_motion="estimate" also the shift resampling,
            34 per map px, and :meth:`ShiftEstimator.flops`.
        """
        h, w = self.map_shape(height, width)
        full = h * self.ds * w * self.ds
        maps = h * w
        f = self.lobula_pool
        lobula_px = (h // f) * (w // f)
        per_map = ((self.ds // 2) ** 2 if self.ds > 2 else 0) + 1 + 4 + 2 + 2 * (7 + 14) + 1
        k1, k2, kb = self._g1.size, self._g2.size, self._bump.shape[0]
        per_lobula = 2 * (2 * k1 - 1) + 2 * (2 * k2 - 1) + (2 * kb * kb - 1) + 3
        if self._rho_scaled:
            per_lobula += 4
        photoreceptor = full * (5 + 10) if self.ds == 1 else full * 3 + full // 4 * (5 + 10)
        total = photoreceptor + maps * per_map + lobula_px * per_lobula
        if f > 1:
            total += int(maps * (4 / 3 + 6))
        if self._estimator is not None:
            # cubic P~ (4 + 4 taps, 2 ops each) and bilinear L~, V~ (3 x 6) when the camera moves
            total += maps * 34 + self._estimator.flops(h, w)
        return int(total)


def direction_at(motion: MotionMaps, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Motion direction (CDGC) at integer 1/ds map coordinates ``(xs, ys)`` → radians in [0, 2pi).

    In the 3x3 neighbourhood of each point::

        G = V_off / V_on   where L > 0 and V_on > 0
        G = V_on / V_off   where L < 0 and V_off > 0,     else 0
        theta = atan2(sum G * Ks, sum G * Kc) mod 2pi,   Kc = dx / r,  Ks = -dy / r

    (``r = sqrt(dx^2 + dy^2)``, centre weight 0, ``dx`` to the right, ``dy`` down the rows; the
    sums are a correlation, ``sum_{dx,dy} G(x + dx, y + dy) K(dx, dy)``). Angle convention:
    0 = +x (right), pi/2 = up (-y), counter-clockwise as seen on screen. Neighbours outside the
    map count as G = 0; a point with G = 0 all round gets theta = 0.
    """
    xs = np.asarray(xs, dtype=np.int64).ravel()
    ys = np.asarray(ys, dtype=np.int64).ravel()
    if xs.shape != ys.shape:
        raise ValueError(f"xs and ys differ in length: {xs.size} vs {ys.size}")
    lam, von, voff = motion.temporal_change, motion.v_on, motion.v_off
    h, w = lam.shape
    d = np.array([-1, 0, 1])
    dy, dx = np.meshgrid(d, d, indexing="ij")
    r = np.hypot(dx, dy)
    r[1, 1] = 1.0
    kc, ks = dx / r, -dy / r
    yy = ys[:, None, None] + dy[None]
    xx = xs[:, None, None] + dx[None]
    inside = (yy >= 0) & (yy < h) & (xx >= 0) & (xx < w)
    yc, xc = np.clip(yy, 0, h - 1), np.clip(xx, 0, w - 1)
    lv = lam[yc, xc].astype(np.float64)
    a = von[yc, xc].astype(np.float64)
    b = voff[yc, xc].astype(np.float64)
    on_side = (lv > 0) & (a > 0)
    off_side = (lv < 0) & (b > 0)
    g = np.zeros_like(lv)
    g[on_side] = b[on_side] / a[on_side]
    g[off_side] = a[off_side] / b[off_side]
    g[~inside] = 0.0
    sx = (g * kc).sum(axis=(1, 2))
    sy = (g * ks).sum(axis=(1, 2))
    return np.mod(np.arctan2(sy, sx), 2.0 * np.pi).astype(np.float32)
