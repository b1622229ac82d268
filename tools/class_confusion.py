"""How often a head calls each maritime class a person (and its own class), written to
docs/class_confusion.md.

Clips of the ``maritime_oblique_*`` presets (upright figures with SeaDronesSee's classes:
swimmers, boats, jetskis, buoys, life rings, and the simulator's birds, debris and glints) run
through MITE-Net with each head as ``sarmission eval`` runs it. In every frame, the person-class
detections (score above the threshold) are matched one-to-one to all annotated boxes of every
class at once (:func:`sarmission.evaluation.matching.match_frame`, NWD above 0.5); a box counts
as "called a person" when a detection is matched to it. For the swimmer classes that is the
per-box recall; for the others, how often the head mistakes them for a person. A head that names
the object classes is also scored on calling each its own class.

    nice -n 19 python tools/class_confusion.py [--frames 15] [--width 960] \
        [--models shipped,/path/head.pt]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sarmission.class_roles import (  # noqa: E402
    normalise_class,
    person_class_ids,
    role_of,
)
from sarmission.data.coco_video import VideoDataset, read_coco_video  # noqa: E402
from sarmission.evaluation.matching import FrameBoxes, match_frame  # noqa: E402
from sarmission.evaluation.report import people_only  # noqa: E402

OUT = ROOT / "docs" / "class_confusion.md"
PRESETS = ("maritime_oblique_low", "maritime_oblique_mid", "maritime_oblique_high")
FPS = 10.0


def count_calls(
    dataset: VideoDataset, detections: dict[int, FrameBoxes], classes: tuple[str, ...]
) -> tuple[Counter, Counter, Counter, int]:
    """(boxes per class, boxes called a person per class, boxes called their own class, person
    detections matched to nothing)."""
    names = {c.id: c.name for c in dataset.categories}
    people = person_class_ids(classes)
    boxes, called, own = Counter(), Counter(), Counter()
    unmatched = 0
    by_image = dataset.annotations_by_image()
    for image in dataset.images:
        found = detections.get(image.id)
        if found is None:
            continue
        anns = by_image.get(image.id, [])
        for a in anns:
            boxes[names[a.category_id]] += 1
        xyxy = np.array(
            [[a.bbox[0], a.bbox[1], a.bbox[0] + a.bbox[2], a.bbox[1] + a.bbox[3]] for a in anns]
        ).reshape(-1, 4)
        truth = FrameBoxes.of(xyxy)
        person = people_only(found, people)
        match = match_frame(person, truth)
        for gt_index in match.gt_indices:
            called[names[anns[gt_index].category_id]] += 1
        unmatched += int(np.sum(person.scores > 0.5)) - len(match.gt_indices)
        for class_id, class_name in enumerate(classes):
            if role_of(class_name) == "person":
                continue
            mine = people_only(found, np.array([class_id]))
            for gt_index in match_frame(mine, truth).gt_indices:
                if normalise_class(names[anns[gt_index].category_id]) == class_name:
                    own[class_name] += 1
    return boxes, called, own, unmatched


def head_label(model: str) -> str:
    """``shipped`` or the checkpoint's file name."""
    return "shipped" if model == "shipped" else Path(model).stem


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=15, help="frames per preset and world")
    parser.add_argument("--seeds", type=int, default=3, help="worlds per preset")
    parser.add_argument("--width", type=int, default=960, help="rendered image width")
    parser.add_argument(
        "--models",
        default="shipped",
        help="comma-separated heads: 'shipped' or checkpoint paths (default: shipped)",
    )
    parser.add_argument("--out", type=Path, default=OUT, help="Markdown file to write")
    args = parser.parse_args()
    from sarmission.commands.detector_options import (
        DEFAULT_DS,
        DEFAULT_SCORE_THRESHOLD,
        DEFAULT_TOPN,
    )
    from sarmission.evaluation.run_model import run_mitenet
    from sarmission.perception.mitenet import MiteNet, build_head_runtime
    from sim.generate import generate_sequence
    from sim.scenarios import preset

    started = time.monotonic()
    models = [m.strip() for m in args.models.split(",") if m.strip()]
    heads = {
        m: build_head_runtime(None if m == "shipped" else m, "onnx" if m == "shipped" else "torch")
        for m in models
    }
    boxes = Counter()
    called = {m: Counter() for m in models}
    own = {m: Counter() for m in models}
    unmatched = dict.fromkeys(models, 0)
    frames = 0
    for name, k in ((n, k) for n in PRESETS for k in range(args.seeds)):
        chosen = preset(name)
        scenario = dataclasses.replace(chosen.scenario, seed=chosen.scenario.seed + k)
        with tempfile.TemporaryDirectory() as tmp:
            path = generate_sequence(
                scenario,
                chosen.mission,
                args.frames,
                size=(args.width, args.width * 9 // 16),
                seed=scenario.seed,
                out_dir=tmp,
                fps=FPS,
                video=False,
                progress=False,
                name=name,
                start_s=5.0,
            )
            dataset = read_coco_video(path)
            for m, head in heads.items():
                net = MiteNet(
                    head, ds=DEFAULT_DS, topn=DEFAULT_TOPN, score_threshold=DEFAULT_SCORE_THRESHOLD
                )
                run = run_mitenet(net, dataset, progress=False)
                b, c, o, u = count_calls(dataset, run.detections, tuple(head.classes))
                called[m] += c
                own[m] += o
                unmatched[m] += u
        boxes += b
        frames += len(run.frame_ms)
        print(f"{name} world {k}: done", file=sys.stderr)
    command = (
        f"nice -n 19 python tools/class_confusion.py --frames {args.frames} "
        f"--seeds {args.seeds} --width {args.width}"
        + (f" --models {args.models}" if args.models != "shipped" else "")
    )
    labels = [head_label(m) for m in models]
    lines = [
        "# Which classes the head calls a person",
        "",
        f"Generated by `{command}` (`tools/class_confusion.py`, "
        f"{(time.monotonic() - started) / 60:.1f} min): {frames} frames of "
        f"{', '.join(f'`{p}`' for p in PRESETS)} ({args.seeds} worlds each: the preset's seed "
        f"and the next) at {args.width} px wide, {FPS:g} frames per second from 5 s into each "
        "flight, each head as `sarmission eval` runs it. A box is called a person when a "
        "detection of a person class (swimmer, swimmer with life jacket), scored above 0.5, is "
        "matched to it (one-to-one over the boxes of all classes, NWD above 0.5); it is called "
        "its own class when a detection of that class is (heads that name boats, jetskis, "
        "buoys and life-saving appliances). NWD matching needs similar sizes, so a detection "
        "on part of a large object (a person on a boat's deck, a buoy's top mark) matches no "
        "box and counts below as matched to none.",
        "",
        "| class | boxes | "
        + " | ".join(f"{lab}: called a person | {lab}: own class" for lab in labels)
        + " |",
        "|---|---|" + "---|---|" * len(labels),
    ]
    for name in sorted(boxes, key=lambda n: -boxes[n]):
        cells = []
        for m in models:
            share = 100 * called[m][name] / boxes[name]
            key = normalise_class(name)
            named = key in {normalise_class(c) for c in heads[m].classes}
            mine = (
                f"{100 * own[m][key] / boxes[name]:.1f} %"
                if named and role_of(name) != "person"
                else "-"
            )
            cells += [f"{called[m][name]} ({share:.1f} %)", mine]
        lines.append(f"| {name} | {boxes[name]} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "Person detections matched to no box (open water, wakes, foam): "
        + ", ".join(
            f"{head_label(m)} {unmatched[m]} ({unmatched[m] / max(frames, 1):.2f} per frame)"
            for m in models
        )
        + ".",
        "",
    ]
    args.out.write_text("\n".join(lines), encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
