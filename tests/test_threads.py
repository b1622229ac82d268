"""The thread plan: each compute library gets a deliberate share of the cores."""

from __future__ import annotations

import subprocess
import sys

import cv2
import pytest

from sarmission import threads
from sarmission.threads import ThreadPlan, apply_thread_plan, available_cores, plan_for


@pytest.mark.parametrize(
    ("cores", "decode", "opencv", "onnx"),
    [(1, 1, 1, 1), (2, 2, 2, 2), (4, 4, 2, 2), (8, 4, 4, 2), (16, 4, 8, 2)],
)
def test_plans_for_two_to_eight_cores(cores: int, decode: int, opencv: int, onnx: int):
    plan = plan_for(cores)
    assert (plan.decode, plan.opencv, plan.onnx) == (decode, opencv, onnx)
    assert plan.numba == plan.torch == cores


def test_the_environment_overrides_the_cores(monkeypatch):
    monkeypatch.setenv(threads.THREADS_ENV, "8")
    assert available_cores() == 8
    for bad in ("0", "many", "-2"):
        monkeypatch.setenv(threads.THREADS_ENV, bad)
        with pytest.raises(ValueError, match="SARMISSION_THREADS must be a positive integer"):
            available_cores()


def test_applying_sets_opencv_and_the_onnx_sessions_made_after(monkeypatch):
    from sarmission.perception.mitenet import build_head_runtime

    before = cv2.getNumThreads()
    monkeypatch.setattr(threads, "_applied", None)
    try:
        plan = apply_thread_plan(ThreadPlan(cores=3, decode=1, opencv=3, onnx=1, numba=3, torch=3))
        assert cv2.getNumThreads() == 3 and threads.thread_plan() is plan
        session = build_head_runtime(None, "onnx").session
        assert session.get_session_options().intra_op_num_threads == 1
    finally:
        cv2.setNumThreads(before)


def test_the_onnx_detection_path_loads_no_torch(tmp_path):
    """torch (a few hundred MB) is for training and export; detecting with the ONNX head runs
    the whole cascade without it."""
    script = (
        "import sys, numpy as np\n"
        "from sarmission.cli import main\n"
        "from sarmission.perception.mitenet import MiteNet, build_head_runtime\n"
        "net = MiteNet(build_head_runtime(None, 'onnx'), ds=2, topn=25)\n"
        "rng = np.random.default_rng(0)\n"
        "for i in range(3):\n"
        "    net.process(rng.integers(0, 256, (240, 320, 3), dtype=np.uint8), i / 30)\n"
        "print('torch' in sys.modules, 'onnx' in sys.modules)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["False", "False"]
