"""Compile the numba loops (vSTMD, the crops, the object extent) ahead of time into one module.

A process that JIT-loads numba's compiled code carries numba, LLVM and scipy.linalg (numba's BLAS
check): about 120 MB of its memory and half a second of its start. numba's ``pycc`` turns the
same functions into a plain CPython extension that needs neither (numba marks ``pycc`` as
pending deprecation; :mod:`~sarmission.perception.kernels` falls back to the JIT when a build
fails). Each export is a thin wrapper calling the ``@njit`` function, which is compiled with its
own options (fastmath where it has them) for this machine's CPU.

Run as ``python -m sarmission.perception.kernels_aot DIR`` (what
:mod:`~sarmission.perception.kernels` does, in a child process, so that the caller never loads
LLVM); it writes ``DIR/<MODULE_NAME><extension suffix>``.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Callable
from pathlib import Path

#: Name of the compiled extension module (its ``PyInit_`` symbol).
MODULE_NAME = "sarmission_kernels"

_MAP = "float32[:, ::1]"
_CONSTANTS = ", ".join(["float32"] * 5)
_POOLED = {"u8": "uint8[:, ::1]", "f32": "float32[:, ::1]"}


def _exports() -> list[tuple[str, str, Callable[..., object]]]:
    """``(exported name, numba signature, wrapper)`` of every compiled entry point."""
    from sarmission.perception import crop_kernels, extent_kernels, vstmd_kernels

    lamina = vstmd_kernels.lamina_medulla
    shifted = vstmd_kernels.lamina_medulla_shifted
    translation = vstmd_kernels.translation_system
    combine = vstmd_kernels.combine_rectify
    sample = crop_kernels.bilinear
    region = extent_kernels.region

    def lamina_medulla(pooled, scale, p, lam, von, voff, corr, a0, decay, g_leak, v_rest, v_exc):
        lamina(pooled, scale, p, lam, von, voff, corr, a0, decay, g_leak, v_rest, v_exc)

    def lamina_medulla_shifted(
        pooled, scale, p, lam, von, voff, corr, ring, column, kx, ky, fx, fy, cx, cy,
        a0, decay, g_leak, v_rest, v_exc,
    ):  # fmt: skip
        shifted(
            pooled, scale, p, lam, von, voff, corr, ring, column, kx, ky, fx, fy, cx, cy,
            a0, decay, g_leak, v_rest, v_exc,
        )  # fmt: skip

    def translation_system(cur, prev, sx, sy, huber, level):
        return translation(cur, prev, sx, sy, huber, level)

    def combine_rectify(centre, surround, bump, out):
        combine(centre, surround, bump, out)

    def bilinear(windows, grid_x, grid_y, out):
        sample(windows, grid_x, grid_y, out)

    def extent_region(lab, ix0, iy0, ix1, iy1, threshold, spread_floor, border_share):
        return region(lab, ix0, iy0, ix1, iy1, threshold, spread_floor, border_share)

    exports: list[tuple[str, str, Callable[..., object]]] = []
    for tag, pooled in _POOLED.items():
        exports.append(
            (
                f"lamina_medulla_{tag}",
                f"void({pooled}, float32, {_MAP}, {_MAP}, {_MAP}, {_MAP}, {_MAP}, {_CONSTANTS})",
                lamina_medulla,
            )
        )
        exports.append(
            (
                f"lamina_medulla_shifted_{tag}",
                f"void({pooled}, float32, {_MAP}, {_MAP}, {_MAP}, {_MAP}, {_MAP}, "
                "float32[:, :, ::1], float32[::1], int64, int64, float32, float32, "
                f"float32[::1], float32[::1], {_CONSTANTS})",
                lamina_medulla_shifted,
            )
        )
    exports += [
        (
            "translation_system",
            "Tuple((float64, float64, float64, float64, float64, float64, float64, int64))"
            f"({_MAP}, {_MAP}, float64, float64, float64, float64)",
            translation_system,
        ),
        ("combine_rectify", f"void({_MAP}, {_MAP}, {_MAP}, {_MAP})", combine_rectify),
        (
            "bilinear",
            "void(float32[:, :, :, ::1], float32[:, ::1], float32[:, ::1], float32[:, :, :, ::1])",
            bilinear,
        ),
        (
            "extent_region",
            "Tuple((int64, int64, int64, int64, int64, boolean))"
            "(uint8[:, :, ::1], int64, int64, int64, int64, float64, float64, float64)",
            extent_region,
        ),
    ]
    return exports


def build(out_dir: Path) -> Path:
    """Compile the extension into ``out_dir`` for this machine's CPU; return its path."""
    import llvmlite.binding as llvm

    with warnings.catch_warnings():  # pycc's pending-deprecation notice: see the docstring
        warnings.simplefilter("ignore")
        from numba.pycc import CC

    out_dir.mkdir(parents=True, exist_ok=True)
    cc = CC(MODULE_NAME)
    cc.output_dir = str(out_dir)
    cc.target_cpu = llvm.get_host_cpu_name()
    cc.verbose = False
    for name, signature, wrapper in _exports():
        cc.export(name, signature)(wrapper)
    cc.compile()
    built = sorted(out_dir.glob(f"{MODULE_NAME}.*"))
    if not built:
        raise RuntimeError(f"numba.pycc wrote no {MODULE_NAME} module into {out_dir}")
    return built[0]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", type=Path, help="directory to write the extension module into")
    args = parser.parse_args(argv)
    print(build(args.out_dir))
    return 0


if __name__ == "__main__":
    sys.exit(main())
