"""Which thread counts to give FFmpeg, OpenCV and onnxruntime: measured, into docs/benchmarks.md.

Each candidate plan runs in a fresh process, what ``detect`` runs (the 4K H.264 clip of
``tools/pipeline_benchmark.py`` decoded one frame ahead in its own thread, MITE-Net ds 2 N 25),
over the clip's first ``--frames`` frames after 8 warm-up frames; the plans take turns, repeated,
medians. Then the head alone at N 25 and N 100 with one and two onnxruntime threads (the crops
of one frame in, as MiteNet calls it). Run it on an otherwise idle machine: the load average is
recorded with the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

from pipeline_benchmark import DOC, make_clip, measure, write_section  # noqa: E402

PIPELINE = """
import json, resource, sys, time
from pathlib import Path
from sarmission.threads import ThreadPlan, apply_thread_plan
decode, opencv, onnx, frames = (int(v) for v in sys.argv[2:6])
apply_thread_plan(ThreadPlan(cores=2, decode=decode, opencv=opencv, onnx=onnx, numba=2, torch=2))
from sarmission.data.frames import VideoFileSource
from sarmission.data.prefetch import Prefetcher
from sarmission.perception.mitenet import MiteNet, build_head_runtime
net = MiteNet(build_head_runtime(None, "onnx"), ds=2, topn=25)
source = VideoFileSource(Path(sys.argv[1]))
count = 0
with Prefetcher(source) as video:
    for frame in video:
        if count == 8:
            start, cpu = time.perf_counter(), time.process_time()
        net.process(frame.image_bgr, frame.timestamp_s)
        count += 1
        if count == frames + 8:
            break
print(json.dumps({"ms": (time.perf_counter() - start) * 1e3 / frames,
                  "cpu_ms": (time.process_time() - cpu) * 1e3 / frames,
                  "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""

HEAD = """
import json, sys, time
import numpy as np
from sarmission.perception.mitenet import build_head_runtime
threads = int(sys.argv[1])
head = build_head_runtime(None, "onnx", intra_op_threads=threads)
out = {}
for n in (25, 100):
    crops = np.random.default_rng(0).random((n, 4, 16, 16), dtype=np.float32)
    for _ in range(10):
        head.predict(crops)
    times = []
    for _ in range(60):
        start = time.perf_counter()
        head.predict(crops)
        times.append((time.perf_counter() - start) * 1e3)
    out[n] = sorted(times)[len(times) // 2]
print(json.dumps(out))
"""

PLANS = [(1, 1, 1), (2, 1, 1), (2, 1, 2), (2, 2, 2)]


def child(code: str, *argv: str, others: list[float]) -> dict:
    """Run ``code`` in a fresh process; its JSON result (and the other processes' load)."""
    done = measure([sys.executable, "-c", code, *argv], ROOT)
    others.append(done.others)
    return json.loads(done.out.strip().splitlines()[-1])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "sar-bench")
    parser.add_argument("--clip-frames", type=int, default=300)
    parser.add_argument("--frames", type=int, default=90)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=DOC)
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    clip = make_clip(args.work, args.clip_frames)
    others: list[float] = []
    runs: dict[tuple[int, int, int], list[dict]] = {plan: [] for plan in PLANS}
    heads: dict[int, list[dict]] = {1: [], 2: []}
    for repeat in range(args.repeats):
        print(f"repeat {repeat + 1}/{args.repeats}", flush=True)
        for plan in PLANS:
            runs[plan].append(
                child(PIPELINE, str(clip), *map(str, plan), str(args.frames), others=others)
            )
        for threads in heads:
            heads[threads].append(child(HEAD, str(threads), others=others))
    med = {
        plan: {k: statistics.median(r[k] for r in rs) for k in rs[0]} for plan, rs in runs.items()
    }
    lines = [
        f"Thread plans on {os.cpu_count()} cores, measured {time.strftime('%Y-%m-%d')} with "
        f"`python tools/thread_plan_benchmark.py` (other processes kept "
        f"{min(others):.2f}-{max(others):.2f} cores busy meanwhile): decoding one frame ahead + "
        f"MITE-Net ds 2 N 25 on "
        f"{args.frames} frames of `{clip.name}` after 8 warm-up frames, medians of "
        f"{args.repeats} interleaved runs.",
        "",
        "| FFmpeg threads | OpenCV threads | onnxruntime threads | ms per frame | CPU ms per "
        "frame | peak RSS MB |",
        "|---|---|---|---|---|---|",
    ]
    for plan in PLANS:
        m = med[plan]
        lines.append(
            f"| {plan[0]} | {plan[1]} | {plan[2]} | {m['ms']:.1f} | {m['cpu_ms']:.1f} | "
            f"{m['rss_mb']:.0f} |"
        )
    head = {
        t: {n: statistics.median(r[str(n)] for r in rs) for n in (25, 100)}
        for t, rs in heads.items()
    }
    lines += [
        "",
        "The head alone (onnxruntime, ms per call): "
        + "; ".join(
            f"{t} thread{'s' if t > 1 else ''}: N 25 {h[25]:.2f}, N 100 "
            f"{h[100]:.2f} ({h[100] / h[25]:.1f}x)"
            for t, h in head.items()
        )
        + ".",
    ]
    report = "\n".join(lines)
    write_section(args.out, report, "thread_plan_benchmark")
    print(report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
