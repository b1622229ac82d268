"""Would a closer look tell a person from a boat, a buoy, a life ring or debris? -> docs.

The head classifies a 16-px crop of each proposal's box. This study asks whether a second,
separate classifier that sees more, a crop of three times the box (at least 24 px of the frame)
resized to 32 px, could tell the classes apart where the head cannot (docs/class_confusion.md):
as a check on a candidate before it becomes an alert, or to give boats, buoys and life rings
their own kind of alert. It trains a small CNN (:class:`ContextNet`, about 70 k parameters) on
crops around the annotated boxes of the simulator's maritime training presets (world seeds
:data:`TRAIN_OFFSET` on, so no world the head or the tests use) and of open water, with the
classes of :data:`GROUP` balanced per batch, and tests it on

* unseen simulator worlds (the oblique presets and ``maritime_test`` at seeds
  :data:`TEST_OFFSET` on, as tools/class_confusion.py uses them), and
* the held-out generator's validation clips (:mod:`heldout`, clip index
  :data:`HELDOUT_FIRST_CLIP` on; its people, buoys, boats, debris and birds).

Figures: per true class, the share of its boxes the classifier calls a person (probability
above 0.5) and the share it calls its own class, for each training seed::

    python tools/closer_look_study.py [--seeds 0,1,2] [--work /tmp/closer]
    python tools/closer_look_study.py --from-json /tmp/closer/closer_look.json

Two variants are trained side by side: ``plain`` and ``randomised`` (the head's photometric
domain randomisation, :mod:`sarmission.training.randomise`, on top). The measured numbers go to
``<work>/closer_look.json``; the Markdown (docs/closer_look.md) is a pure function of it.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sarmission.class_roles import normalise_class  # noqa: E402

DOC = ROOT / "docs" / "closer_look.md"
#: The classifier's classes: what a search must tell apart, and open water.
CLASSES: tuple[str, ...] = ("person", "boat", "buoy", "life_ring", "clutter", "water")
#: Annotated class (normalised) -> the classifier's class; others are left out.
GROUP: dict[str, str] = {
    "swimmer": "person",
    "swimmer_with_life_jacket": "person",
    "person": "person",
    "boat": "boat",
    "jetski": "boat",
    "buoy": "buoy",
    "life_saving_appliances": "life_ring",
    "debris": "clutter",
    "bird": "clutter",
    "sun_glint": "clutter",
    "rock": "clutter",
    "log": "clutter",
    "animal": "clutter",
}
#: Side of the classifier's input, and the window cut around a box of side s:
#: ``max(CONTEXT * s, MIN_WINDOW)`` full-resolution pixels.
CROP = 32
CONTEXT = 3.0
MIN_WINDOW = 24
TRAIN_PRESETS = (
    "maritime_objects_train",
    "maritime_oblique_low",
    "maritime_oblique_mid",
    "maritime_oblique_high",
    "maritime_train",
    "maritime_train_high",
)
TEST_PRESETS = (
    "maritime_oblique_low",
    "maritime_oblique_mid",
    "maritime_oblique_high",
    "maritime_test",
)
#: World seeds: the preset's plus these and the world's index.
TRAIN_OFFSET = 100
TEST_OFFSET = 500
#: ``--altworld``: clips of the alternative training world's sea (:mod:`altworld`; its people,
#: boats, buoys, life rings, debris and gulls) added to the training crops, every
#: :data:`VIDEO_STRIDE`-th frame.
ALTWORLD_SEA = (12, 72)
VIDEO_STRIDE = 12
HELDOUT_WORLDS = ("heldout_maritime", "heldout_maritime_empty")
HELDOUT_FIRST_CLIP = 150
PARTS = ("sim_test", "heldout_val")


def group_of(name: str) -> str | None:
    """The classifier's class of an annotated class name, None when it has none."""
    return GROUP.get(normalise_class(name))


def cut_context_crop(image: np.ndarray, cx: float, cy: float, side: float) -> np.ndarray:
    """The ``CROP`` x ``CROP`` view of a window of ``max(CONTEXT * side, MIN_WINDOW)`` pixels
    centred on ``(cx, cy)``; beyond the frame the image is mirrored."""
    import cv2

    window = max(1, int(round(max(CONTEXT * side, MIN_WINDOW))))
    x0 = int(round(cx - window / 2))
    y0 = int(round(cy - window / 2))
    pad = window + 2
    padded = cv2.copyMakeBorder(image, pad, pad, pad, pad, cv2.BORDER_REFLECT)
    x0 = min(max(x0 + pad, 0), padded.shape[1] - window)
    y0 = min(max(y0 + pad, 0), padded.shape[0] - window)
    view = padded[y0 : y0 + window, x0 : x0 + window]
    return cv2.resize(view, (CROP, CROP), interpolation=cv2.INTER_AREA)


def _frames(path: Path) -> Any:
    """``(BGR frame, [(class name, box)])`` of each readable frame of a COCO-video file rendered
    as JPEG folders, or of every :data:`VIDEO_STRIDE`-th frame of its videos when its videos
    name a video file (consecutive video frames are near copies)."""
    import cv2

    from sarmission.data.coco_video import read_coco_video
    from sarmission.data.sequence import iter_sequence, video_file

    dataset = read_coco_video(path)
    names = {c.id: c.name for c in dataset.categories}
    by_image = dataset.annotations_by_image()

    def boxes(image_id: int) -> list[tuple[str, list[float]]]:
        return [(names[a.category_id], a.bbox) for a in by_image.get(image_id, [])]

    videos = [v.id for v in dataset.videos if video_file(dataset, v.id) is not None]
    if videos:
        for video_id in videos:
            for k, item in enumerate(iter_sequence(dataset, video_id)):
                if k % VIDEO_STRIDE == 0:
                    yield item.frame_bgr, boxes(item.image.id)
        return
    for image in dataset.images:
        frame = cv2.imread(str(path.parent / image.file_name))
        if frame is not None:
            yield frame, boxes(image.id)


def _clear_of(boxes: Sequence[Sequence[float]], cx: float, cy: float, side: float) -> bool:
    """Whether a window of ``CONTEXT * side`` around ``(cx, cy)`` misses every box."""
    reach = CONTEXT * side / 2
    return all(
        abs(cx - (x + w / 2)) > w / 2 + reach or abs(cy - (y + h / 2)) > h / 2 + reach
        for x, y, w, h in boxes
    )


def box_crops(
    path: Path, rng: np.random.Generator, per_box: int, water_per_frame: int, jitter: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Crops around every annotated box of a class in :data:`GROUP` (``per_box`` each, moved
    by up to a quarter of the box and scaled by 0.7-1.4 when ``jitter``, as a detection's box
    is off) and of open water away from every box; ``(crops [N, CROP, CROP, 3] uint8, class
    index [N])``."""
    crops: list[np.ndarray] = []
    labels: list[int] = []
    for frame, annotated in _frames(path):
        boxes = [box for _, box in annotated]
        for name, (x, y, w, h) in annotated:
            group = group_of(name)
            if group is None or min(w, h) < 2:
                continue
            side = max(w, h)
            for _ in range(per_box):
                scale, dx, dy = 1.0, 0.0, 0.0
                if jitter:
                    scale = rng.uniform(0.7, 1.4)
                    dx, dy = rng.uniform(-0.25, 0.25, 2) * side
                crops.append(cut_context_crop(frame, x + w / 2 + dx, y + h / 2 + dy, side * scale))
                labels.append(CLASSES.index(group))
        height, width = frame.shape[:2]
        found = 0
        for _ in range(10 * water_per_frame):
            if found == water_per_frame:
                break
            side = float(np.exp(rng.uniform(np.log(6.0), np.log(40.0))))
            cx, cy = rng.uniform(0, width), rng.uniform(0, height)
            if _clear_of(boxes, cx, cy, side):
                crops.append(cut_context_crop(frame, cx, cy, side))
                labels.append(CLASSES.index("water"))
                found += 1
    if not crops:
        return np.zeros((0, CROP, CROP, 3), np.uint8), np.zeros(0, np.int64)
    return np.stack(crops), np.array(labels, np.int64)


def render(work: Path, frames: int) -> dict[str, list[Path]]:
    """Render the training and test worlds into ``work`` (kept and reused); part -> files."""
    from heldout.generate import render_world
    from sim.generate import generate_sequence
    from sim.scenarios import preset

    jobs = [("train", n, TRAIN_OFFSET + k, frames) for n in TRAIN_PRESETS for k in range(3)]
    jobs += [
        ("sim_test", n, TEST_OFFSET + k, frames * 2 // 3) for n in TEST_PRESETS for k in (0, 1)
    ]
    parts: dict[str, list[Path]] = {"train": [], "sim_test": [], "heldout_val": []}
    for part, name, offset, count in jobs:
        chosen = preset(name)
        scenario = dataclasses.replace(chosen.scenario, seed=chosen.scenario.seed + offset)
        out = work / part / f"{name}_{offset}"
        found = sorted(out.glob("*.json"))
        if not found:
            out.mkdir(parents=True, exist_ok=True)
            found = [
                generate_sequence(
                    scenario,
                    chosen.mission,
                    count,
                    size=(3840, 2160),
                    seed=scenario.seed,
                    out_dir=out,
                    fps=1.0,
                    video=False,
                    progress=False,
                    name=name,
                    start_s=5.0,
                )
            ]
        parts[part] += found
    for name in HELDOUT_WORLDS:
        out = work / "heldout_val" / name
        path = out / f"{name}.json"
        if not path.is_file():
            path = render_world(
                name, 4, frames * 5 // 3, out, fps=2.0, images=True, first_clip=HELDOUT_FIRST_CLIP
            )
        parts["heldout_val"].append(path)
    return parts


def render_altworld(work: Path) -> Path:
    """The alternative world's sea clips (:data:`ALTWORLD_SEA`) in ``work/altworld`` (kept and
    reused); their annotation file."""
    from altworld.generate import render_world as render_alt

    path = work / "altworld" / "altworld_sea.json"
    if not path.is_file():
        render_alt("sea", *ALTWORLD_SEA, path.parent)
    return path


def context_net() -> Any:
    """A small CNN over a ``CROP``-px colour crop -> one logit per class of :data:`CLASSES`."""
    import torch.nn as nn

    def block(cin: int, cout: int) -> nn.Module:
        return nn.Sequential(
            nn.Conv2d(cin, cout, 3, padding=1, bias=False), nn.BatchNorm2d(cout), nn.ReLU()
        )

    return nn.Sequential(
        block(3, 16),
        block(16, 16),
        nn.MaxPool2d(2),
        block(16, 32),
        block(32, 32),
        nn.MaxPool2d(2),
        block(32, 64),
        block(64, 64),
        nn.MaxPool2d(2),
        block(64, 64),
        nn.AdaptiveAvgPool2d(1),
        nn.Flatten(),
        nn.Linear(64, len(CLASSES)),
    )


def _as_tensor(crops: np.ndarray) -> Any:
    import torch

    return torch.from_numpy(crops).permute(0, 3, 1, 2).float() / 255.0


def _augment(batch: Any, rng: np.random.Generator, randomise: bool) -> Any:
    """A quarter turn, a mirror, tone and colour gains, sensor noise; with ``randomise`` the
    head's photometric randomisation too (each transform on half the crops)."""
    import torch

    from sarmission.training import randomise as transforms

    n = batch.shape[0]
    batch = torch.rot90(batch, int(rng.integers(4)), (2, 3))
    if rng.random() < 0.5:
        batch = batch.flip(3)
    gain = torch.from_numpy(np.exp(rng.uniform(-0.2, 0.2, (n, 3, 1, 1)))).float()
    mean = batch.mean((1, 2, 3), keepdim=True)
    contrast = torch.from_numpy(np.exp(rng.uniform(-0.3, 0.3, (n, 1, 1, 1)))).float()
    batch = ((batch - mean) * contrast + mean) * gain
    sigma = torch.from_numpy(rng.uniform(0, 0.04, (n, 1, 1, 1))).float()
    batch = (batch + torch.from_numpy(rng.standard_normal(batch.shape)).float() * sigma).clamp(0, 1)
    if randomise:
        for name in ("tone", "white_balance", "hue", "blur", "noise", "blocks"):
            chosen = torch.from_numpy(rng.random(n) < 0.5)
            if chosen.any():
                changed = getattr(transforms, name)(batch[chosen].contiguous(), rng)
                batch[chosen] = changed.clamp(0, 1)
    return batch


def train_classifier(
    crops: np.ndarray, labels: np.ndarray, seed: int, epochs: int, randomise: bool
) -> Any:
    """Train :func:`context_net` with every class equally likely per batch (AdamW, one-cycle
    learning rate, label smoothing 0.05); seeded."""
    import torch
    import torch.nn.functional as F

    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    net = context_net()
    counts = np.bincount(labels, minlength=len(CLASSES)).astype(float)
    weights = 1.0 / np.maximum(counts[labels], 1.0)
    weights /= weights.sum()
    batch_size = 128
    steps = max(1, epochs * len(labels) // batch_size)
    optimiser = torch.optim.AdamW(net.parameters(), 2e-3, weight_decay=1e-3)
    schedule = torch.optim.lr_scheduler.OneCycleLR(optimiser, 2e-3, total_steps=steps)
    inputs, targets = _as_tensor(crops), torch.from_numpy(labels)
    net.train()
    for _ in range(steps):
        index = torch.from_numpy(rng.choice(len(labels), batch_size, p=weights))
        loss = F.cross_entropy(
            net(_augment(inputs[index], rng, randomise)), targets[index], label_smoothing=0.05
        )
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        schedule.step()
    return net.eval()


def class_probabilities(net: Any, crops: np.ndarray) -> np.ndarray:
    """Softmax over :data:`CLASSES` per crop."""
    import torch

    with torch.no_grad():
        return (
            np.concatenate(
                [
                    torch.softmax(net(_as_tensor(crops[i : i + 1024])), 1).numpy()
                    for i in range(0, len(crops), 1024)
                ]
            )
            if len(crops)
            else np.zeros((0, len(CLASSES)))
        )


def per_class_calls(probabilities: np.ndarray, labels: np.ndarray) -> dict[str, dict[str, float]]:
    """Per true class present: boxes, share called a person (probability above 0.5) and share
    called its own class (the most probable)."""
    person = CLASSES.index("person")
    out: dict[str, dict[str, float]] = {}
    for index, name in enumerate(CLASSES):
        mine = labels == index
        if not mine.any():
            continue
        p = probabilities[mine]
        out[name] = {
            "boxes": int(mine.sum()),
            "called_person": float((p[:, person] > 0.5).mean()),
            "own_class": float((p.argmax(1) == index).mean()),
        }
    return out


def _mean_range(values: Sequence[float]) -> str:
    return f"{100 * np.mean(values):.0f} % ({100 * min(values):.0f}-{100 * max(values):.0f})"


def render_markdown(results: Mapping[str, Any]) -> str:
    """docs/closer_look.md from the results JSON (pure)."""
    lines = [
        "# A closer look: a classifier on three times the box",
        "",
        f"Generated by `{results['command']}` (`tools/closer_look_study.py`, "
        f"{results['minutes']:.1f} min; its docstring says what is trained and tested). "
        f"Training: {results['train_boxes']} crops of {len(TRAIN_PRESETS)} simulator presets, "
        "three worlds each"
        + (
            f"; the `+ altworld` variants add {results['altworld_boxes']} crops of the "
            f"alternative training world's sea (`altworld/`, {ALTWORLD_SEA[0]} clips, every "
            f"{VIDEO_STRIDE}th frame; docs/altworld.md)"
            if results.get("altworld_boxes")
            else ""
        )
        + ". Each cell: mean over the training seeds "
        f"({', '.join(str(s) for s in results['seeds'])}), their range in brackets; boxes per "
        "class in the header.",
    ]
    variants = results["variants"]
    for part, title in (
        ("sim_test", "Unseen simulator worlds"),
        ("heldout_val", "Held-out generator, validation clips"),
    ):
        any_run = next(iter(next(iter(variants.values())).values()))[part]
        classes = [c for c in CLASSES if c in any_run]
        header = " | ".join(f"{c} ({any_run[c]['boxes']})" for c in classes)
        for measure, what in (
            ("called_person", "called a person"),
            ("own_class", "called its own class"),
        ):
            lines += [
                "",
                f"### {title}: share of each class's boxes {what}",
                "",
                f"| variant | {header} |",
                "|---|" + "---|" * len(classes),
            ]
            for variant, runs in variants.items():
                cells = [_mean_range([r[part][c][measure] for r in runs.values()]) for c in classes]
                lines.append(f"| {variant} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, default=Path("/tmp/closer"))
    parser.add_argument("--seeds", default="0,1,2", help="training seeds (default: 0,1,2)")
    parser.add_argument("--epochs", type=int, default=12)
    parser.add_argument("--frames", type=int, default=12, help="frames per training world")
    parser.add_argument("--from-json", type=Path, default=None)
    parser.add_argument("--doc", type=Path, default=DOC)
    parser.add_argument(
        "--altworld",
        action="store_true",
        help="also train both variants with the alternative world's sea clips added",
    )
    args = parser.parse_args(argv)
    if args.from_json:
        results = json.loads(args.from_json.read_text())
    else:
        import torch

        torch.set_num_threads(2)
        started = time.monotonic()
        args.work.mkdir(parents=True, exist_ok=True)
        files = render(args.work, args.frames)
        rng = np.random.default_rng(0)
        data = {}
        for part, per_box, jitter in (("train", 3, True), ("sim_test", 1, False)):
            data[part] = _stack([box_crops(f, rng, per_box, 6, jitter) for f in files[part]])
        data["heldout_val"] = _stack([box_crops(f, rng, 1, 6, False) for f in files["heldout_val"]])
        runs = [("plain", False, data["train"]), ("randomised", True, data["train"])]
        extra_boxes = 0
        if args.altworld:
            alt = box_crops(render_altworld(args.work), rng, 3, 6, True)
            extra_boxes = len(alt[1])
            both = _stack([data["train"], alt])
            runs += [("plain + altworld", False, both), ("randomised + altworld", True, both)]
        seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
        variants: dict[str, dict[str, Any]] = {}
        for variant, randomise, train in runs:
            variants[variant] = {}
            for seed in seeds:
                net = train_classifier(*train, seed, args.epochs, randomise)
                variants[variant][str(seed)] = {
                    part: per_class_calls(class_probabilities(net, data[part][0]), data[part][1])
                    for part in PARTS
                }
                print(f"{variant} seed {seed}: {variants[variant][str(seed)]}", file=sys.stderr)
        results = {
            "command": "python tools/closer_look_study.py"
            + (f" --seeds {args.seeds}" if args.seeds != "0,1,2" else "")
            + (" --altworld" if args.altworld else ""),
            "altworld_boxes": extra_boxes,
            "minutes": (time.monotonic() - started) / 60,
            "seeds": seeds,
            "train_boxes": int(len(data["train"][1])),
            "variants": variants,
        }
        out = args.work / "closer_look.json"
        out.write_text(json.dumps(results, indent=1))
        print(f"wrote {out}", file=sys.stderr)
    args.doc.write_text(render_markdown(results))
    print(f"wrote {args.doc}", file=sys.stderr)
    return 0


def _stack(pairs: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    return np.concatenate([p[0] for p in pairs]), np.concatenate([p[1] for p in pairs])


if __name__ == "__main__":
    sys.exit(main())
