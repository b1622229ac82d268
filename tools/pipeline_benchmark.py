"""Before/after benchmark of the video pipeline on a 4K H.264 clip, written to docs/benchmarks.md.

Compares this checkout with another one (``--baseline DIR``, e.g. ``git worktree add /tmp/before
<revision>``), side by side in one run, each measurement repeated and interleaved (decode-only,
baseline, this checkout, again ...) so that both meet the same machine state; medians reported:

- ``detect --ds 2 --topn 25`` over the clip: wall time, frames/s, CPU time, peak RSS, against a
  plain OpenCV decoding loop over the same file (whole processes: start-up included);
- ``run --video CLIP`` (no autopilot; the file played as a camera in real time): peak RSS;
- what importing the detection path and loading the model costs (RSS, torch loaded or not);
- crops + head at N 25, 50 and 100 (``sarmission bench --ds 2``, frames in memory);
- whether the two checkouts' detections are the same, byte for byte, and if not how many of
  them match (same frame and class, box corners within 4 px) and how far those differ.

The clip is rendered by the simulator (maritime_test, 300 frames of 3840x2160) and encoded as
H.264 at 100 Mb/s by ``ffmpeg``, cached under ``--work``. The load average is recorded with the
figures; start it when the machine is otherwise idle (``--wait-quiet`` waits for that).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from sarmission.commands.cli_helpers import free_udp_port

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "benchmarks.md"

DECODE_ONLY = """
import sys, cv2
capture = cv2.VideoCapture(sys.argv[1])
n = 0
while capture.read()[0]:
    n += 1
print(n)
"""

IMPORT_COST = """
import json, resource, sys
from sarmission.perception.mitenet import MiteNet, build_head_runtime
import sarmission.commands.detect, sarmission.data.frames
net = MiteNet(build_head_runtime(None, "onnx"))
print(json.dumps({"rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "torch": "torch" in sys.modules, "onnx": "onnx" in sys.modules}))
"""


@dataclass
class Run:
    """One child process: wall seconds, CPU seconds (all threads), peak RSS in MB, stdout, and
    the cores other processes of the machine kept busy meanwhile (on average)."""

    wall_s: float
    cpu_s: float
    rss_mb: float
    out: str = ""
    others: float = 0.0


def machine_busy_s() -> float:
    """CPU seconds all processes of the machine have spent busy since boot (/proc/stat)."""
    fields = Path("/proc/stat").read_text().splitlines()[0].split()[1:]
    user, nice, system, _idle, _iowait, irq, softirq, steal = (int(v) for v in fields[:8])
    return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")


@dataclass
class Series:
    runs: list[Run] = field(default_factory=list)
    loads: list[float] = field(default_factory=list)

    def median(self, attr: str) -> float:
        return statistics.median(getattr(r, attr) for r in self.runs)

    def spread(self, attr: str) -> str:
        values = [getattr(r, attr) for r in self.runs]
        return f"{min(values):.1f}-{max(values):.1f}"


def measure(cmd: list[str], cwd: Path, timeout_s: float = 900.0) -> Run:
    """Run ``cmd`` in ``cwd`` (its ``sarmission`` package first on the path); wall, CPU, RSS."""
    env = dict(os.environ, PYTHONPATH=str(cwd), SARMISSION_DEBUG="1")
    with tempfile.TemporaryFile("w+") as out:
        busy, own = machine_busy_s(), time.process_time()
        start = time.perf_counter()
        process = subprocess.Popen(
            cmd, cwd=cwd, env=env, stdout=out, stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL
        )
        deadline = start + timeout_s
        while True:
            pid, status, usage = os.wait4(process.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() > deadline:
                process.kill()
                raise RuntimeError(f"timed out: {' '.join(cmd)}")
            time.sleep(0.02)
        wall = time.perf_counter() - start
        cpu = usage.ru_utime + usage.ru_stime
        others = (machine_busy_s() - busy - cpu - (time.process_time() - own)) / wall
        process.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        text = out.read()
    if process.returncode != 0:
        raise RuntimeError(f"exit {process.returncode}: {' '.join(cmd)}\n{text[-2000:]}")
    return Run(wall, cpu, usage.ru_maxrss / 1024.0, text, max(0.0, others))


def load1() -> float:
    return os.getloadavg()[0]


def wait_quiet(limit: float, patience_s: float) -> None:
    """Wait (up to ``patience_s``) for the 1-minute load average to fall below ``limit``."""
    deadline = time.monotonic() + patience_s
    while load1() > limit and time.monotonic() < deadline:
        print(f"load {load1():.2f} > {limit}: waiting", flush=True)
        time.sleep(30)


def make_clip(work: Path, frames: int) -> Path:
    """The simulator's maritime_test clip, 4K, as H.264 at 100 Mb/s (cached)."""
    clip = work / f"maritime_test_{frames}_h264.mp4"
    if clip.is_file():
        return clip
    ffmpeg = shutil.which("ffmpeg")
    if ffmpeg is None:
        raise SystemExit("needs the ffmpeg command to encode H.264 (apt-get install ffmpeg)")
    rendered = work / f"render_{frames}"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "sarmission.cli",
            "sim",
            "generate",
            "--scenario",
            "maritime_test",
            "--frames",
            str(frames),
            "--size",
            "3840x2160",
            "--out",
            str(rendered),
            "--no-progress",
        ],
        check=True,
        cwd=ROOT,
    )
    subprocess.run(
        [
            ffmpeg,
            "-loglevel",
            "error",
            "-y",
            "-i",
            str(rendered / "maritime_test_00.mp4"),
            "-c:v",
            "libx264",
            "-preset",
            "veryfast",
            "-b:v",
            "100M",
            "-maxrate",
            "100M",
            "-bufsize",
            "200M",
            "-pix_fmt",
            "yuv420p",
            "-g",
            "30",
            str(clip),
        ],
        check=True,
    )
    shutil.copy(rendered / "maritime_test.json", work / f"maritime_test_{frames}.json")
    return clip


def detections_gap(before: str, after: str, max_px: float = 4.0) -> str:
    """How two results files (COCO JSON text) differ: the share of their detections that pair
    up (same frame and class, every box corner within ``max_px``; each used once, best score
    first) and the pairs' corner and score differences (median, 90th and 99th percentiles)."""
    if before == after:
        return "identical (results files compared byte for byte)"

    def by_frame(text: str) -> dict[int, list[tuple[float, int, tuple[float, ...]]]]:
        frames: dict[int, list[tuple[float, int, tuple[float, ...]]]] = {}
        for d in json.loads(text):
            x, y, w, h = d["bbox"]
            item = (d["score"], d["category_id"], (x, y, x + w, y + h))
            frames.setdefault(d["frame_index"], []).append(item)
        return frames

    a, b = by_frame(before), by_frame(after)
    total = sum(map(len, a.values())) + sum(map(len, b.values()))
    box_gaps: list[float] = []
    score_gaps: list[float] = []
    for frame, dets in a.items():
        free = list(b.get(frame, []))
        for score, category, box in sorted(dets, reverse=True):
            gaps = [
                (max(abs(p - q) for p, q in zip(box, other[2], strict=True)), k)
                for k, other in enumerate(free)
                if other[1] == category
            ]
            gap, k = min(gaps, default=(math.inf, -1))
            if gap <= max_px:
                box_gaps.append(gap)
                score_gaps.append(abs(score - free[k][0]))
                free.pop(k)

    if not box_gaps:
        return f"DIFFERENT: none of the {total} detections of the two pair up"

    def spread(values: list[float], digits: int) -> str:
        data = values if len(values) > 1 else values * 2  # quantiles() needs two
        cuts = statistics.quantiles(data, n=100, method="inclusive")
        return " / ".join(f"{cuts[i]:.{digits}f}" for i in (49, 89, 98))

    return (
        f"DIFFERENT: {2 * len(box_gaps)} of the {total} detections of the two pair up (same "
        f"frame and class, box corners within {max_px:g} px); the pairs' corners differ by "
        f"{spread(box_gaps, 2)} px and their scores by {spread(score_gaps, 3)} (median / 90th / "
        "99th percentile)"
    )


def supports(checkout: Path, command: str, option: str) -> bool:
    """Whether ``sarmission COMMAND`` of ``checkout`` has ``option``."""
    done = subprocess.run(
        [sys.executable, "-m", "sarmission.cli", command, "--help"],
        cwd=checkout,
        env=dict(os.environ, PYTHONPATH=str(checkout)),
        capture_output=True,
        text=True,
        timeout=120,
    )
    return option in done.stdout


def crops_head(rows: list[dict]) -> dict[int, float]:
    return {row["topn"]: row["ms"]["crops"] + row["ms"]["head"] for row in rows}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--baseline", type=Path, required=True, help="checkout of the revision to compare with"
    )
    parser.add_argument("--baseline-label", default="before")
    parser.add_argument("--label", default="after")
    parser.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "sar-bench")
    parser.add_argument("--frames", type=int, default=300, help="frames of the clip")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--run-frames",
        type=int,
        default=150,
        help="frames of the run measurement (played at 30 fps)",
    )
    parser.add_argument("--bench-repeats", type=int, default=2)
    parser.add_argument(
        "--wait-quiet",
        type=float,
        default=0.0,
        metavar="S",
        help="first wait up to S seconds for the load average to fall below 0.5",
    )
    parser.add_argument("--out", type=Path, default=DOC)
    args = parser.parse_args()

    args.work.mkdir(parents=True, exist_ok=True)
    clip = make_clip(args.work, args.frames)
    sides = [(args.baseline_label, args.baseline.resolve()), (args.label, ROOT)]
    if args.wait_quiet:
        wait_quiet(0.5, args.wait_quiet)
    py = sys.executable
    for _label, checkout in sides:  # JIT caches compiled before anything is timed
        with tempfile.TemporaryDirectory() as tmp:
            measure(
                [
                    py,
                    "-m",
                    "sarmission.cli",
                    "detect",
                    str(clip),
                    "--max-frames",
                    "3",
                    "--out",
                    str(Path(tmp) / "warm.json"),
                ],
                checkout,
            )
    decode = Series()
    detect = {label: Series() for label, _ in sides}
    run = {label: Series() for label, _ in sides}
    outputs: dict[str, str] = {}
    started_load = os.getloadavg()
    for repeat in range(args.repeats):
        print(f"repeat {repeat + 1}/{args.repeats}", flush=True)
        decode.loads.append(load1())
        decode.runs.append(measure([py, "-c", DECODE_ONLY, str(clip)], ROOT))
        for label, checkout in sides:
            out = args.work / f"dets_{label}.json"
            extra = ["--no-progress"] if supports(checkout, "detect", "--no-progress") else []
            detect[label].loads.append(load1())
            detect[label].runs.append(
                measure(
                    [
                        py,
                        "-m",
                        "sarmission.cli",
                        "detect",
                        str(clip),
                        "--ds",
                        "2",
                        "--topn",
                        "25",
                        "--out",
                        str(out),
                        *extra,
                    ],
                    checkout,
                )
            )
            outputs[label] = out.read_text()
        for label, checkout in sides:
            with tempfile.TemporaryDirectory() as tmp:
                run[label].loads.append(load1())
                run[label].runs.append(
                    measure(
                        [
                            py,
                            "-m",
                            "sarmission.cli",
                            "run",
                            "--connect",
                            f"udpin:127.0.0.1:{free_udp_port()}",
                            "--connect-timeout",
                            "1",
                            "--video",
                            str(clip),
                            "--max-frames",
                            str(args.run_frames),
                            "--alerts-db",
                            str(Path(tmp) / "alerts.db"),
                        ],
                        checkout,
                    )
                )
    imports = {
        label: json.loads(measure([py, "-c", IMPORT_COST], checkout).out)
        for label, checkout in sides
    }
    bench: dict[str, list[dict[int, float]]] = {label: [] for label, _ in sides}
    for _ in range(args.bench_repeats):
        for label, checkout in sides:
            extra = (
                ["--no-clip", "--no-progress"] if supports(checkout, "bench", "--no-clip") else []
            )
            done = measure(
                [
                    py,
                    "-m",
                    "sarmission.cli",
                    "bench",
                    "--ds",
                    "2",
                    "--topn",
                    "25,50,100",
                    "--frames",
                    "20",
                    "--json",
                    *extra,
                ],
                checkout,
                1800,
            )
            bench[label].append(crops_head(json.loads(done.out)))
    ended_load = os.getloadavg()
    same = detections_gap(outputs[args.baseline_label], outputs[args.label])
    count = len(json.loads(outputs[args.label]))
    report = render(
        args,
        clip,
        sides,
        decode,
        detect,
        run,
        imports,
        bench,
        same,
        count,
        started_load,
        ended_load,
    )
    write_section(args.out, report)
    print(report)
    return 0


def render(
    args, clip, sides, decode, detect, run, imports, bench, same, count, started, ended
) -> str:
    frames = args.frames
    cpu = platform.processor() or platform.machine()
    model = (
        next(
            (
                line.split(":", 1)[1].strip()
                for line in Path("/proc/cpuinfo").read_text().splitlines()
                if line.startswith("model name")
            ),
            cpu,
        )
        if Path("/proc/cpuinfo").exists()
        else cpu
    )
    others = [r.others for s in [decode, *detect.values(), *run.values()] for r in s.runs]
    lines = [
        f"Measured {time.strftime('%Y-%m-%d')} with `python tools/pipeline_benchmark.py "
        f"--baseline <checkout of {args.baseline_label}>`: {os.cpu_count()} cores ({model}), "
        f"{frames}-frame 3840x2160 H.264 clip at 100 Mb/s (`{clip.name}`, the simulator's "
        f"maritime_test), {args.repeats} interleaved repeats, medians (range). Other "
        f"processes kept {min(others):.2f}-{max(others):.2f} cores busy during the runs "
        f"(/proc/stat less the runs' own CPU time; 1-minute load average {started[0]:.2f} at "
        f"the start). Whole processes: start-up (imports, model, JIT caches) is included in "
        "detect's time.",
        "",
        "| | wall s | frames/s | CPU s | CPU use | peak RSS MB | ÷ decode-only |",
        "|---|---|---|---|---|---|---|",
    ]
    base = decode.median("wall_s")

    def row(name: str, s: Series) -> str:
        wall, cpu_s = s.median("wall_s"), s.median("cpu_s")
        return (
            f"| {name} | {wall:.1f} ({s.spread('wall_s')}) | {frames / wall:.1f} | "
            f"{cpu_s:.1f} | {cpu_s / wall:.2f} cores | {s.median('rss_mb'):.0f} "
            f"({s.spread('rss_mb')}) | {wall / base:.2f} |"
        )

    lines.append(row("decode only (OpenCV loop)", decode))
    for label, _ in sides:
        lines.append(row(f"`detect --ds 2 --topn 25`, {label}", detect[label]))
    lines += [
        "",
        f"`run --video CLIP --max-frames {args.run_frames}` (file played at 30 fps, no "
        "autopilot): peak RSS "
        + ", ".join(
            f"{label} {run[label].median('rss_mb'):.0f} MB ({run[label].spread('rss_mb')})"
            for label, _ in sides
        )
        + ".",
    ]
    lines += [
        "",
        "Importing the detection path and loading the ONNX head: "
        + ", ".join(
            f"{label} {imports[label]['rss_mb']:.0f} MB"
            f"{' with torch' if imports[label]['torch'] else ', no torch'}"
            for label, _ in sides
        )
        + ".",
    ]
    lines += [
        "",
        "Crops + head, ms per frame (`sarmission bench --ds 2 --topn 25,50,100 "
        f"--frames 20`, frames in memory, medians of {args.bench_repeats} runs):",
        "",
        "| | N 25 | N 50 | N 100 | N 100 ÷ N 25 |",
        "|---|---|---|---|---|",
    ]
    for label, _ in sides:
        med = {n: statistics.median(r[n] for r in bench[label]) for n in (25, 50, 100)}
        lines.append(
            f"| {label} | {med[25]:.1f} | {med[50]:.1f} | {med[100]:.1f} | "
            f"{med[100] / med[25]:.1f} |"
        )
    lines += [
        "",
        f"Detections of the two ({count} over {frames} frames in this checkout): {same}.",
    ]
    return "\n".join(lines)


def write_section(path: Path, report: str, tag: str = "pipeline_benchmark") -> None:
    """Replace the section between ``tag``'s markers in ``path`` (or append it)."""
    begin, end = f"<!-- {tag}: begin -->", f"<!-- {tag}: end -->"
    text = path.read_text() if path.exists() else "# Benchmarks\n"
    block = f"{begin}\n{report}\n{end}"
    if begin in text and end in text:
        text = re.sub(re.escape(begin) + ".*?" + re.escape(end), lambda _m: block, text, flags=re.S)
    else:
        text = text.rstrip() + "\n\n" + block + "\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


if __name__ == "__main__":
    sys.exit(main())
