"""Throughput benchmark of MITE-Net on 4K frames (the paper's Table 4 sweep), in memory and end
to end on an encoded clip.

In memory: each configuration (ds, N) runs in its own Python process so that its peak resident
memory is its own, and times a plain memory pass (a BGR copy plus a grayscale conversion) on
each frame just before MITE-Net runs on it, so the reference shares the pipeline's conditions.

End to end: the same frames encoded as a video (H.264 by the ``ffmpeg`` command where there is
one, else MPEG-4 by OpenCV), and in another fresh process per configuration, passes of plain
decoding alternate with passes of what ``sarmission detect`` does (decoding in its own thread,
one frame ahead, and MiteNet): ms per frame of each, frames/s, and that process's peak memory.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from sarmission.perception.types import DEFAULT_COLOUR_SHARE, DEFAULT_CROP_SCALES

BLOBS = 120  # enough moving targets that every N up to 100 is filled
WARMUP_FRAMES = 8  # JIT compilation, allocator, and the medulla building up its potentials
CLIP_REPEATS = 2  # alternating decode-only and end-to-end passes over the clip
CLIP_BITRATE = "100M"  # as a 4K drone camera records


@dataclass
class BenchRow:
    """Medians of one (ds, N) configuration."""

    ds: int
    topn: int
    ego_motion: str
    width: int
    height: int
    frames: int
    ms: dict[str, float]
    total_ms: float
    fps: float
    memory_pass_ms: float
    ratio_to_memory_pass: float
    gflops: dict[str, float]
    peak_rss_mb: float
    proposals_per_frame: float
    colour_share: float = 0.0
    crop_scales: tuple[float, ...] = DEFAULT_CROP_SCALES
    refine_threshold: float | None = None
    fit_boxes: bool = True
    clip: dict[str, float | str] = field(default_factory=dict)  # :class:`ClipRow`, or empty


@dataclass
class ClipRow:
    """Medians of the passes over an encoded clip (ms per frame of wall time).

    ``decode_ms``: plain decoding; ``detect_ms``: MiteNet in the end-to-end pass; ``total_ms``:
    the end-to-end pass (decoding overlapped with detection); ``ratio``: total / decode;
    ``cpu_ms``: process CPU time per frame of the end-to-end pass (all threads).
    """

    codec: str
    frames: int
    decode_ms: float
    detect_ms: float
    total_ms: float
    fps: float
    ratio: float
    cpu_ms: float
    peak_rss_mb: float


def synthetic_frames(width: int, height: int, count: int, seed: int = 0) -> list[np.ndarray]:
    """Frames of a textured sea with small moving blobs, seen from a hovering drone.

    The sea texture shimmers (a fresh fine-grain noise field is blended in every frame) so the
    motion front-end sees clutter everywhere, as over real water; the blobs (4–12 px) drift
    1–3 px per frame, as swimmers do in the image of a slowly moving drone.
    """
    import cv2

    rng = np.random.default_rng(seed)
    base = rng.normal(0.0, 1.0, (height // 8 + 1, width // 8 + 1)).astype(np.float32)
    base = cv2.resize(base, (width, height), interpolation=cv2.INTER_CUBIC)
    texture = np.clip(90 + 18 * base, 0, 255)
    sea = np.stack([texture * 1.15, texture * 0.95, texture * 0.55], axis=-1).astype(np.uint8)
    shimmer = [rng.integers(-4, 5, (height, width, 1), dtype=np.int16) for _ in range(3)]
    blobs = rng.uniform([0, 0], [width, height], (BLOBS, 2))
    speed = rng.uniform(1.0, 3.0, BLOBS)
    heading = rng.uniform(0, 2 * np.pi, BLOBS)
    velocity = np.stack([speed * np.cos(heading), speed * np.sin(heading)], axis=1)
    sizes = rng.uniform(4, 12, BLOBS)
    frames = []
    for t in range(count):
        frame = np.clip(sea + shimmer[t % 3], 0, 255).astype(np.uint8)
        for (x, y), (vx, vy), size in zip(blobs, velocity, sizes, strict=True):
            centre = (int((x + vx * t) % width), int((y + vy * t) % height))
            cv2.circle(frame, centre, int(size / 2), (40, 60, 230), -1, cv2.LINE_AA)
        frames.append(frame)
    return frames


def _median(values: list[float]) -> float:
    return float(statistics.median(values)) if values else float("nan")


def _peak_rss_mb() -> float:
    return round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, 1)


def _memory_pass(image: np.ndarray) -> float:
    """ms of the reference: a BGR copy and a grayscale conversion of ``image``."""
    import cv2

    start = time.perf_counter()
    copy = image.copy()
    cv2.cvtColor(copy, cv2.COLOR_BGR2GRAY)
    return (time.perf_counter() - start) * 1e3


def _mitenet(
    ds: int,
    topn: int,
    model: str | None,
    runtime: str,
    ego_motion: str,
    colour_share: float,
    crop_scales: tuple[float, ...],
    refine_threshold: float | None,
    fit_boxes: bool,
):
    from sarmission.perception.mitenet import MiteNet, build_head_runtime

    return MiteNet(
        build_head_runtime(model, runtime),
        ds=ds,
        topn=topn,
        ego_motion=ego_motion,
        colour_share=colour_share,
        crop_scales=crop_scales,
        refine_threshold=refine_threshold,
        fit_boxes=fit_boxes,
    )


def measure_config(
    ds: int,
    topn: int,
    width: int,
    height: int,
    frames: int,
    model: str | None,
    runtime: str,
    ego_motion: str = "estimate",
    colour_share: float = DEFAULT_COLOUR_SHARE,
    crop_scales: tuple[float, ...] = DEFAULT_CROP_SCALES,
    refine_threshold: float | None = None,
    fit_boxes: bool = True,
) -> BenchRow:
    """Time one configuration in this process (call it in a fresh process for memory figures).

    The memory pass runs on each frame right before MiteNet does, so both see the same caches,
    clock and neighbours."""
    from sarmission.perception.mitenet import STAGES
    from sarmission.threads import apply_thread_plan

    apply_thread_plan()
    images = synthetic_frames(width, height, frames + WARMUP_FRAMES)
    net = _mitenet(
        ds,
        topn,
        model,
        runtime,
        ego_motion,
        colour_share,
        crop_scales,
        refine_threshold,
        fit_boxes,
    )
    stage_ms: dict[str, list[float]] = {stage: [] for stage in STAGES}
    totals, proposals, memory_pass = [], [], []
    for i, image in enumerate(images):
        reference = _memory_pass(image)
        start = time.perf_counter()
        result = net.process(image, i / 30.0)
        elapsed = (time.perf_counter() - start) * 1e3
        if i < WARMUP_FRAMES:
            continue
        memory_pass.append(reference)
        totals.append(elapsed)
        proposals.append(len(result.proposals))
        for stage in STAGES:
            stage_ms[stage].append(net.per_stage_ms.get(stage, float("nan")))
    peak = _peak_rss_mb()  # before the FLOP count, which builds the torch head
    flops = net.complexity(height, width)
    total = _median(totals)
    reference = _median(memory_pass)
    return BenchRow(
        ds=ds,
        topn=topn,
        ego_motion=ego_motion,
        width=width,
        height=height,
        frames=len(totals),
        ms={stage: round(_median(v), 3) for stage, v in stage_ms.items()},
        total_ms=round(total, 3),
        fps=round(1e3 / total, 2),
        memory_pass_ms=round(reference, 3),
        ratio_to_memory_pass=round(total / reference, 2),
        gflops={k: round(v / 1e9, 4) for k, v in flops["flops"].items()},
        peak_rss_mb=peak,
        proposals_per_frame=round(float(np.mean(proposals)), 1),
        colour_share=colour_share,
        crop_scales=tuple(crop_scales),
        refine_threshold=net.refine_threshold,
        fit_boxes=net.fit_boxes,
    )


def encode_clip(width: int, height: int, frames: int, folder: str | Path) -> Path:
    """The benchmark's frames as a video in ``folder``: H.264 at :data:`CLIP_BITRATE` by the
    ``ffmpeg`` command when there is one (as a drone camera records), else MPEG-4 by OpenCV."""
    import cv2

    folder = Path(folder)
    images = synthetic_frames(width, height, frames)
    ffmpeg = shutil.which("ffmpeg")
    if ffmpeg is not None:
        path = folder / "bench_h264.mp4"
        encoder = subprocess.Popen(
            [
                ffmpeg,
                "-loglevel",
                "error",
                "-y",
                "-f",
                "rawvideo",
                "-pix_fmt",
                "bgr24",
                "-s",
                f"{width}x{height}",
                "-r",
                "30",
                "-i",
                "-",
                "-c:v",
                "libx264",
                "-preset",
                "veryfast",
                "-b:v",
                CLIP_BITRATE,
                "-maxrate",
                CLIP_BITRATE,
                "-bufsize",
                "200M",
                "-pix_fmt",
                "yuv420p",
                "-g",
                "30",
                str(path),
            ],
            stdin=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        assert encoder.stdin is not None
        try:
            for image in images:
                encoder.stdin.write(image.tobytes())
        finally:
            encoder.stdin.close()
        if encoder.wait() == 0:
            return path
    path = folder / "bench_mp4v.mp4"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30.0, (width, height))
    for image in images:
        writer.write(image)
    writer.release()
    return path


def measure_clip(
    ds: int,
    topn: int,
    clip: str | Path,
    model: str | None,
    runtime: str,
    ego_motion: str = "estimate",
    colour_share: float = DEFAULT_COLOUR_SHARE,
    crop_scales: tuple[float, ...] = DEFAULT_CROP_SCALES,
    refine_threshold: float | None = None,
    fit_boxes: bool = True,
    repeats: int = CLIP_REPEATS,
) -> ClipRow:
    """Alternate plain decoding passes and end-to-end passes (decoding one frame ahead in its
    own thread, as ``detect`` does) over ``clip``; call it in a fresh process. Both read the
    clip as ``detect`` does (the decoder's YUV planes where PyAV is installed), so the plain
    pass is the decoding ``detect`` cannot do without."""
    import cv2

    from sarmission.data.frames import open_frame_source
    from sarmission.data.prefetch import Prefetcher
    from sarmission.threads import apply_thread_plan

    apply_thread_plan()
    source = open_frame_source(Path(clip), yuv=True)
    net = _mitenet(
        ds,
        topn,
        model,
        runtime,
        ego_motion,
        colour_share,
        crop_scales,
        refine_threshold,
        fit_boxes,
    )
    for i, frame in enumerate(source):  # warm-up: allocator, onnxruntime
        net.process(frame.image, frame.timestamp_s)
        if i + 1 >= WARMUP_FRAMES:
            break
    decode, detect, total, cpu = [], [], [], []
    count = 0
    for _ in range(repeats):
        start, count = time.perf_counter(), 0
        for _frame in source:
            count += 1
        decode.append((time.perf_counter() - start) * 1e3 / max(count, 1))
        net.reset()
        start, cpu_start, count, busy = time.perf_counter(), time.process_time(), 0, 0.0
        with Prefetcher(source) as frames:
            for frame in frames:
                t0 = time.perf_counter()
                net.process(frame.image, frame.timestamp_s)
                busy += time.perf_counter() - t0
                count += 1
        total.append((time.perf_counter() - start) * 1e3 / max(count, 1))
        cpu.append((time.process_time() - cpu_start) * 1e3 / max(count, 1))
        detect.append(busy * 1e3 / max(count, 1))
    capture = cv2.VideoCapture(str(clip))
    fourcc = int(capture.get(cv2.CAP_PROP_FOURCC))
    capture.release()
    codec = "".join(chr((fourcc >> 8 * k) & 0xFF) for k in range(4)).strip() or "?"
    decode_ms, total_ms = _median(decode), _median(total)
    return ClipRow(
        codec=codec,
        frames=count,
        decode_ms=round(decode_ms, 2),
        detect_ms=round(_median(detect), 2),
        total_ms=round(total_ms, 2),
        fps=round(1e3 / total_ms, 2),
        ratio=round(total_ms / decode_ms, 2),
        cpu_ms=round(_median(cpu), 2),
        peak_rss_mb=_peak_rss_mb(),
    )


def _settings_argv(
    colour_share: float,
    crop_scales: tuple[float, ...],
    refine_threshold: float | None,
    fit_boxes: bool,
) -> list[str]:
    return [
        repr(colour_share),
        ",".join(repr(v) for v in crop_scales),
        "" if refine_threshold is None else repr(refine_threshold),
        "1" if fit_boxes else "0",
    ]


def _run_worker(argv: list[str], what: str) -> dict:
    cmd = [sys.executable, "-m", "sarmission.benchmark", *argv]
    done = subprocess.run(cmd, capture_output=True, text=True, env=os.environ.copy())
    if done.returncode != 0:
        raise RuntimeError(f"benchmark of {what} failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def run_sweep(
    ds_values: list[int],
    topn_values: list[int],
    width: int,
    height: int,
    frames: int,
    model: str | None,
    runtime: str,
    ego_motion: str = "estimate",
    on_row: Callable[[BenchRow], None] | None = None,
    colour_share: float = DEFAULT_COLOUR_SHARE,
    crop_scales: tuple[float, ...] = DEFAULT_CROP_SCALES,
    refine_threshold: float | None = None,
    clip: str | Path | None = None,
    fit_boxes: bool = True,
) -> list[BenchRow]:
    """Run every (ds, N) configuration in a fresh process (and, with ``clip``, its end-to-end
    passes over that video in another) and collect the rows; ``on_row`` sees each."""
    settings = _settings_argv(colour_share, crop_scales, refine_threshold, fit_boxes)
    rows = []
    for ds, topn in [(ds, n) for ds in ds_values for n in topn_values]:
        common = [str(ds), str(topn), model or "", runtime, ego_motion, *settings]
        row = _run_worker(
            ["memory", *common, str(width), str(height), str(frames)], f"ds={ds} N={topn}"
        )
        row["crop_scales"] = tuple(row["crop_scales"])
        if clip is not None:
            row["clip"] = _run_worker(["clip", *common, str(clip)], f"ds={ds} N={topn} on {clip}")
        rows.append(BenchRow(**row))
        if on_row is not None:
            on_row(rows[-1])
    return rows


def format_table(rows: list[BenchRow]) -> str:
    """Render the rows as a fixed-width text table."""
    header = (
        f"{'ds':>2} {'N':>4} {'vstmd':>7} {'colour':>6} {'rpn':>6} {'crops':>6} {'head':>6} "
        f"{'fit':>5} {'total':>7} {'FPS':>6} {'mem':>6} {'ratio':>6} {'GFLOPs':>7} {'RSS MB':>7} "
        f"{'props':>6}"
    )
    lines = [header, "-" * len(header)]
    for r in rows:
        lines.append(
            f"{r.ds:>2} {r.topn:>4} {r.ms['vstmd']:>7.2f} {r.ms.get('colour', 0.0):>6.2f} "
            f"{r.ms['rpn']:>6.2f} "
            f"{r.ms['crops']:>6.2f} {r.ms['head']:>6.2f} {r.ms.get('fit', 0.0):>5.2f} "
            f"{r.total_ms:>7.2f} {r.fps:>6.1f} "
            f"{r.memory_pass_ms:>6.2f} {r.ratio_to_memory_pass:>6.1f} "
            f"{r.gflops.get('total', float('nan')):>7.4f} {r.peak_rss_mb:>7.0f} "
            f"{r.proposals_per_frame:>6.1f}"
        )
    lines.append(
        "times in ms (medians per frame); mem = plain memory pass (BGR copy + grayscale) "
        "on each frame just before MITE-Net; ratio = total / mem"
    )
    if rows:
        scales = ",".join(f"{v:g}" for v in rows[0].crop_scales)
        lines.append(
            f"ego-motion compensation: {rows[0].ego_motion}; colour share "
            f"{rows[0].colour_share:g}; crop scales {scales}"
            + (
                f" (further scales from first-crop score {rows[0].refine_threshold:g})"
                if len(rows[0].crop_scales) > 1 and rows[0].refine_threshold is not None
                else ""
            )
            + f"; boxes {'fitted to the object' if rows[0].fit_boxes else 'as the head gives them'}"
        )
    clip_rows = [r for r in rows if r.clip]
    if clip_rows:
        lines += ["", _clip_table(clip_rows)]
    return "\n".join(lines)


def _clip_table(rows: list[BenchRow]) -> str:
    """End-to-end rows: decoding alone, then decoding overlapped with MiteNet."""
    header = (
        f"{'ds':>2} {'N':>4} {'decode':>7} {'detect':>7} {'total':>7} {'FPS':>6} "
        f"{'ratio':>6} {'CPU':>7} {'RSS MB':>7}"
    )
    lines = [
        f"end to end on an encoded clip ({rows[0].clip['codec']}, "
        f"{rows[0].width}x{rows[0].height}, {rows[0].clip['frames']} frames):",
        header,
        "-" * len(header),
    ]
    for r in rows:
        c = r.clip
        lines.append(
            f"{r.ds:>2} {r.topn:>4} {c['decode_ms']:>7.1f} {c['detect_ms']:>7.1f} "
            f"{c['total_ms']:>7.1f} {c['fps']:>6.1f} {c['ratio']:>6.2f} "
            f"{c['cpu_ms']:>7.1f} {c['peak_rss_mb']:>7.0f}"
        )
    lines.append(
        "decode = plain decoding pass; detect = MiteNet while decoding runs in its own "
        "thread; total = that pass per frame; ratio = total / decode; CPU = CPU time "
        "per frame, all threads; passes alternate, medians of "
        f"{CLIP_REPEATS}"
    )
    return "\n".join(lines)


def rows_to_json(rows: list[BenchRow]) -> str:
    """Serialise rows as a JSON list."""
    return json.dumps([asdict(r) for r in rows], indent=2)


def _worker(argv: list[str]) -> None:
    mode, ds, topn, model, runtime, ego_motion = argv[:6]
    colour_share = float(argv[6])
    crop_scales = tuple(float(v) for v in argv[7].split(","))
    refine_threshold = float(argv[8]) if argv[8] else None
    fit_boxes = argv[9] == "1"
    settings = (ego_motion, colour_share, crop_scales, refine_threshold, fit_boxes)
    if mode == "memory":
        width, height, frames = (int(v) for v in argv[10:13])
        row = asdict(
            measure_config(
                int(ds), int(topn), width, height, frames, model or None, runtime, *settings
            )
        )
    else:
        row = asdict(measure_clip(int(ds), int(topn), argv[10], model or None, runtime, *settings))
    print(json.dumps(row))


if __name__ == "__main__":
    _worker(sys.argv[1:])
