"""How often a head calls each maritime class a person (and its own class), written to
docs/class_confusion.md.

Clips of the ``maritime_oblique_*`` presets (upright figures with SeaDronesSee's classes:
swimmers, boats, jetskis, buoys, life rings, and the simulator's birds, debris and glints) run
through MITE-Net with each head as ``sarmission eval`` runs it. In every frame, the person-class
detections scored above 0.5 are compared with the annotated boxes of every class (:func:`hits`:
NWD above 0.5, or the detection's centre inside the box, so that a detection on part of a boat
counts); a box counts as "called a person" when such a detection lies on it. For the swimmer
classes that is the per-box recall; for the others, how often the head mistakes them for a
person. A head that names
the object classes is also scored on calling each its own class.

    nice -n 19 python tools/class_confusion.py [--frames 15] [--width 960] \
        [--models shipped,/path/head.pt] [--crop-scales 1,2,4,8] [--presets maritime_test]

``--presets`` takes other maritime presets instead (``maritime_test``: the flat swimmers,
debris and glints the scenario suite flies among); ``--width`` renders the same worlds finer
or coarser, so a person covers more or fewer pixels.
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

from sarmission.boxes import centres_inside  # noqa: E402
from sarmission.class_roles import (  # noqa: E402
    normalise_class,
    person_class_ids,
    role_of,
)
from sarmission.commands.detector_options import (  # noqa: E402
    DEFAULT_DS,
    DEFAULT_SCORE_THRESHOLD,
    DEFAULT_TOPN,
    parse_crop_scales,
)
from sarmission.data.coco_video import VideoDataset, read_coco_video  # noqa: E402
from sarmission.evaluation.matching import FrameBoxes, nwd_matrix  # noqa: E402
from sarmission.evaluation.report import people_only  # noqa: E402

OUT = ROOT / "docs" / "class_confusion.md"
PRESETS = ("maritime_oblique_low", "maritime_oblique_mid", "maritime_oblique_high")
FPS = 10.0
#: World seeds are the preset's plus this (and the world's index): the presets' own seeds train
#: heads (tools/train_default_model.py renders maritime_oblique_mid and _high from theirs).
WORLD_OFFSET = 500


def hits(detections: FrameBoxes, truth: np.ndarray) -> np.ndarray:
    """``[D, G]``: detection d (scored above 0.5) lies on box g: NWD above 0.5 (the search
    metrics' match), or its centre inside the box (a detection on part of a boat or of a buoy's
    top mark, which NWD cannot match for the sizes differ)."""
    keep = detections.scores > 0.5
    boxes = detections.boxes[keep]
    if not len(boxes) or not len(truth):
        return np.zeros((len(boxes), len(truth)), bool)
    return centres_inside(boxes, truth) | (nwd_matrix(boxes, truth) > 0.5)


def count_calls(
    dataset: VideoDataset, detections: dict[int, FrameBoxes], classes: tuple[str, ...]
) -> tuple[Counter, Counter, Counter, int]:
    """(boxes per class, boxes called a person per class, boxes called their own class, person
    detections on no box)."""
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
        labels = [names[a.category_id] for a in anns]
        boxes.update(labels)
        truth = np.array(
            [[a.bbox[0], a.bbox[1], a.bbox[0] + a.bbox[2], a.bbox[1] + a.bbox[3]] for a in anns]
        ).reshape(-1, 4)
        on = hits(people_only(found, people), truth)
        called.update(labels[g] for g in np.flatnonzero(on.any(axis=0)))
        unmatched += int(np.sum(~on.any(axis=1)))
        for class_id, class_name in enumerate(classes):
            if role_of(class_name) == "person":
                continue
            mine = hits(people_only(found, np.array([class_id])), truth).any(axis=0)
            own[class_name] += sum(
                1 for g in np.flatnonzero(mine) if normalise_class(labels[g]) == class_name
            )
    return boxes, called, own, unmatched


def _table(
    models: list[str],
    classes: list[str],
    boxes: Counter,
    count,
    unmatched: dict | None,
    frames: int,
) -> list[str]:
    """One row per head, one column per class: ``count(head, class)`` as a share of the class's
    boxes; with ``unmatched``, a last column of person detections on no box."""
    head = "| head | " + " | ".join(f"{n} ({boxes[n]})" for n in classes)
    rule = "|---|" + "---|" * len(classes)
    if unmatched is not None:
        head += " | person detections on no box, per frame"
        rule += "---|"
    rows = [head + " |", rule]
    for m in models:
        cells = [f"{100 * count(m, n) / boxes[n]:.1f} %" for n in classes]
        if unmatched is not None:
            cells.append(f"{unmatched[m] / max(frames, 1):.2f}")
        rows.append(f"| {m} | " + " | ".join(cells) + " |")
    return rows


def parse_models(text: str) -> dict[str, str]:
    """``shipped,name=path,...`` -> label -> model (``shipped`` or a checkpoint path; a path
    without ``name=`` is labelled by its file name)."""
    models = {}
    for item in (t.strip() for t in text.split(",") if t.strip()):
        label, _, path = item.rpartition("=")
        models[label or ("shipped" if path == "shipped" else Path(path).stem)] = path
    return models


def parse_presets(text: str) -> tuple[str, ...]:
    """Comma-separated simulator preset names (argparse type), at least one; an unknown name
    gets :func:`sim.scenarios.preset`'s own message."""
    from sim.scenarios import preset

    names = tuple(n.strip() for n in text.split(",") if n.strip())
    if not names:
        raise argparse.ArgumentTypeError("no preset: none given")
    for name in names:
        try:
            preset(name)
        except ValueError as error:
            raise argparse.ArgumentTypeError(str(error)) from None
    return names


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=15, help="frames per preset and world")
    parser.add_argument("--seeds", type=int, default=3, help="worlds per preset")
    parser.add_argument("--width", type=int, default=960, help="rendered image width")
    parser.add_argument(
        "--presets",
        type=parse_presets,
        default=PRESETS,
        help=f"comma-separated simulator presets (default: {','.join(PRESETS)})",
    )
    parser.add_argument(
        "--models",
        default="shipped",
        help="comma-separated heads: 'shipped' or checkpoint paths (default: shipped)",
    )
    parser.add_argument(
        "--crop-scales",
        type=parse_crop_scales,
        default=None,
        help="the detector's crop scales, comma-separated multiples of S (default: its own)",
    )
    parser.add_argument("--note", default="", help="a paragraph on the heads, printed first")
    parser.add_argument("--out", type=Path, default=OUT, help="Markdown file to write")
    args = parser.parse_args()
    from sarmission.evaluation.run_model import run_mitenet
    from sarmission.perception.mitenet import MiteNet, build_head_runtime
    from sarmission.perception.types import DEFAULT_CROP_SCALES
    from sim.generate import generate_sequence
    from sim.scenarios import preset

    started = time.monotonic()
    scales = args.crop_scales or DEFAULT_CROP_SCALES
    paths = parse_models(args.models)
    models = list(paths)
    heads = {
        m: build_head_runtime(
            None if path == "shipped" else path, "onnx" if path == "shipped" else "torch"
        )
        for m, path in paths.items()
    }
    boxes = Counter()
    called = {m: Counter() for m in models}
    own = {m: Counter() for m in models}
    unmatched = dict.fromkeys(models, 0)
    frames = 0
    for name, k in ((n, k) for n in args.presets for k in range(args.seeds)):
        chosen = preset(name)
        scenario = dataclasses.replace(
            chosen.scenario, seed=chosen.scenario.seed + WORLD_OFFSET + k
        )
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
                    head,
                    ds=DEFAULT_DS,
                    topn=DEFAULT_TOPN,
                    score_threshold=DEFAULT_SCORE_THRESHOLD,
                    crop_scales=scales,
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
        + (f" --crop-scales {','.join(f'{v:g}' for v in scales)}" if args.crop_scales else "")
        + (f" --presets {','.join(args.presets)}" if args.presets != PRESETS else "")
    )
    lines = [
        "# Which classes the head calls a person",
        "",
        f"Generated by `{command}` (`tools/class_confusion.py`, "
        f"{(time.monotonic() - started) / 60:.1f} min): {frames} frames of "
        f"{', '.join(f'`{p}`' for p in args.presets)} ({args.seeds} worlds each, seeds "
        f"the preset's plus {WORLD_OFFSET} and on: worlds no head trained on) at "
        f"{args.width} px wide, {FPS:g} frames per second from 5 s into each "
        "flight, each head as `sarmission eval` runs it. A box is called a person when a "
        "detection of a person class (swimmer, swimmer with life jacket), scored above 0.5, lies "
        "on it: NWD above 0.5 (the search metrics' match), or its centre inside the box (a "
        "detection on part of a boat, a person on its deck, a buoy's top mark); it is called "
        "its own class when a detection of that class lies on it (heads that name boats, "
        "jetskis, buoys and life-saving appliances). Detections on no box lie on open water, "
        "wakes or foam.",
        "",
        *([args.note, ""] if args.note else []),
        "Share of each class's boxes called a person (boxes per class in the header):",
        "",
    ]
    order = sorted(boxes, key=lambda n: -boxes[n])
    lines += _table(models, order, boxes, lambda m, n: called[m][n], unmatched, frames)
    naming = [m for m in models if any(role_of(c) != "person" for c in heads[m].classes)]
    named = {normalise_class(c) for m in naming for c in heads[m].classes}
    objects = [n for n in order if role_of(n) != "person" and normalise_class(n) in named]
    if naming:
        lines += [
            "",
            "Share of each class's boxes called its own class by the heads that name it:",
            "",
        ]
        lines += _table(
            naming, objects, boxes, lambda m, n: own[m][normalise_class(n)], None, frames
        )
    lines.append("")
    args.out.write_text("\n".join(lines), encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
