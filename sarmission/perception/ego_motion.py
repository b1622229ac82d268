"""Camera ego-motion for vSTMD: the dominant translation between consecutive frames.

On a moving camera the whole scene moves; vSTMD must carry its state along with it so that it
sees only motion against the background. :class:`ShiftEstimator` finds that translation from
the pooled retina images (phase correlation, then robust Gauss-Newton) and refuses it when it
does not explain most of the change, so a still camera gets exactly zero.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from sarmission.perception.kernels import translation_system
from sarmission.perception.pyramid import halve
from sarmission.perception.vstmd_params import VSTMDParams


class ShiftEstimator:
    """Dominant global translation between consecutive pooled retina images ``P'``.

    Every :meth:`update` area-pools ``P'`` by ``f = 2**k`` (the smallest ``k`` that fits the
    image in ``max_size``) into ``E_t`` and estimates the shift ``s`` with
    ``E_t(x) = E_{t-1}(x - s)``:

    1. coarse: ``cv2.phaseCorrelate`` of Hanning-windowed ``E`` pooled once more by 2; the
       whitened cross-power spectrum peaks at the translation of most of the image, whatever
       moves on top of it;
    2. fine: up to ``iterations`` robust Gauss-Newton steps on ``E`` (:func:`translation_system`,
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
        est = halve(pooled[: eh * f, : ew * f], self._levels).astype(np.float32) * scale
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
        *_, err0, changed, _ = translation_system(est, prev, 0.0, 0.0, np.inf, level)
        if changed < p.ego_min_changed:
            return 0.0, 0.0
        huber = np.inf
        err, count = err0, 0
        for _ in range(p.ego_iterations):
            a11, a12, a22, b1, b2, err, _, count = translation_system(
                est, prev, s[0], s[1], huber, level
            )
            det = a11 * a22 - a12 * a12
            if count == 0 or not det > 1e-12 * max(a11 * a22, 1e-30):
                return 0.0, 0.0
            step = -np.array([a22 * b1 - a12 * b2, a11 * b2 - a12 * b1]) / det
            s += step
            huber = max(1.345 * 1.253 * err, 1e-6)
            if float(np.hypot(*step)) < p.ego_tolerance:
                break
        *_, err, _, count = translation_system(est, prev, s[0], s[1], np.inf, level)
        if count < 0.25 * est.size or not (
            err0 - err > p.ego_min_gain and err < p.ego_max_ratio * err0
        ):
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
        return int(
            height * width
            + n_est * (60 + 25 * self.params.ego_iterations)
            + n_coarse * (15 * math.log2(max(n_coarse, 2)) + 10)
        )
