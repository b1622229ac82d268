"""Shared test helpers: free ports from the OS, waiting on a condition, the SITL binary, a
script of tools/ imported by path."""

from __future__ import annotations

import importlib.util
import os
import socket
import sys
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import pytest

#: Environment variable naming ArduPilot's ``arducopter`` SITL binary (tier skipped when unset).
SITL_ENV = "SARMISSION_SITL"

TESTS_DIR = Path(__file__).resolve().parent
FIXTURES_DIR = TESTS_DIR / "fixtures"


TOOLS_DIR = TESTS_DIR.parent / "tools"


def load_tool(name: str) -> ModuleType:
    """The script ``tools/<name>.py`` imported as a module (registered, so dataclasses work)."""
    spec = importlib.util.spec_from_file_location(
        f"sarmission_tool_{name}", TOOLS_DIR / f"{name}.py"
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def render_narrow_sea(out: Path, frames: int) -> Path:
    """``frames`` 960x540 JPEG frames of the simulator's narrow-view maritime scene (swimmers of
    8-30 px, boats, foam; seed 0, from 5 s on) under ``out``; the folder that holds them (what
    ``tools/rounding_gap.py --preset maritime_train_narrow`` renders)."""
    return load_tool("rounding_gap").render_frames(out, "maritime_train_narrow", frames)


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that the OS reports free right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_until(cond: Callable[[], object], timeout: float, step: float = 0.05) -> bool:
    """Poll ``cond`` until it is true or ``timeout`` seconds passed; returns its last value.

    Deadlines are generous on purpose: they bound a hung test, they do not measure speed."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(step)
    return bool(cond())


@pytest.fixture(scope="session")
def sitl_binary() -> Path:
    """The ``arducopter`` SITL binary named by ``$SARMISSION_SITL``; skips the test when unset.
    Session-wide, so that module fixtures sharing one SITL process can use it too."""
    value = os.environ.get(SITL_ENV, "")
    if not value:
        pytest.skip(f"ArduPilot SITL tier: set {SITL_ENV} to the arducopter binary")
    path = Path(value)
    if not path.is_file() or not os.access(path, os.X_OK):
        pytest.fail(f"{SITL_ENV}={value} is not an executable file")
    return path
