"""The detector's loops compiled ahead of time: the same results as numba's JIT, no numba in a
detecting process, one build however many processes start at once, and a fallback to the JIT
when the compiled module is unusable."""

from __future__ import annotations

import importlib.machinery
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sarmission.perception import crop_kernels, kernels, vstmd_kernels
from sarmission.perception.kernels_aot import MODULE_NAME

ROOT = Path(__file__).resolve().parents[1]
H, W = 37, 53

# A process that runs vSTMD (shifted and not), the shift estimate and the crops, then reports
# which loops it used and what it imported.
DETECTING = """
import json, logging, sys
import numpy as np
logging.basicConfig(level=logging.INFO, stream=sys.stderr)
from sarmission.perception import kernels
from sarmission.perception.crops import roi_align
from sarmission.perception.vstmd import VSTMD
rng = np.random.default_rng(0)
model = VSTMD(ds=2)
for k in range(3):
    model.step(rng.integers(0, 256, (96, 128), dtype=np.uint8), shift_px=(2.5 * k, 1.5 * k))
model.step(rng.integers(0, 256, (96, 128), dtype=np.uint8))
frame = rng.integers(0, 256, (96, 128, 3), dtype=np.uint8)
crops = roi_align(frame, np.array([[10.0, 10.0, 30.0, 26.0]]))
print(json.dumps({
    "backend": kernels.backend_name(),
    "loaded": sorted(m for m in ("numba", "llvmlite", "scipy.linalg") if m in sys.modules),
    "crop_sum": float(crops.sum()),
}))
"""


def detecting_process(env_extra: dict[str, str]) -> subprocess.Popen[str]:
    env = {**os.environ, **env_extra}
    return subprocess.Popen(
        [sys.executable, "-c", DETECTING],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def report(process: subprocess.Popen[str]) -> tuple[dict, str]:
    out, err = process.communicate(timeout=240)
    assert process.returncode == 0, err
    return json.loads(out.strip().splitlines()[-1]), err


def random_state(seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {
        "p": rng.random((H, W), dtype=np.float32),
        "l": (rng.random((H, W), dtype=np.float32) - 0.5) * 0.6,
        "v_on": rng.random((H, W), dtype=np.float32) * 0.8,
        "v_off": rng.random((H, W), dtype=np.float32) * 0.8,
        "corr": np.full((H, W), np.nan, np.float32),
    }


CONSTANTS = tuple(np.float32(c) for c in (0.31, 0.72, 0.1, 0.0, 1.0))


@pytest.fixture(scope="module")
def compiled() -> kernels._Aot:
    chosen = kernels.backend()
    assert chosen.name == "aot", "the loops did not compile ahead of time on this machine"
    return chosen  # type: ignore[return-value]


@pytest.mark.parametrize("dtype", [np.uint8, np.float32])
@pytest.mark.parametrize(("sx", "sy"), [(0.0, 0.0), (2.3, 1.6), (-3.75, -4.2), (1.5, 8.25)])
def test_the_compiled_lamina_medulla_matches_the_jit(compiled, dtype, sx: float, sy: float):
    rng = np.random.default_rng(5)
    pooled = (rng.random((H, W)) * 255).astype(dtype)
    scale = np.float32(1 / 255)
    got, want = random_state(1), random_state(1)
    names = ("p", "l", "v_on", "v_off", "corr")
    if sx == 0.0 and sy == 0.0:
        compiled.lamina_medulla(pooled, scale, *(got[n] for n in names), *CONSTANTS)
        vstmd_kernels.lamina_medulla(pooled, scale, *(want[n] for n in names), *CONSTANTS)
    else:
        kx, ky = math.floor(sx), math.floor(sy)
        taps = (
            np.int64(kx),
            np.int64(ky),
            np.float32(sx - kx),
            np.float32(sy - ky),
            kernels.cubic_weights(sx - kx),
            kernels.cubic_weights(sy - ky),
        )
        for state, run in ((got, compiled.lamina_medulla_shifted), (want, None)):
            ring = np.zeros((4, kernels.ring_rows(ky, H), W), np.float32)
            column = np.empty(W + 3, np.float32)
            args = (pooled, scale, *(state[n] for n in names), ring, column, *taps, *CONSTANTS)
            (run or vstmd_kernels.lamina_medulla_shifted)(*args)
    for name in names:
        np.testing.assert_allclose(got[name], want[name], rtol=2e-6, atol=1e-7, err_msg=name)


def test_the_compiled_shift_estimate_lobula_and_crops_match_the_jit(compiled):
    rng = np.random.default_rng(2)
    cur, prev = rng.random((40, 60), dtype=np.float32), rng.random((40, 60), dtype=np.float32)
    for args in ((0.0, 0.0, np.inf, 0.05), (1.25, -0.5, 0.2, 0.05)):
        np.testing.assert_allclose(
            compiled.translation_system(cur, prev, *args),
            vstmd_kernels.translation_system(cur, prev, *args),
            rtol=1e-9,
        )
    parts = [rng.random((H, W), dtype=np.float32) for _ in range(3)]
    got, want = np.empty((H, W), np.float32), np.empty((H, W), np.float32)
    compiled.combine_rectify(*parts, got)
    vstmd_kernels.combine_rectify(*parts, want)
    np.testing.assert_array_equal(got, want)
    windows = rng.random((5, 9, 9, 4), dtype=np.float32)
    grid = (rng.random((5, 16), dtype=np.float32) * 2.4 - 1.2, rng.random((5, 16)) * 2 - 1)
    grid_x, grid_y = grid[0], grid[1].astype(np.float32)
    got, want = np.empty((5, 4, 16, 16), np.float32), np.empty((5, 4, 16, 16), np.float32)
    compiled.bilinear(windows, grid_x, grid_y, got)
    crop_kernels.bilinear(windows, grid_x, grid_y, want)
    np.testing.assert_array_equal(got, want)  # no fastmath in this loop: bit for bit


def test_processes_starting_together_build_once_and_run_without_numba(tmp_path):
    env = {kernels.KERNEL_DIR_ENV: str(tmp_path), kernels.KERNELS_ENV: "aot"}
    first, second = detecting_process(env), detecting_process(env)
    (a, err_a), (b, err_b) = report(first), report(second)
    assert a["backend"] == b["backend"] == "aot"
    assert a["loaded"] == b["loaded"] == []  # neither numba, LLVM nor scipy.linalg
    assert (err_a + err_b).count("compiling the detector's loops") == 1, err_a + err_b
    assert len(list(tmp_path.glob(f"*/{MODULE_NAME}.*"))) == 1
    jit, _ = report(detecting_process({**env, kernels.KERNELS_ENV: "jit"}))
    assert jit["backend"] == "jit" and "numba" in jit["loaded"]
    assert jit["crop_sum"] == a["crop_sum"]


def test_an_unusable_compiled_module_falls_back_to_the_jit_with_one_warning(tmp_path):
    env = {kernels.KERNEL_DIR_ENV: str(tmp_path), kernels.KERNELS_ENV: "aot"}
    corrupt = (
        tmp_path / kernels.cache_key() / f"{MODULE_NAME}{importlib.machinery.EXTENSION_SUFFIXES[0]}"
    )
    corrupt.parent.mkdir(parents=True)
    corrupt.write_bytes(b"\x7fELF not really a shared object")
    result, err = report(detecting_process(env))
    assert result["backend"] == "jit"
    assert err.count("could not be compiled ahead of time") == 1, err
    assert str(corrupt.parent) in err


def test_an_unknown_kernel_choice_is_one_clear_error(monkeypatch):
    monkeypatch.setenv(kernels.KERNELS_ENV, "fast")
    with pytest.raises(ValueError, match=r"SARMISSION_KERNELS must be 'aot' or 'jit', got 'fast'"):
        kernels._choose()
