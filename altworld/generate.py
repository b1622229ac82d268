"""Render clips of the alternative world into a COCO video annotation file.

    python -m altworld.generate --world sea --clips 10 --frames 72 --out DIR

writes ``DIR/altworld_<world>_<i>.mp4`` and ``DIR/altworld_<world>.json`` (the layout ``sarmission
train`` reads; people on land are ``person``). Clip ``i`` is rendered from seed ``first_seed + i``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from altworld.clip import FPS, HEIGHT, WIDTH, render_clip

#: COCO categories, fixed ids.
CATEGORIES = (
    "swimmer", "swimmer_with_life_jacket", "person", "boat", "bird", "debris", "buoy",
    "life_saving_appliances", "animal",
)  # fmt: skip
#: Default first seed per world: used by no other renderer.
FIRST_SEEDS = {"sea": 9_310_000, "land": 9_320_000}


def render_world(
    world: str, clips: int, frames: int, out: Path, first_seed: int | None = None, log=print
) -> Path:
    """Render ``clips`` clips of ``frames`` frames into ``out``; the annotation file's path."""
    if world not in FIRST_SEEDS:
        raise ValueError(f"unknown world {world!r}: choose from {', '.join(FIRST_SEEDS)}")
    if clips < 1 or frames < 1:
        raise ValueError("--clips and --frames must be at least 1")
    out.mkdir(parents=True, exist_ok=True)
    seed0 = FIRST_SEEDS[world] if first_seed is None else first_seed
    category_id = {name: i + 1 for i, name in enumerate(CATEGORIES)}
    data: dict = {
        "info": {"generator": "altworld", "world": world, "first_seed": seed0},
        "videos": [],
        "images": [],
        "annotations": [],
        "categories": [
            {"id": i, "name": n, "supercategory": "object"} for n, i in category_id.items()
        ],
    }
    for clip in range(clips):
        name = f"altworld_{world}_{clip:02d}"
        started = time.monotonic()
        images, boxes = render_clip(seed0 + clip, world, frames, out / f"{name}.mp4")
        video_id = clip + 1
        data["videos"].append(
            {
                "id": video_id,
                "name": name,
                "width": WIDTH,
                "height": HEIGHT,
                "fps": FPS,
                "file_name": f"{name}.mp4",
            }
        )
        first_image = len(data["images"]) + 1
        for im in images:
            data["images"].append(
                {
                    "id": first_image + im["frame_index"],
                    "file_name": im["file_name"],
                    "height": HEIGHT,
                    "width": WIDTH,
                    "video_id": video_id,
                    "frame_index": im["frame_index"],
                    "meta": None,
                }
            )
        for box in boxes:
            x, y, w, h = box["bbox"]
            data["annotations"].append(
                {
                    "id": len(data["annotations"]) + 1,
                    "image_id": first_image + box["frame_index"],
                    "video_id": video_id,
                    "track_id": box["track_id"],
                    "category_id": category_id[box["category"]],
                    "bbox": box["bbox"],
                    "area": round(w * h, 3),
                    "iscrowd": 0,
                }
            )
        log(f"{name}: {frames} frames, {len(boxes)} boxes ({time.monotonic() - started:.1f} s)")
    path = out / f"altworld_{world}.json"
    path.write_text(json.dumps(data))
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m altworld.generate", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--world", choices=sorted(FIRST_SEEDS), required=True)
    parser.add_argument("--clips", type=int, default=10)
    parser.add_argument("--frames", type=int, default=72)
    parser.add_argument("--first-seed", type=int, default=None)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    try:
        path = render_world(args.world, args.clips, args.frames, args.out, args.first_seed)
    except (ValueError, OSError, RuntimeError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
