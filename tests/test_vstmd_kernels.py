"""The fused numba loops of vSTMD against a plain numpy reference of the equations, written here
from docs/vstmd.md and independently of the kernels:

    L_t   = a0 * (P'_t - P~_{t-1}) + decay * L~_{t-1}
    ON    = max(L_t, 0),  OFF = max(-L_t, 0)
    V_on  = V~_on  + exp(OFF) * g_leak * (v_rest - V~_on)  + ON  * (v_exc - V~_on)
    V_off = V~_off + exp(ON)  * g_leak * (v_rest - V~_off) + OFF * (v_exc - V~_off)
    C     = V_on * V_off

with ``~`` the previous frame's state carried by the camera shift ``s``: ``P~`` Catmull-Rom
cubic, ``L~`` and ``V~`` bilinear, all sampled at ``x - s``; where a cubic tap falls outside
the map, ``P~ = P'_t`` and ``L~ = V~ = 0``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sarmission.perception.kernels import cubic_weights, ring_rows
from sarmission.perception.vstmd_kernels import (
    combine_rectify,
    lamina_medulla,
    lamina_medulla_shifted,
)
from sarmission.perception.vstmd_params import VSTMDParams

H, W = 23, 31
SCALE = np.float32(1.0 / 255.0)


def constants() -> tuple[float, float, float, float, float]:
    p = VSTMDParams()
    rate = p.alpha / (1.0 - p.alpha)
    a0 = 1.0 / sum(math.exp(-rate * j) for j in range(p.lamina_width))
    return a0, math.exp(-rate), p.g_leak, p.v_rest, p.v_exc


def state(seed: int) -> dict[str, np.ndarray]:
    """A frame and last frame's state as a stream leaves them: values in their ranges."""
    rng = np.random.default_rng(seed)
    return {
        "pooled": rng.integers(0, 256, (H, W), dtype=np.uint8),
        "p_prev": rng.random((H, W), dtype=np.float32),
        "l": (rng.random((H, W), dtype=np.float32) - 0.5) * 0.6,
        "v_on": rng.random((H, W), dtype=np.float32) * 0.8,
        "v_off": rng.random((H, W), dtype=np.float32) * 0.8,
    }


def reference_update(
    p: np.ndarray, q: np.ndarray, l_prev: np.ndarray, v_on: np.ndarray, v_off: np.ndarray
) -> tuple[np.ndarray, ...]:
    """The lamina and medulla equations in float64: ``(L, V_on, V_off, C)``."""
    a0, decay, g_leak, v_rest, v_exc = constants()
    lt = a0 * (p - q) + decay * l_prev
    on, off = np.maximum(lt, 0.0), np.maximum(-lt, 0.0)
    a = v_on + np.exp(off) * g_leak * (v_rest - v_on) + on * (v_exc - v_on)
    b = v_off + np.exp(on) * g_leak * (v_rest - v_off) + off * (v_exc - v_off)
    return lt, a, b, a * b


def keys_cubic(d: float) -> float:
    """Catmull-Rom (Keys, a = -0.5) interpolation kernel at distance ``d``."""
    d = abs(d)
    if d <= 1.0:
        return 1.5 * d**3 - 2.5 * d**2 + 1.0
    if d < 2.0:
        return -0.5 * d**3 + 2.5 * d**2 - 4.0 * d + 2.0
    return 0.0


def reference_carried(s: dict[str, np.ndarray], sx: float, sy: float) -> tuple[np.ndarray, ...]:
    """``(P~, L~, V~_on, V~_off)`` of the docstring's rule, pixel by pixel."""
    p_now = s["pooled"].astype(np.float64) / 255.0
    prev = {k: s[k].astype(np.float64) for k in ("p_prev", "l", "v_on", "v_off")}
    carried = [p_now.copy(), np.zeros((H, W)), np.zeros((H, W)), np.zeros((H, W))]
    for i in range(H):
        for j in range(W):
            u, v = j - sx, i - sy  # where this pixel's content was in the previous frame
            c0, r0 = math.ceil(u), math.ceil(v)  # the cubic's taps: c0 - 2 .. c0 + 1
            if not (c0 - 2 >= 0 and c0 + 1 <= W - 1 and r0 - 2 >= 0 and r0 + 1 <= H - 1):
                continue
            cubic = sum(
                keys_cubic(v - r) * keys_cubic(u - c) * prev["p_prev"][r, c]
                for r in range(r0 - 2, r0 + 2)
                for c in range(c0 - 2, c0 + 2)
            )
            carried[0][i, j] = cubic
            x0, y0 = math.floor(u), math.floor(v)
            fx, fy = u - x0, v - y0
            for n, name in enumerate(("l", "v_on", "v_off"), start=1):
                m = prev[name]
                carried[n][i, j] = (1 - fy) * ((1 - fx) * m[y0, x0] + fx * m[y0, x0 + 1]) + fy * (
                    (1 - fx) * m[y0 + 1, x0] + fx * m[y0 + 1, x0 + 1]
                )
    return tuple(carried)


def in_place(s: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Copies of the state the kernels update in place, and a correlation map to fill."""
    return {
        "p": s["p_prev"].copy(),
        "l": s["l"].copy(),
        "v_on": s["v_on"].copy(),
        "v_off": s["v_off"].copy(),
        "corr": np.full((H, W), np.nan, np.float32),
    }


def run_shifted(
    s: dict[str, np.ndarray], kx: int, ky: int, fx: float, fy: float, kept_rows: int
) -> dict[str, np.ndarray]:
    out = in_place(s)
    lamina_medulla_shifted(
        s["pooled"],
        SCALE,
        out["p"],
        out["l"],
        out["v_on"],
        out["v_off"],
        out["corr"],
        np.full((4, kept_rows, W), np.nan, np.float32),
        np.empty(W + 3, np.float32),
        kx,
        ky,
        np.float32(fx),
        np.float32(fy),
        cubic_weights(fx),
        cubic_weights(fy),
        *kernel_constants(),
    )
    return out


def kernel_constants() -> tuple[np.float32, ...]:
    return tuple(np.float32(c) for c in constants())


@pytest.mark.parametrize("seed", [0, 1])
def test_unshifted_kernel_follows_the_equations(seed: int) -> None:
    s = state(seed)
    out = in_place(s)
    lamina_medulla(
        s["pooled"],
        SCALE,
        out["p"],
        out["l"],
        out["v_on"],
        out["v_off"],
        out["corr"],
        *kernel_constants(),
    )
    p_now = s["pooled"].astype(np.float64) / 255.0
    expected = reference_update(
        p_now,
        s["p_prev"].astype(np.float64),
        *(s[k].astype(np.float64) for k in ("l", "v_on", "v_off")),
    )
    for got, want in zip((out["l"], out["v_on"], out["v_off"], out["corr"]), expected, strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(out["p"], p_now, rtol=1e-6)  # this frame becomes the previous


# ky from -6 to 7: rows read below, around and above the row written in place
@pytest.mark.parametrize(
    ("sx", "sy"),
    [(2.3, 1.6), (-3.75, 0.4), (0.5, -2.2), (4.0, 3.0), (1.2, 7.4), (-0.6, -5.9), (0.3, -1.5)],
)
def test_shifted_kernel_follows_the_equations(sx: float, sy: float) -> None:
    s = state(7)
    kx, ky = math.floor(sx), math.floor(sy)
    out = run_shifted(s, kx, ky, sx - kx, sy - ky, ring_rows(ky, H))
    p_now = s["pooled"].astype(np.float64) / 255.0
    expected = reference_update(p_now, *reference_carried(s, sx, sy))
    for got, want in zip((out["l"], out["v_on"], out["v_off"], out["corr"]), expected, strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(out["p"], p_now, rtol=1e-6)


def test_a_ring_one_row_short_reads_overwritten_state() -> None:
    # the rows kept aside are what makes the update in place exact
    s = state(7)
    sx, sy = 1.2, 4.4
    kx, ky = math.floor(sx), math.floor(sy)
    exact = run_shifted(s, kx, ky, sx - kx, sy - ky, ring_rows(ky, H))
    short = run_shifted(s, kx, ky, sx - kx, sy - ky, ring_rows(ky, H) - 1)
    assert not np.allclose(short["l"], exact["l"], equal_nan=True)


def test_a_shift_beyond_the_map_carries_nothing() -> None:
    s = state(3)
    out = run_shifted(s, W + 5, 0, 0.0, 0.0, ring_rows(0, H))
    p_now = s["pooled"].astype(np.float64) / 255.0
    zero = np.zeros((H, W))
    expected = reference_update(p_now, p_now, zero, zero, zero)
    np.testing.assert_allclose(out["l"], 0.0, atol=1e-7)  # no temporal change at all
    np.testing.assert_allclose(out["corr"], expected[3], rtol=1e-4, atol=1e-7)


def test_cubic_weights_are_the_catmull_rom_kernel() -> None:
    for frac in (0.0, 0.25, 0.5, 0.9):
        # taps k + 1, k, k - 1, k - 2 for the sample at k - frac
        want = [
            keys_cubic(-frac - 1.0),
            keys_cubic(-frac),
            keys_cubic(1.0 - frac),
            keys_cubic(2.0 - frac),
        ]
        np.testing.assert_allclose(cubic_weights(frac), want, atol=1e-6)


def test_lobula_combination_is_rectified_centre_minus_surround_plus_bump() -> None:
    rng = np.random.default_rng(5)
    centre, surround, bump = (rng.normal(size=(H, W)).astype(np.float32) for _ in range(3))
    out = np.full((H, W), np.nan, np.float32)
    combine_rectify(centre, surround, bump, out)
    np.testing.assert_allclose(out, np.maximum(centre - surround + bump, 0.0), atol=1e-6)
