"""The size gate with the head's box alone and with the object's extent against its
surroundings, per class of what the head calls a person, written to docs/object_extent.md.

Every person-class detection scored above 0.5 (the shipped head as ``sarmission eval`` runs it)
that lies on an annotated box (``class_confusion.hits``) is sized twice across the line of
sight (:func:`sarmission.geo.ground_size.apparent_size_m`): its own box, which never grows past
the head's crop, and the object under it (:func:`sarmission.perception.extent.object_extent`).
Per track, the confirmation's rule decides what the gate keeps: the median box size within
``[confirm] min_size_m``-``max_size_m``, and, once three sightings measured it, the median
extent at most ``max_extent_m`` (:mod:`sarmission.mission.confirmation`). Sightings here
are the confident detections on a box, not a flight's tracks.

Footage: the simulator's oblique presets and ``maritime_test`` at 4K (worlds no head trained
on: the presets' seeds plus 500), and clips of the held-out generator's sea and land worlds
(``tools/heldout_alerts.py``'s, rendered when missing).

    nice -n 19 python tools/object_extent_study.py [--splits validation,test] [--clips 3] \
        [--sim-frames 12] [--out docs/object_extent.md]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tools"))

from class_confusion import hits  # noqa: E402
from heldout_alerts import SPLITS, clip_path, render_clips  # noqa: E402

from sarmission.boxes import xywh_to_xyxy  # noqa: E402
from sarmission.class_roles import person_class_ids  # noqa: E402
from sarmission.data.coco_video import read_coco_video  # noqa: E402
from sarmission.data.meta_conventions import MetaPose, dataset_conventions, meta_pose  # noqa: E402
from sarmission.data.sequence import iter_sequence, sequence_ids  # noqa: E402
from sarmission.evaluation.matching import FrameBoxes  # noqa: E402
from sarmission.geo.camera import CameraIntrinsics  # noqa: E402
from sarmission.geo.ground_size import apparent_size_m  # noqa: E402
from sarmission.mission.config import ConfirmConfig  # noqa: E402
from sarmission.mission.confirmation import MIN_EXTENTS  # noqa: E402
from sarmission.mission.replay_telemetry import frame_pose  # noqa: E402
from sarmission.perception.extent import object_extent  # noqa: E402

OUT = ROOT / "docs" / "object_extent.md"
SIM_PRESETS = (
    "maritime_oblique_low",
    "maritime_oblique_mid",
    "maritime_oblique_high",
    "maritime_test",
)
#: The simulator's worlds are the presets' seeds plus this (and the world's index), as in
#: tools/class_confusion.py: worlds no head trained on.
WORLD_OFFSET = 500
SIM_FPS = 10.0
#: The simulator's presets' lens (tools/size_gate.py takes the same).
SIM_HFOV_DEG = 70.0
#: Clips rendered per held-out world, and their frames (10 s at 30 frames/s).
CLIP_FRAMES = 300
#: Classes shown as one: people with or without a life jacket, on land or at sea.
SAME_AS = {"swimmer_with_life_jacket": "person", "swimmer": "person"}


@dataclasses.dataclass
class Sized:
    """One confident person detection on an annotated box, sized."""

    track: tuple[str, int, int]
    box_m: float | None
    extent_m: float | None
    extent_ms: float


def sized_detections(path: Path, source: str, head: object) -> dict[str, list[Sized]]:
    """Per class: the ``head``'s confident person detections on that class's boxes, sized.
    Each frame is decoded once: the detector and the measurement read the same picture."""
    from sarmission.commands.detector_options import (
        DEFAULT_DS,
        DEFAULT_SCORE_THRESHOLD,
        DEFAULT_TOPN,
    )
    from sarmission.evaluation.run_model import NOMINAL_FPS
    from sarmission.perception.mitenet import MiteNet

    dataset = read_coco_video(path)
    net = MiteNet(head, ds=DEFAULT_DS, topn=DEFAULT_TOPN, score_threshold=DEFAULT_SCORE_THRESHOLD)
    people = list(person_class_ids(tuple(head.classes)))
    names = {c.id: SAME_AS.get(c.name, c.name) for c in dataset.categories}
    videos = {v.id: v for v in dataset.videos}
    conventions = dataset_conventions(dataset)
    boxes: dict[int, list] = defaultdict(list)
    for ann in dataset.annotations:
        boxes[ann.image_id].append(ann)
    out: dict[str, list[Sized]] = defaultdict(list)
    for video_id in sequence_ids(dataset):
        net.reset()
        for position, item in enumerate(iter_sequence(dataset, video_id)):
            found = net.process(item.frame_bgr, position / NOMINAL_FPS).detections
            image, anns = item.image, boxes[item.image.id]
            pose = meta_pose(image.telemetry, conventions)
            keep = np.flatnonzero((found.scores > 0.5) & np.isin(found.class_ids, people))
            if not keep.size or not anns or not isinstance(pose, MetaPose):
                continue
            platform = frame_pose(pose)
            hfov = float(videos[image.video_id].extra.get("hfov_deg", SIM_HFOV_DEG))
            lens = CameraIntrinsics.from_hfov(image.width, image.height, hfov)
            truth = xywh_to_xyxy(np.array([a.bbox for a in anns], np.float64))
            on = hits(FrameBoxes.of(found.boxes[keep], found.scores[keep]), truth)
            area = (truth[:, 2] - truth[:, 0]) * (truth[:, 3] - truth[:, 1])
            for row in np.flatnonzero(on.any(axis=1)):
                ann = anns[min(np.flatnonzero(on[row]), key=lambda j: area[j])]
                box = found.boxes[keep[row]]
                started = time.perf_counter()
                extent = object_extent(item.frame_bgr, box)
                took = (time.perf_counter() - started) * 1e3
                out[names[ann.category_id]].append(
                    Sized(
                        (source, ann.video_id, ann.track_id),
                        apparent_size_m(box, lens, platform),
                        None if extent is None else apparent_size_m(extent, lens, platform),
                        took,
                    )
                )
    return out


def kept_by_gate(sightings: list[Sized], rule: ConfirmConfig) -> tuple[bool, bool] | None:
    """Whether the confirmation's size rule keeps a track: by its box, and by box and extent;
    None when no sighting could be sized."""
    sizes = [s.box_m for s in sightings if s.box_m is not None]
    if not sizes:
        return None
    by_box = rule.min_size_m <= float(np.median(sizes)) <= rule.max_size_m
    extents = [s.extent_m for s in sightings if s.extent_m is not None]
    too_large = len(extents) >= MIN_EXTENTS and float(np.median(extents)) > rule.max_extent_m
    return by_box, by_box and not too_large


def _quantiles(values: list[float]) -> str:
    if not values:
        return "-"
    return " / ".join(f"{v:.2f}" for v in np.percentile(values, [10, 50, 90]))


def _share(flags: list[bool]) -> str:
    return f"{100 * np.mean(flags):.0f} %" if flags else "-"


def table(by_class: dict[str, list[Sized]], rule: ConfirmConfig) -> list[str]:
    lines = [
        "| class | detections | box, m: p10 / p50 / p90 | extent, m: p10 / p50 / p90 "
        "| extent measured | tracks | kept by the box | kept by box and extent |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, rows in sorted(by_class.items(), key=lambda item: -len(item[1])):
        tracks: dict[tuple, list[Sized]] = defaultdict(list)
        for row in rows:
            tracks[row.track].append(row)
        verdicts = [v for v in (kept_by_gate(t, rule) for t in tracks.values()) if v is not None]
        extents = [r.extent_m for r in rows if r.extent_m is not None]
        lines.append(
            f"| {name} | {len(rows)} | {_quantiles([r.box_m for r in rows if r.box_m])} "
            f"| {_quantiles(extents)} | {_share([r.extent_m is not None for r in rows])} "
            f"| {len(verdicts)} | {_share([v[0] for v in verdicts])} "
            f"| {_share([v[1] for v in verdicts])} |"
        )
    return lines


def simulated(frames: int, out_dir: Path) -> list[Path]:
    """The simulator's study worlds at 4K, two per preset."""
    from sim.generate import generate_sequence
    from sim.scenarios import preset

    paths = []
    for name in SIM_PRESETS:
        chosen = preset(name)
        for k in range(2):
            scenario = dataclasses.replace(
                chosen.scenario, seed=chosen.scenario.seed + WORLD_OFFSET + k
            )
            paths.append(
                generate_sequence(
                    scenario,
                    chosen.mission,
                    frames,
                    size=(3840, 2160),
                    seed=scenario.seed,
                    out_dir=out_dir,
                    fps=SIM_FPS,
                    video=False,
                    progress=False,
                    name=f"{name}_{k}",
                    start_s=5.0,
                )
            )
    return paths


def merge(into: dict[str, list[Sized]], more: dict[str, list[Sized]]) -> None:
    for name, rows in more.items():
        into[name] += rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--splits",
        type=lambda text: [part for part in text.split(",") if part],
        default=["validation"],
        help=f"held-out clip splits, comma-separated: {', '.join(sorted(SPLITS))}",
    )
    parser.add_argument("--clips", type=int, default=3, help="held-out clips per world")
    parser.add_argument("--sim-frames", type=int, default=12, help="frames per simulated world")
    parser.add_argument("--work", type=Path, default=Path("/tmp/sarmission-heldout-alerts"))
    parser.add_argument("--jobs", type=int, default=2, help="clips rendered at once")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    started = time.monotonic()
    unknown = sorted(set(args.splits) - set(SPLITS))
    if unknown or not args.splits:
        parser.error(f"--splits: expected some of {', '.join(sorted(SPLITS))}, got {unknown}")
    from sarmission.perception.mitenet import build_head_runtime

    rule = ConfirmConfig()
    head = build_head_runtime(None, "onnx")  # the shipped head, as sarmission eval runs it
    worlds = ["heldout_maritime", "heldout_land"]
    for split in args.splits:
        render_clips(args.work, worlds, SPLITS[split][0], args.clips, CLIP_FRAMES, args.jobs)
    sections: dict[str, dict[str, list[Sized]]] = {}
    timings: list[float] = []
    with tempfile.TemporaryDirectory(prefix="sarmission-extent-") as tmp:
        sim: dict[str, list[Sized]] = defaultdict(list)
        for path in simulated(args.sim_frames, Path(tmp)):
            merge(sim, sized_detections(path, path.stem, head))
            print(f"{path.stem}: done", file=sys.stderr, flush=True)
        sections["The simulator: oblique presets and maritime_test, 4K"] = sim
    for split in args.splits:
        first = SPLITS[split][0]
        for world in worlds:
            found: dict[str, list[Sized]] = defaultdict(list)
            for i in range(args.clips):
                path = clip_path(args.work, world, first + i)
                merge(found, sized_detections(path, path.parent.name, head))
                print(f"{path.parent.name}: done", file=sys.stderr, flush=True)
            last = first + args.clips - 1
            sections[f"Held-out `{world}`, {split} clips {first}-{last}"] = found
    for by_class in sections.values():
        timings += [r.extent_ms for rows in by_class.values() for r in rows]
    command = (
        f"nice -n 19 python tools/object_extent_study.py --splits {','.join(args.splits)} "
        f"--clips {args.clips} --sim-frames {args.sim_frames}"
    )
    lines = [
        "# The object under a detection, against its surroundings",
        "",
        f"Generated by `{command}` (`tools/object_extent_study.py`, "
        f"{(time.monotonic() - started) / 60:.1f} min). The head boxes what fits in its crop, "
        "never more than about 31 px, so its box alone cannot show a boat or a car it calls a "
        "person as larger than one. `sarmission.perception.extent` measures the object under "
        "the detection against the background around it; the confirmation discards a "
        f"candidate whose median extent exceeds `[confirm] max_extent_m` ({rule.max_extent_m:g} "
        "m), once three of its sightings measured it (the mission measures every third sighting of "
        "an undecided candidate; here every detection is measured), beside the box's own gate "
        f"({rule.min_size_m:g}-{rule.max_size_m:g} m). Rows: the classes the head's confident "
        "person detections (score above 0.5) lay on; sizes across the line of sight; a *track* "
        "is one annotated object of one clip, judged on its detections as the confirmation "
        "judges a candidate's sightings. *Extent measured*: the share of detections where the "
        "measurement did not refuse (mixed background, an object cut by the frame or wider than "
        "the largest window, nothing standing out). People should be kept near 100 %, boats "
        "near 0.",
        "",
    ]
    for title, by_class in sections.items():
        lines += [f"## {title}", "", *table(by_class, rule), ""]
    if timings:
        lines += [
            f"One measurement took {np.median(timings):.2f} ms (median; p90 "
            f"{np.percentile(timings, 90):.2f} ms) on this machine's CPU, shared with the "
            "detector's own work.",
            "",
        ]
    args.out.write_text("\n".join(lines), encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
