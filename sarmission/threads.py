"""Thread counts of the compute libraries, chosen once per process for the cores it may use.

FFmpeg (video decoding), OpenCV (filters, resizes), onnxruntime (the head), numba (the
simulator's parallel kernels) and torch (training, export) each keep a thread pool sized to
every core by default, and on a 2-8 core companion computer they compete for the same cores.
:func:`plan_for` gives each a deliberate share: the FFmpeg decoder, in its own thread beside
detection, gets frame threads on every core up to four (they fill the moments detection leaves
a core idle; more than four only hold more 4K frames in memory); OpenCV's filters half the
cores, at least two; onnxruntime two threads, which never spin while idle (a batch of 25-100
crops of 16 x 16 spreads no further). On two cores that is two of each, the best of the plans
measured (``docs/benchmarks.md``); above two cores it is the same reasoning, not a measurement.
:func:`apply_thread_plan` sets the libraries already loaded and the environment read by those
loaded later; ``SARMISSION_THREADS`` (a core count) overrides the cores it plans for.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass

#: Environment variable that overrides the number of cores the plan is made for.
THREADS_ENV = "SARMISSION_THREADS"


@dataclass(frozen=True)
class ThreadPlan:
    """Threads per library for a machine of ``cores`` usable cores."""

    cores: int
    decode: int  # FFmpeg decoding threads of one video or stream
    opencv: int  # cv2.setNumThreads: filters and resizes of the detection stages
    onnx: int  # onnxruntime intra-op threads of the head
    numba: int  # numba's parallel loops (the simulator's renderer)
    torch: int  # torch intra-op threads (training, export, the torch runtime)


def available_cores() -> int:
    """Cores this process may run on: ``$SARMISSION_THREADS``, else its CPU affinity."""
    value = os.environ.get(THREADS_ENV, "").strip()
    if value:
        try:
            cores = int(value)
        except ValueError:
            raise ValueError(f"${THREADS_ENV} must be a positive integer, got {value!r}") from None
        if cores < 1:
            raise ValueError(f"${THREADS_ENV} must be a positive integer, got {value!r}")
        return cores
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def plan_for(cores: int) -> ThreadPlan:
    """The plan for ``cores`` cores (module docstring)."""
    cores = max(1, int(cores))
    return ThreadPlan(
        cores=cores,
        decode=min(cores, 4),
        opencv=min(cores, max(2, cores // 2)),
        onnx=min(cores, 2),
        numba=cores,
        torch=cores,
    )


_applied: ThreadPlan | None = None


def thread_plan() -> ThreadPlan:
    """The plan in force: the applied one, else the one for :func:`available_cores`."""
    return _applied if _applied is not None else plan_for(available_cores())


def apply_thread_plan(plan: ThreadPlan | None = None) -> ThreadPlan:
    """Set OpenCV's and (when loaded) torch's thread counts to ``plan`` (default: the plan for
    this machine), numba's for when it is imported, and remember the plan for the onnxruntime
    sessions and decoders made later. Call it before the compute modules are imported."""
    global _applied
    plan = plan or plan_for(available_cores())
    # Read when numba is imported (a pool started earlier keeps its size; starting it here just
    # to resize it would cost threads that inference, which has no parallel numba loop, never
    # uses) and when torch starts OpenMP.
    os.environ["NUMBA_NUM_THREADS"] = str(plan.numba)
    os.environ.setdefault("OMP_NUM_THREADS", str(plan.torch))
    import cv2

    cv2.setNumThreads(plan.opencv)
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(plan.torch)
    _applied = plan
    return plan
