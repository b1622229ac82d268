"""The compiled loops detection runs (vSTMD's lamina/medulla, lobula and shift estimate, the
crops' bilinear sampling, the object extent's region), without numba in the process where
possible.

Loading numba's JIT-compiled code costs a process about 120 MB (numba, LLVM, scipy.linalg) and
half a second. So the loops are compiled ahead of time once per machine
(:mod:`~sarmission.perception.kernels_aot`, in a child process, about 15 s) into a cache
directory, keyed by their source, numba's and numpy's versions, the Python build and the CPU,
and later processes import that extension alone. The first call compiles; where compiling or
loading fails the same functions run through numba's JIT, with one warning.

``SARMISSION_KERNELS=jit`` always uses the JIT (no compiling); ``SARMISSION_KERNEL_DIR`` moves
the cache (default ``$XDG_CACHE_HOME/sarmission/kernels``, else ``~/.cache/sarmission/kernels``).
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import importlib.machinery
import importlib.metadata
import importlib.util
import logging
import os
import platform
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

log = logging.getLogger(__name__)

#: Environment variable choosing the loops: "aot" (default) or "jit".
KERNELS_ENV = "SARMISSION_KERNELS"
#: Environment variable naming the directory of the compiled loops.
KERNEL_DIR_ENV = "SARMISSION_KERNEL_DIR"
#: Source files whose contents decide the compiled module.
_SOURCES = ("vstmd_kernels.py", "crop_kernels.py", "extent_kernels.py", "kernels_aot.py")
#: Longest a build may take before it is given up (seconds).
BUILD_TIMEOUT_S = 600.0


def cubic_weights(frac: float) -> np.ndarray:
    """Catmull-Rom (Keys, a = -0.5) weights of the taps ``k + 1, k, k - 1, k - 2`` for the
    sample at ``k - frac`` (``frac`` in [0, 1)). With ``t = 1 - frac``::

        w = [t^3 - t^2,  -3t^3 + 4t^2 + t,  3t^3 - 5t^2 + 2,  -t^3 + 2t^2 - t] / 2
    """
    t = 1.0 - frac
    t2, t3 = t * t, t * t * t
    return np.array(
        [t3 - t2, -3.0 * t3 + 4.0 * t2 + t, 3.0 * t3 - 5.0 * t2 + 2.0, -t3 + 2.0 * t2 - t],
        np.float32,
    ) / np.float32(2.0)


def ring_rows(ky: int, height: int) -> int:
    """Rows of last frame's state :func:`lamina_medulla_shifted` keeps aside for a vertical
    shift ``ky``: output row ``i`` reads rows ``i - ky - 2 .. i - ky + 1``, so the rows down to
    ``i - ky - 2`` must outlive their overwrite (none when the shift leaves no row inside)."""
    return max(1, min(ky + 3, height))


# ---------------------------------------------------------------------------- the two backends
class _Jit:
    """numba's JIT-compiled functions (imports numba)."""

    name = "jit"

    def __init__(self) -> None:
        from sarmission.perception import crop_kernels, extent_kernels, vstmd_kernels

        self.lamina_medulla = vstmd_kernels.lamina_medulla
        self.lamina_medulla_shifted = vstmd_kernels.lamina_medulla_shifted
        self.translation_system = vstmd_kernels.translation_system
        self.combine_rectify = vstmd_kernels.combine_rectify
        self.bilinear = crop_kernels.bilinear
        self.extent_region = extent_kernels.region


class _Aot:
    """The extension module built by :mod:`~sarmission.perception.kernels_aot`: one entry point
    per dtype of the pooled frame, arrays C-contiguous."""

    name = "aot"

    def __init__(self, module: ModuleType, path: Path) -> None:
        self.module = module
        self.path = path
        self.translation_system = module.translation_system
        self.combine_rectify = module.combine_rectify
        self.bilinear = module.bilinear
        self.extent_region = module.extent_region

    def lamina_medulla(self, pooled: np.ndarray, *args: Any) -> None:
        tag = "u8" if pooled.dtype == np.uint8 else "f32"
        getattr(self.module, f"lamina_medulla_{tag}")(pooled, *args)

    def lamina_medulla_shifted(self, pooled: np.ndarray, *args: Any) -> None:
        tag = "u8" if pooled.dtype == np.uint8 else "f32"
        getattr(self.module, f"lamina_medulla_shifted_{tag}")(pooled, *args)


_backend: _Jit | _Aot | None = None
_lock = threading.Lock()


def backend() -> _Jit | _Aot:
    """The loops in use in this process (chosen, and compiled if need be, on first use)."""
    global _backend
    if _backend is None:
        with _lock:
            if _backend is None:
                _backend = _choose()
    return _backend


def backend_name() -> str:
    """``"aot"`` or ``"jit"``: which loops this process runs."""
    return backend().name


# ---------------------------------------------------------------------------- entry points
def lamina_medulla(pooled: np.ndarray, *args: Any) -> None:
    """:func:`sarmission.perception.vstmd_kernels.lamina_medulla`."""
    backend().lamina_medulla(pooled, *args)


def lamina_medulla_shifted(pooled: np.ndarray, *args: Any) -> None:
    """:func:`sarmission.perception.vstmd_kernels.lamina_medulla_shifted`."""
    backend().lamina_medulla_shifted(pooled, *args)


def translation_system(cur: np.ndarray, prev: np.ndarray, *args: float) -> tuple:
    """:func:`sarmission.perception.vstmd_kernels.translation_system`."""
    return backend().translation_system(cur, prev, *args)


def combine_rectify(centre: np.ndarray, surround: np.ndarray, bump: np.ndarray, out: np.ndarray):
    """:func:`sarmission.perception.vstmd_kernels.combine_rectify`."""
    backend().combine_rectify(centre, surround, bump, out)


def bilinear(windows: np.ndarray, grid_x: np.ndarray, grid_y: np.ndarray, out: np.ndarray):
    """:func:`sarmission.perception.crop_kernels.bilinear`."""
    backend().bilinear(windows, grid_x, grid_y, out)


def extent_region(lab: np.ndarray, *args: float) -> tuple[int, int, int, int, int, bool]:
    """:func:`sarmission.perception.extent_kernels.region`."""
    return backend().extent_region(lab, *args)


# ---------------------------------------------------------------------------- the cache
def cache_root() -> Path:
    """Directory holding the compiled loops of every key."""
    chosen = os.environ.get(KERNEL_DIR_ENV, "").strip()
    if chosen:
        return Path(chosen).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME", "").strip()
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "sarmission" / "kernels"


def _cpu_description() -> str:
    """The CPU's model and instruction-set flags (what the compiled code may use)."""
    with contextlib.suppress(OSError):
        lines = Path("/proc/cpuinfo").read_text().splitlines()
        wanted = ("model name", "flags", "Features", "CPU part", "CPU implementer")
        picked = [line for line in lines if line.split(":")[0].strip() in wanted]
        if picked:
            return "\n".join(dict.fromkeys(picked))  # the first core's, once each
    return f"{platform.machine()} {platform.processor()}"


def cache_key() -> str:
    """Hex key of the compiled module: its sources, numba and numpy, Python, the CPU."""
    digest = hashlib.sha256()
    here = Path(__file__).parent
    for name in _SOURCES:
        digest.update(name.encode())
        digest.update((here / name).read_bytes())
    for package in ("numba", "llvmlite", "numpy"):
        digest.update(f"{package}={importlib.metadata.version(package)}".encode())
    digest.update(sys.version.encode())
    digest.update(_cpu_description().encode())
    return digest.hexdigest()[:20]


def _compiled_in(directory: Path) -> Path | None:
    from sarmission.perception.kernels_aot import MODULE_NAME

    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        path = directory / f"{MODULE_NAME}{suffix}"
        if path.is_file():
            return path
    return None


@contextlib.contextmanager
def _locked(directory: Path) -> Iterator[None]:
    """Hold ``directory``'s lock file: one process builds, the others wait and reuse it."""
    directory.mkdir(parents=True, exist_ok=True)
    with open(directory / ".lock", "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _build(directory: Path) -> Path:
    """Compile into ``directory`` in a child process (which alone loads LLVM)."""
    log.info("compiling the detector's loops for this CPU once (about 15 s) into %s", directory)
    staging = directory / f".build-{os.getpid()}"
    done = subprocess.run(
        [sys.executable, "-m", "sarmission.perception.kernels_aot", str(staging)],
        capture_output=True,
        text=True,
        timeout=BUILD_TIMEOUT_S,
        check=False,
    )
    built = _compiled_in(staging) if done.returncode == 0 else None
    if built is None:
        lines = (done.stderr or done.stdout or "no output").strip().splitlines()
        raise RuntimeError(f"build exited {done.returncode}: {lines[-1] if lines else ''}")
    target = directory / built.name
    os.replace(built, target)
    for leftover in staging.iterdir():
        leftover.unlink()
    staging.rmdir()
    return target


def _load(path: Path) -> ModuleType:
    from sarmission.perception.kernels_aot import MODULE_NAME

    loader = importlib.machinery.ExtensionFileLoader(MODULE_NAME, str(path))
    spec = importlib.util.spec_from_file_location(MODULE_NAME, path, loader=loader)
    if spec is None:
        raise ImportError(f"cannot load {path}")
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    return module


def _choose() -> _Jit | _Aot:
    mode = os.environ.get(KERNELS_ENV, "aot").strip().lower() or "aot"
    if mode not in ("aot", "jit"):
        raise ValueError(f"${KERNELS_ENV} must be 'aot' or 'jit', got {mode!r}")
    if mode == "jit":
        return _Jit()
    directory = cache_root() / cache_key()
    try:
        with _locked(directory):
            path = _compiled_in(directory) or _build(directory)
        return _Aot(_load(path), path)
    except (OSError, RuntimeError, ImportError, AttributeError, subprocess.SubprocessError) as exc:
        log.warning(
            "the detector's loops could not be compiled ahead of time into %s (%s); "
            "running them through numba's JIT (about 120 MB more memory)",
            directory,
            exc,
        )
        return _Jit()
