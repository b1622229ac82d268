"""Throughput benchmark of MITE-Net on 4K frames held in memory (the paper's Table 4 sweep).

Each configuration (ds, N) runs in its own Python process so that its peak resident memory is
its own; every process also times a plain memory pass over the same frames (a BGR copy plus a
grayscale conversion) as the reference the pipeline is compared with.
"""

from __future__ import annotations

import json
import os
import resource
import statistics
import subprocess
import sys
import time
from dataclasses import asdict, dataclass

import numpy as np

from sarmission.perception.types import DEFAULT_COLOUR_SHARE, DEFAULT_CROP_SCALES

BLOBS = 120  # enough moving targets that every N up to 100 is filled
WARMUP_FRAMES = 8  # JIT compilation, allocator, and the medulla building up its potentials


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


def measure_config(ds: int, topn: int, width: int, height: int, frames: int,
                   model: str | None, runtime: str, ego_motion: str = "estimate",
                   colour_share: float = DEFAULT_COLOUR_SHARE,
                   crop_scales: tuple[float, ...] = DEFAULT_CROP_SCALES,
                   refine_threshold: float | None = None) -> BenchRow:
    """Time one configuration in this process (call it in a fresh process for memory figures)."""
    import cv2

    from sarmission.perception.mitenet import STAGES, MiteNet, build_head_runtime

    images = synthetic_frames(width, height, frames + WARMUP_FRAMES)
    memory_pass = []
    for image in images:
        start = time.perf_counter()
        copy = image.copy()
        cv2.cvtColor(copy, cv2.COLOR_BGR2GRAY)
        memory_pass.append((time.perf_counter() - start) * 1e3)

    net = MiteNet(build_head_runtime(model, runtime), ds=ds, topn=topn, ego_motion=ego_motion,
                  colour_share=colour_share, crop_scales=crop_scales,
                  refine_threshold=refine_threshold)
    stage_ms: dict[str, list[float]] = {stage: [] for stage in STAGES}
    totals, proposals = [], []
    for i, image in enumerate(images):
        start = time.perf_counter()
        result = net.process(image, i / 30.0)
        elapsed = (time.perf_counter() - start) * 1e3
        if i < WARMUP_FRAMES:
            continue
        totals.append(elapsed)
        proposals.append(len(result.proposals))
        for stage in STAGES:
            stage_ms[stage].append(net.per_stage_ms.get(stage, float("nan")))
    flops = net.complexity(height, width)
    total = _median(totals)
    reference = _median(memory_pass)
    return BenchRow(
        ds=ds, topn=topn, ego_motion=ego_motion, width=width, height=height, frames=len(totals),
        ms={stage: round(_median(v), 3) for stage, v in stage_ms.items()},
        total_ms=round(total, 3), fps=round(1e3 / total, 2),
        memory_pass_ms=round(reference, 3), ratio_to_memory_pass=round(total / reference, 2),
        gflops={k: round(v / 1e9, 4) for k, v in flops["flops"].items()},
        peak_rss_mb=round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, 1),
        proposals_per_frame=round(float(np.mean(proposals)), 1),
        colour_share=colour_share, crop_scales=tuple(crop_scales),
        refine_threshold=net.refine_threshold,
    )


def run_sweep(ds_values: list[int], topn_values: list[int], width: int, height: int,
              frames: int, model: str | None, runtime: str, ego_motion: str = "estimate",
              progress: bool = True, colour_share: float = DEFAULT_COLOUR_SHARE,
              crop_scales: tuple[float, ...] = DEFAULT_CROP_SCALES,
              refine_threshold: float | None = None) -> list[BenchRow]:
    """Run every (ds, N) configuration in a fresh process and collect the rows."""
    from tqdm import tqdm

    configs = [(ds, n) for ds in ds_values for n in topn_values]
    rows = []
    for ds, topn in tqdm(configs, desc="bench", unit="config", disable=not progress,
                         file=sys.stderr):
        cmd = [sys.executable, "-m", "sarmission.benchmark", str(ds), str(topn), str(width),
               str(height), str(frames), model or "", runtime, ego_motion,
               repr(colour_share),
               ",".join(repr(v) for v in crop_scales),
               "" if refine_threshold is None else repr(refine_threshold)]
        done = subprocess.run(cmd, capture_output=True, text=True, env=os.environ.copy())
        if done.returncode != 0:
            raise RuntimeError(f"benchmark of ds={ds} N={topn} failed:\n{done.stderr[-2000:]}")
        row = json.loads(done.stdout.strip().splitlines()[-1])
        row["crop_scales"] = tuple(row["crop_scales"])
        rows.append(BenchRow(**row))
    return rows


def format_table(rows: list[BenchRow]) -> str:
    """Render the rows as a fixed-width text table."""
    header = (f"{'ds':>2} {'N':>4} {'vstmd':>7} {'colour':>6} {'rpn':>6} {'crops':>6} {'head':>6} "
              f"{'total':>7} {'FPS':>6} {'mem':>6} {'ratio':>6} {'GFLOPs':>7} {'RSS MB':>7} "
              f"{'props':>6}")
    lines = [header, "-" * len(header)]
    for r in rows:
        lines.append(
            f"{r.ds:>2} {r.topn:>4} {r.ms['vstmd']:>7.2f} {r.ms.get('colour', 0.0):>6.2f} "
            f"{r.ms['rpn']:>6.2f} "
            f"{r.ms['crops']:>6.2f} {r.ms['head']:>6.2f} {r.total_ms:>7.2f} {r.fps:>6.1f} "
            f"{r.memory_pass_ms:>6.2f} {r.ratio_to_memory_pass:>6.1f} "
            f"{r.gflops.get('total', float('nan')):>7.4f} {r.peak_rss_mb:>7.0f} "
            f"{r.proposals_per_frame:>6.1f}")
    lines.append("times in ms (medians per frame); mem = plain memory pass (BGR copy + grayscale) "
                 "on the same frames; ratio = total / mem")
    if rows:
        scales = ",".join(f"{v:g}" for v in rows[0].crop_scales)
        lines.append(f"ego-motion compensation: {rows[0].ego_motion}; colour share "
                     f"{rows[0].colour_share:g}; crop scales {scales}"
                     + (f" (further scales from first-crop score {rows[0].refine_threshold:g})"
                        if len(rows[0].crop_scales) > 1 and rows[0].refine_threshold is not None
                        else ""))
    return "\n".join(lines)


def rows_to_json(rows: list[BenchRow]) -> str:
    """Serialise rows as a JSON list."""
    return json.dumps([asdict(r) for r in rows], indent=2)


def _worker(argv: list[str]) -> None:
    ds, topn, width, height, frames = (int(v) for v in argv[:5])
    model, runtime, ego_motion = argv[5] or None, argv[6], argv[7]
    crop_scales = tuple(float(v) for v in argv[9].split(","))
    refine_threshold = float(argv[10]) if argv[10] else None
    row = measure_config(ds, topn, width, height, frames, model, runtime, ego_motion,
                         float(argv[8]), crop_scales, refine_threshold)
    print(json.dumps(asdict(row)))


if __name__ == "__main__":
    _worker(sys.argv[1:])
