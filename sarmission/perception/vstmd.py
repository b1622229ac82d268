"""vSTMD: the learning-free small-target motion front-end of MITE-Net (streaming, one video).

Per frame it turns a grayscale image into 1/ds motion maps: retina blur, lamina (fractional
temporal difference), medulla (ON/OFF cross-inhibition potentials), their correlation ``C`` and
the lobula's size-selective centre-surround response ``R`` (:class:`MotionMaps`), which the
TTM-RPN proposes from. The camera's own motion is compensated first, so only what moves
against the background responds. Everything before the 1/ds map is linear, so the only
full-resolution work is one OpenCV pass per frame; the rest is one fused numba loop
(:mod:`~sarmission.perception.vstmd_kernels`, compiled ahead of time by
:mod:`~sarmission.perception.kernels`) plus separable lobula filters. The camera's shift comes
from :mod:`~sarmission.perception.ego_motion`, the constants from
:mod:`~sarmission.perception.vstmd_params`. The equations, geometry and approximations are in
docs/vstmd.md, the measurements behind the constants in docs/experiments.md.

Map pixel ``(i, j)`` averages frame rows ``i*ds .. i*ds+ds-1`` and columns ``j*ds .. j*ds+ds-1``
(:func:`map_to_full`). The arrays of a returned :class:`MotionMaps` belong to the model: they
stay valid until the next :meth:`VSTMD.step`, which overwrites them (``correlation`` and
``response``) or the one after (the others).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from sarmission.perception.ego_motion import ShiftEstimator
from sarmission.perception.kernels import (
    combine_rectify,
    cubic_weights,
    lamina_medulla,
    lamina_medulla_shifted,
    ring_rows,
)
from sarmission.perception.pyramid import half_resolution, halve
from sarmission.perception.types import VALID_DS, MotionMaps
from sarmission.perception.vstmd_params import VSTMDParams, check_ds, gaussian_1d, lobe_radius

__all__ = [
    "EGO_MOTION_MODES",
    "VALID_DS",
    "VSTMD",
    "ShiftEstimator",
    "VSTMDParams",
    "direction_at",
    "full_to_map_index",
    "lobe_radius",
    "map_to_full",
]

EGO_MOTION_MODES = ("estimate", "none")


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

    def __init__(
        self,
        ds: int = 2,
        target_size: float = 16.0,
        params: VSTMDParams | None = None,
        ego_motion: str = "estimate",
    ) -> None:
        self.ds = check_ds(ds)
        if ego_motion not in EGO_MOTION_MODES:
            raise ValueError(f"ego_motion must be one of {EGO_MOTION_MODES}, got {ego_motion!r}")
        self.ego_motion = ego_motion
        if not target_size > 0:
            raise ValueError(
                f"target_size must be positive (full-resolution pixels), got {target_size}"
            )
        self.target_size = float(target_size)
        self.params = params or VSTMDParams()
        p = self.params
        a0, decay = p.lamina_coefficients()
        self._a0, self._decay = np.float32(a0), np.float32(decay)
        #: The lobula's pooling of ``C`` (1 = none); its sigmas are in pooled map pixels.
        self.lobula_pool = self.lobula_pooling(self.ds, self.target_size, p)
        self.sigma1, self.sigma2 = self.dog_sigmas(self.ds * self.lobula_pool, self.target_size, p)
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
        while (
            lobula_ds > ds
            and cls.dog_sigmas(lobula_ds, target_size, params)[0] < params.lobula_min_sigma
        ):
            lobula_ds //= 2
        return max(1, lobula_ds // ds)

    @staticmethod
    def dog_sigmas(
        ds: int, target_size: float, params: VSTMDParams | None = None
    ) -> tuple[float, float]:
        """Size-selective DoG sigmas ``(s1, s2)`` in 1/ds map pixels: the excitatory lobe radius
        is ``kappa * T / ds`` (``kappa`` = :meth:`VSTMDParams.lobe_per_size`), so::

            s1 = max(kappa * T / ds / lobe_radius(1, k, e), s_min),   s2 = k * s1
            (k = sigma2_ref / sigma1_ref)

        With ``e = e_ref`` this is the reference rule ``s1 = s1_ref * T / T_ref / ds``.
        """
        p = params or VSTMDParams()
        k = p.sigma2_ref / p.sigma1_ref
        radius = p.lobe_per_size() * target_size / check_ds(ds)
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
        self._bump = (
            (p.dog_a - p.dog_b) * bump[rad - rb : rad + rb + 1, rad - rb : rad + rb + 1]
        ).astype(np.float32)
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
        d = self._centre_surround(
            gaussian_1d(self.sigma1, self._g1.size // 2),
            gaussian_1d(self.sigma2, self._g2.size // 2),
            self._radius,
        )
        return p.dog_a * np.maximum(d, 0.0) - p.dog_b * np.maximum(-d, 0.0)

    # ------------------------------------------------------------------ stream
    def reset(self) -> None:
        """Forget all state: the next frame is the first of a new stream (any size)."""
        self._shape: tuple[int, int] | None = None
        self._state: dict[str, np.ndarray] = {}
        self._scratch: dict[str, np.ndarray] = {}
        self._ring = np.zeros((4, 0, 0), np.float32)
        self._first = True
        self.last_shift: tuple[float, float] = (0.0, 0.0)
        if self._estimator is not None:
            self._estimator.reset()

    def map_shape(self, height: int, width: int) -> tuple[int, int]:
        """``(h, w)`` of the 1/ds maps for ``height x width`` frames."""
        return height // self.ds, width // self.ds

    def _allocate(self, h: int, w: int) -> None:
        # One map each (8 MB apiece at 4K and ds 2): the kernels update P', L, V_on and V_off in
        # place; C and R are only read out.
        names = ("p_prev", "temporal_change", "v_on", "v_off", "correlation", "response")
        self._state = {n: np.zeros((h, w), np.float32) for n in names}
        f = self.lobula_pool
        hl, wl = h // f, w // f
        lobula = ("centre", "surround", "bump") + (("coarse",) if f > 1 else ())
        self._scratch = {n: np.empty((hl, wl), np.float32) for n in lobula}
        self._scratch["column"] = np.empty(w + 3, np.float32)
        self._ring = np.zeros((4, 0, w), np.float32)

    def _ring_for(self, ky: int, h: int) -> np.ndarray:
        """The shifted kernel's rows of last frame's state, grown for ``ky`` when needed."""
        rows = ring_rows(ky, h)
        if self._ring.shape[1] < rows:
            self._ring = np.empty((4, rows, self._ring.shape[2]), np.float32)
        return self._ring

    def _pooled(
        self, frame: np.ndarray, h: int, w: int, half: np.ndarray | None
    ) -> tuple[np.ndarray, np.float32]:
        """``P'`` at 1/ds and the scale to [0, 1] (docs/vstmd.md, "Linear shortcut")."""
        ds = self.ds
        k = self.params.retina_size
        if ds == 1:
            img, sigma = frame[:h, :w], self.params.retina_sigma
        else:  # from the half-resolution frame, where the retina's sigma is half as wide
            img = (half if half is not None else half_resolution(frame))[
                : h * ds // 2, : w * ds // 2
            ]
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
            raise ValueError(
                "frame must be BGR uint8 [H, W, 3] or grayscale uint8/float32 "
                f"[H, W], got {frame.dtype} {list(frame.shape)}"
            )
        height, width = int(frame.shape[0]), int(frame.shape[1])
        if height < self.ds or width < self.ds:
            raise ValueError(f"frame {width}x{height} is smaller than ds={self.ds}")
        if self._shape is not None and (height, width) != self._shape:
            raise ValueError(
                f"frame size changed from {self._shape[1]}x{self._shape[0]} to "
                f"{width}x{height}; call reset() to start a new stream"
            )
        return height, width

    def step(
        self,
        frame: np.ndarray,
        shift_px: tuple[float, float] | None = None,
        half: np.ndarray | None = None,
    ) -> MotionMaps:
        """Advance the model by one frame and return this frame's 1/ds maps.

        ``shift_px = (dx, dy)``, if given, is the camera-induced translation of the scene since
        the previous frame in full-resolution pixels (e.g. from telemetry); it replaces the
        estimate (and applies with ``ego_motion="none"`` too). Ignored on a stream's first frame.
        ``half`` is :func:`~sarmission.perception.pyramid.half_resolution` of ``frame`` when the
        caller has it already (ds >= 2 starts from it and reads only ``frame``'s size).
        """
        height, width = self._check_frame(frame)
        h, w = self.map_shape(height, width)
        if self._shape is None:
            self._shape = (height, width)
            self._allocate(h, w)
        pooled, scale = self._pooled(frame, h, w, half)
        sx, sy = self._shift(pooled, scale, shift_px)
        self.last_shift = (sx * self.ds, sy * self.ds)
        state = self._state
        if self._first:
            state["p_prev"][...] = pooled * scale  # D = 0 on the first frame
            self._first = False
        p = self.params
        f32 = np.float32
        constants = (self._a0, self._decay, f32(p.g_leak), f32(p.v_rest), f32(p.v_exc))
        maps = (state["p_prev"], state["temporal_change"], state["v_on"], state["v_off"])
        if sx == 0.0 and sy == 0.0:
            lamina_medulla(pooled, scale, *maps, state["correlation"], *constants)
        else:
            kx, ky = math.floor(sx), math.floor(sy)
            lamina_medulla_shifted(
                pooled,
                scale,
                *maps,
                state["correlation"],
                self._ring_for(ky, h),
                self._scratch["column"],
                kx,
                ky,
                f32(sx - kx),
                f32(sy - ky),
                cubic_weights(sx - kx),
                cubic_weights(sy - ky),
                *constants,
            )
        self._lobula(state["correlation"], state["response"])
        return MotionMaps(
            ds=self.ds,
            temporal_change=state["temporal_change"],
            v_on=state["v_on"],
            v_off=state["v_off"],
            correlation=state["correlation"],
            response=state["response"],
        )

    def _shift(
        self, pooled: np.ndarray, scale: np.float32, shift_px: tuple[float, float] | None
    ) -> tuple[float, float]:
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
        self._lobula_filter(halve(corr[: hl * f, : wl * f], int(math.log2(f))), s["coarse"])
        size = (wl * f, hl * f)
        if out.shape == size[::-1]:
            cv2.resize(s["coarse"], size, dst=out, interpolation=cv2.INTER_LINEAR)
            return
        out[...] = 0.0
        out[: hl * f, : wl * f] = cv2.resize(s["coarse"], size, interpolation=cv2.INTER_LINEAR)

    def _lobula_filter(self, corr: np.ndarray, out: np.ndarray) -> None:
        """``out = max(W * corr, 0)`` via the separable decomposition of ``W``."""
        s = self._scratch
        border = cv2.BORDER_CONSTANT
        cv2.sepFilter2D(corr, -1, self._g1, self._g1_scaled, dst=s["centre"], borderType=border)
        cv2.sepFilter2D(corr, -1, self._g2, self._g2_scaled, dst=s["surround"], borderType=border)
        if self._rho_scaled:
            size = 2 * self._radius + 1
            box = cv2.boxFilter(corr, -1, (size, size), normalize=False, borderType=border)
            s["surround"] += self._rho_scaled * box
        cv2.filter2D(corr, -1, self._bump, dst=s["bump"], borderType=border)
        combine_rectify(s["centre"], s["surround"], s["bump"], out)

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
