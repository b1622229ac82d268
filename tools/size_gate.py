"""Which real and simulated boxes the confirmation's person-size gate keeps, per class and band of
view angle, with a box sized across the line of sight (what the mission does) and on the ground
plane (what it did before), written to docs/size_gate.md.

Real: the SeaDronesSee validation file (``../shared/datasets/seadronessee/instances_val.json``,
read with its own conventions), its boxes on frames that look at least 3 degrees down.
Simulator: the oblique presets' frames of ``tools/sim_vs_real.py`` (figures standing up out of
the water). Every box is sized from its frame's meta through the replay's telemetry path and a
70-degree lens (the file states no lens; the simulator's presets fly one), against the default
``[confirm]`` gate (``min_size_m``-``max_size_m``).

    nice -n 19 python tools/size_gate.py [--frames 8] [--seeds 3] [--width 640] [--no-sim]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for folder in (ROOT, ROOT / "tools"):  # runnable from a checkout that is not installed
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

from sarmission.data.coco_video import VideoDataset, read_coco_video  # noqa: E402
from sarmission.data.meta_conventions import MetaPose, dataset_conventions, meta_pose  # noqa: E402
from sarmission.geo.camera import CameraIntrinsics  # noqa: E402
from sarmission.geo.geolocate import PlatformPose  # noqa: E402
from sarmission.geo.ground_size import apparent_size_m, ground_extent_m  # noqa: E402
from sarmission.mavlink.telemetry import TelemetryBuffer  # noqa: E402
from sarmission.mission.config import ConfirmConfig  # noqa: E402
from sarmission.mission.replay_telemetry import push_frame_telemetry  # noqa: E402

OUT = ROOT / "docs" / "size_gate.md"
HFOV_DEG = 70.0
MIN_PITCH_DEG = 3.0
BANDS = ((3.0, 30.0), (30.0, 60.0), (60.0, 90.01))
#: Classes under one name per role: people (with or without a life jacket) and objects.
SAME_AS = {"swimmer_with_life_jacket": "swimmer"}
CLASSES = ("swimmer", "life_saving_appliances", "buoy", "jetski", "boat")
MEASURES: dict[str, Callable[..., float | None]] = {
    "across the sight": apparent_size_m,
    "on the ground": ground_extent_m,
}

Sizes = dict[tuple[str, int], dict[str, list[float]]]


def platform_pose(pose: MetaPose) -> PlatformPose | None:
    """A frame's pose as ``sarmission replay`` gets it: pushed into a buffer, looked up."""
    buffer = TelemetryBuffer()
    push_frame_telemetry(buffer, 0.0, pose)
    found = buffer.lookup(0.0)
    return found if isinstance(found, PlatformPose) else None


def box_sizes(dataset: VideoDataset) -> Sizes:
    """Per (class, band index): each measure's sizes of the boxes it could size."""
    conventions = dataset_conventions(dataset)
    names = {c.id: SAME_AS.get(c.name, c.name) for c in dataset.categories}
    frames: dict[int, tuple[PlatformPose, CameraIntrinsics, int]] = {}
    for image in dataset.images:
        pose = meta_pose(image.telemetry, conventions)
        if not isinstance(pose, MetaPose) or -pose.gimbal_pitch_deg < MIN_PITCH_DEG:
            continue
        platform = platform_pose(pose)
        if platform is None:
            continue
        band = next(i for i, (lo, hi) in enumerate(BANDS) if lo <= -pose.gimbal_pitch_deg < hi)
        intr = CameraIntrinsics.from_hfov(image.width, image.height, HFOV_DEG)
        frames[image.id] = (platform, intr, band)
    sizes: Sizes = {}
    for ann in dataset.annotations:
        name = names[ann.category_id]
        if ann.image_id not in frames or name not in CLASSES:
            continue
        platform, intr, band = frames[ann.image_id]
        x, y, w, h = ann.bbox
        cell = sizes.setdefault((name, band), {m: [] for m in MEASURES})
        for measure, size_of in MEASURES.items():
            size = size_of((x, y, x + w, y + h), intr, platform)
            if size is not None:
                cell[measure].append(size)
    return sizes


def _band(i: int) -> str:
    lo, hi = BANDS[i]
    return f"{lo:.0f}-{min(hi, 90.0):.0f}"


def table(sizes: Sizes, rule: ConfirmConfig) -> list[str]:
    """One row per class and band: boxes, sizes across the sight, share kept by each measure."""

    def kept(values: list[float]) -> str:
        if not values:
            return "-"
        inside = np.mean([rule.min_size_m <= v <= rule.max_size_m for v in values])
        return f"{100 * inside:.0f} %"

    rows = [
        "| class | pitch below the horizon, degrees | boxes | across the sight, m: p5 / p50 / p95 "
        "| kept, across the sight | kept, on the ground |",
        "|---|---|---|---|---|---|",
    ]
    for name in CLASSES:
        for i in range(len(BANDS)):
            cell = sizes.get((name, i))
            if not cell or not cell["across the sight"]:
                continue
            across = cell["across the sight"]
            p5, p50, p95 = np.percentile(across, [5, 50, 95])
            rows.append(
                f"| {name} | {_band(i)} | {len(across)} | {p5:.2f} / {p50:.2f} / {p95:.2f} "
                f"| {kept(across)} | {kept(cell['on the ground'])} |"
            )
    return rows


def render(real: Sizes, sim: Sizes | None, command: str, rule: ConfirmConfig) -> str:
    lines = [
        "# The person-size gate on real and simulated boxes",
        "",
        f"Generated by `{command}` (`tools/size_gate.py`). A candidate becomes an alert only if "
        f"its size fits a person: {rule.min_size_m:g}-{rule.max_size_m:g} m, the `[confirm]` "
        "defaults. The mission sizes a box across the line of sight: its larger angular side "
        "times the slant range to its centre (`sarmission.geo.ground_size.apparent_size_m`). "
        "Until 2026-11-29 it took the box's extent on the ground plane, which stretches "
        "anything with height by 1 / tan(depression) in an oblique view. Each box is sized "
        "from its frame's meta through the replay's telemetry path and a 70-degree lens. A "
        "box sized on the ground can have no size when an edge lies above the horizon, so its "
        "share can be of fewer boxes. *Kept*: the share of the boxes the gate lets through; "
        "for people it should be near 100 %, for boats and jetskis near 0.",
        "",
        "## Real: SeaDronesSee validation annotations",
        "",
        f"`../shared/datasets/seadronessee/instances_val.json`, boxes on frames at least "
        f"{MIN_PITCH_DEG:g} degrees below the horizon.",
        "",
        *table(real, rule),
    ]
    if sim is not None:
        lines += [
            "",
            "## Simulator: the oblique presets",
            "",
            "`maritime_oblique_low`, `_mid` and `_high` as `tools/sim_vs_real.py` renders them "
            "(figures standing up out of the water; swimmers with and without life jackets "
            "together).",
            "",
            *table(sim, rule),
        ]
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=8, help="frames per preset and world")
    parser.add_argument("--seeds", type=int, default=3, help="worlds per preset")
    parser.add_argument("--width", type=int, default=640, help="rendered image width")
    parser.add_argument("--no-sim", action="store_true", help="the real file only")
    parser.add_argument("--out", type=Path, default=OUT, help=f"written page (default {OUT})")
    args = parser.parse_args()
    from sim_vs_real import REAL, simulated_dataset

    if not REAL.is_file():
        print(f"{REAL} not found", file=sys.stderr)
        return 2
    real = box_sizes(read_coco_video(REAL))
    sim = None if args.no_sim else box_sizes(simulated_dataset(args.frames, args.seeds, args.width))
    command = "nice -n 19 python tools/size_gate.py" + (
        " --no-sim"
        if args.no_sim
        else f" --frames {args.frames} --seeds {args.seeds} --width {args.width}"
    )
    args.out.write_text(render(real, sim, command, ConfirmConfig()), encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
