"""Small helpers several sub-commands share: the frame-size option, ``NAME=NAME`` pairs, a
free loopback port and the check that an output is not an input.

One parser for every ``--size`` style option, so each command accepts the same sizes and says
the same thing about a wrong one.
"""

from __future__ import annotations

import argparse
import math
import socket
from collections.abc import Callable
from pathlib import Path

from sarmission.data.frames import MAX_FPS, MIN_FPS

#: Smallest frame side the pipeline accepts (two 16 px proposal boxes).
MIN_FRAME_SIDE = 32
#: Largest frame side accepted: beyond 8K twice over a frame is a typing error, not a camera.
MAX_FRAME_SIDE = 16384


class FrameSizeError(ValueError, argparse.ArgumentTypeError):
    """A frame size that cannot be read or used. A ValueError for callers and the CLI's error
    line, an ArgumentTypeError so argparse prints its message as it is."""


def parse_frame_size(text: str) -> tuple[int, int]:
    """``"960x540"`` -> ``(960, 540)``; :class:`FrameSizeError` for anything else."""
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        width = height = 0
    if not (
        MIN_FRAME_SIDE <= width <= MAX_FRAME_SIDE and MIN_FRAME_SIDE <= height <= MAX_FRAME_SIDE
    ):
        raise FrameSizeError(
            f"expected a frame size WIDTHxHEIGHT with sides {MIN_FRAME_SIDE} "
            f"to {MAX_FRAME_SIDE} px (e.g. 960x540), got {text!r}"
        )
    return width, height


def parse_pairs(pairs: list[str], flag: str) -> dict[str, str]:
    """``["person=swimmer"]`` -> ``{"person": "swimmer"}``; ``ValueError`` naming ``flag`` for a
    pair that is not ``LEFT=RIGHT``."""
    out = {}
    for pair in pairs:
        left, sep, right = pair.partition("=")
        if not sep or not left.strip() or not right.strip():
            raise ValueError(f"{flag} expects NAME=NAME, got {pair!r}")
        out[left.strip()] = right.strip()
    return out


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that is free now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def check_output_path(
    out: str | Path, inputs: dict[str, str | Path | None], suffix: str | None = None
) -> Path:
    """``out`` as a Path, or ValueError when it is a folder, lacks ``suffix`` or is one of
    ``inputs`` (flag -> path): a command never writes over what it reads (an export over its
    checkpoint, detections over the annotations)."""
    path = Path(out)
    if path.is_dir():
        raise ValueError(f"--out {out}: a folder; give the file to write")
    if suffix is not None and path.suffix.lower() != suffix:
        raise ValueError(f"--out {out}: expected a {suffix} file")
    target = path.resolve()
    for flag, given in inputs.items():
        if given is not None and Path(given).resolve() == target:
            raise ValueError(f"--out {out}: the same file as {flag}; write elsewhere")
    return path


def _finite_option(
    at_least_zero: bool, wanted: str, least: float = 0.0, most: float = math.inf
) -> Callable[[str], float]:
    """An argparse type for a finite number above 0 (or 0 and above), at least ``least``
    (0 aside) and at most ``most``, else ``wanted``."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        low_ok = (value >= 0 if at_least_zero else value > 0) and (value >= least or value == 0)
        if not (math.isfinite(value) and low_ok and value <= most):
            raise argparse.ArgumentTypeError(f"expected {wanted}, got {text!r}")
        return value

    return parse


#: A duration option: seconds above 0 (``nan`` once ran for ever, ``0`` the whole flight, a
#: negative one nothing with exit 0).
positive_seconds = _finite_option(False, "seconds above 0")
#: A frame rate option: frames per second from :data:`MIN_FPS` to :data:`MAX_FPS` (``nan``,
#: ``inf`` or ``1e-300`` were once taken: a run that never paced or never returned a frame).
positive_rate = _finite_option(
    False, f"frames per second from {MIN_FPS:g} to {MAX_FPS:g}", MIN_FPS, MAX_FPS
)
#: A frame rate option where 0 means "as fast as processed".
rate_or_zero = _finite_option(
    True, f"0 or frames per second from {MIN_FPS:g} to {MAX_FPS:g}", MIN_FPS, MAX_FPS
)
#: A time option that may be 0: seconds, 0 or more.
non_negative_seconds = _finite_option(True, "seconds, 0 or more")


def non_negative_int(text: str) -> int:
    """A seed or count option: a whole number, 0 or more."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number, 0 or more, got {text!r}")
    return value
