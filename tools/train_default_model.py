"""Reproduce the default MITE-Net head shipped in ``sarmission/models``.

Renders the simulator's maritime training presets (``maritime_train`` at 70 m on a calm sea,
``maritime_train_high`` at 110 m on a rough one, both 4K, and ``maritime_train_narrow``, the
demo's 960x540 view; merged into one training file) and the validation split, trains the head with
``sarmission train`` (seeded, deterministic) and writes ``mitenet_head.pt`` and
``mitenet_head.onnx`` into the package::

    python tools/train_default_model.py            # about 11 minutes on 2 CPU cores
    python tools/train_default_model.py --work /tmp/sarmission-train --epochs 30

The rendered data (several GB of 4K video) stays in ``--work``; only the two small model files
are copied into the package.
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

from sarmission.cli import main as sarmission
from sarmission.data.coco_video import read_coco_video, write_coco_video
from sarmission.models import DEFAULT_ONNX_MODEL, DEFAULT_TORCH_MODEL
from sim.generate import merge_datasets

#: The recipe of the shipped model: (preset, clips, frames per clip, frame size) and the
#: training settings.
TRAIN_SPLITS = (("maritime_train", 6, 90, "3840x2160"), ("maritime_train_high", 4, 90, "3840x2160"),
                ("maritime_train_narrow", 6, 90, "960x540"))
VAL_SPLIT = ("maritime_val", 2, 60, "3840x2160")
TRAIN_ARGS = ["--epochs", "30", "--batch-size", "64", "--lr", "0.02", "--seed", "0",
              "--frame-stride", "3", "--jitters", "4", "--ds", "1", "--select-from", "10"]


def render(folder: Path, split: tuple[str, int, int, str]) -> Path:
    """Render one split ``(preset, clips, frames, WxH)`` into ``folder`` (skipped when its
    annotation file already exists)."""
    name, clips, frames, size = split
    annotations = folder / f"{name}.json"
    if not annotations.is_file():
        code = sarmission(["sim", "generate", "--scenario", name, "--sequences", str(clips),
                           "--frames", str(frames), "--out", str(folder),
                           "--size", size])
        if code:
            sys.exit(code)
    return annotations


def render_training_set(work: Path) -> Path:
    """Render every training preset into one folder and merge their annotations there."""
    folder = work / "maritime_train_mix"
    merged = folder / "maritime_train_mix.json"
    if not merged.is_file():
        parts = [read_coco_video(render(folder, split)) for split in TRAIN_SPLITS]
        write_coco_video(merge_datasets(parts, info={"presets": [s[0] for s in TRAIN_SPLITS]}),
                         merged)
    return merged


def main() -> int:
    """Render, train, export and copy the default model into the package."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, default=Path("/tmp/sarmission-default-model"),
                        help="folder for the rendered data, crop caches and checkpoints")
    parser.add_argument("--no-install", action="store_true",
                        help="do not copy the result into sarmission/models")
    args, extra = parser.parse_known_args()
    args.work.mkdir(parents=True, exist_ok=True)
    train = render_training_set(args.work)
    val = render(args.work / VAL_SPLIT[0], VAL_SPLIT)
    out = args.work / "mitenet_head.pt"
    code = sarmission(["train", "--train", str(train), "--val", str(val), "--out", str(out),
                       "--onnx", *TRAIN_ARGS, *extra])
    if code:
        return code
    if not args.no_install:
        shutil.copyfile(out, DEFAULT_TORCH_MODEL)
        shutil.copyfile(out.with_suffix(".onnx"), DEFAULT_ONNX_MODEL)
        print(f"installed {DEFAULT_TORCH_MODEL.name} and {DEFAULT_ONNX_MODEL.name} "
              f"into {DEFAULT_TORCH_MODEL.parent}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
