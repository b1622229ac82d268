"""Render held-out clips into the COCO video layout that ``sarmission eval`` reads.

Output in ``out``: per clip ``<world>_<i>.mp4`` (H.264 at the clip's drone bitrate) or a folder
``<world>_<i>/NNNNNN.jpg``, and one ``<world>.json``: a video per clip, an image per frame with
SeaDronesSee telemetry in ``meta``, an annotation per visible object with ``track_id``, ``bbox``,
``area``, true ``gt_lat``/``gt_lon``, and as extra keys ``visibility``, ``is_target``,
``posture`` and ``speed_m_s`` (over the ground: 0 for people who stay put)::

    python -m heldout.generate --world heldout_maritime --clips 2 --frames 60 --out /tmp/ho
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

from heldout.encode import H264Writer, JpegWriter
from heldout.presets import WORLDS, draw_clip, world
from heldout.scene import ClipRenderer, ObjectBox
from heldout.world import CATEGORIES, TARGETS
from sarmission.data.coco_video import (
    Annotation,
    Category,
    ImageRecord,
    Video,
    VideoDataset,
    write_coco_video,
)


def _annotation(box: ObjectBox, ann_id: int, image_id: int, video_id: int) -> Annotation:
    x, y, w, h = box.bbox
    return Annotation(
        id=ann_id,
        image_id=image_id,
        category_id=CATEGORIES[box.category],
        bbox=(x, y, w, h),
        track_id=box.track_id,
        video_id=video_id,
        area=w * h,
        gt_lat=box.lat,
        gt_lon=box.lon,
        extra={
            "visibility": round(box.visibility, 3),
            "is_target": box.is_target,
            "posture": box.posture,
            "speed_m_s": round(box.speed_m_s, 2),
        },
    )


def render_world(
    name: str,
    clips: int,
    frames: int,
    out: str | Path,
    size: tuple[int, int] = (1920, 1080),
    fps: float = 30.0,
    images: bool = False,
    first_clip: int = 0,
    progress: bool = False,
    altitude_m: tuple[float, float] | None = None,
) -> Path:
    """Render ``clips`` clips of ``frames`` frames of the world ``name``; returns the JSON path.

    Clip ``i`` is drawn from the world's seed and ``first_clip + i``: the same arguments render
    the same pixels and boxes. ``altitude_m`` (low, high) replaces the world's altitude range,
    for studies of the same world seen from nearer or farther (every other draw of a clip is
    the same; its objects are placed anew over the footprint the new altitude sees).
    """
    if clips < 1 or frames < 1:
        raise ValueError(f"need at least one clip and one frame, got {clips} x {frames}")
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    preset = world(name)
    if altitude_m is not None:
        low, high = altitude_m
        if not (math.isfinite(low) and math.isfinite(high) and 5.0 <= low <= high <= 1000.0):
            raise ValueError(f"altitude range must be 5 <= LOW <= HIGH <= 1000 m, got {low}-{high}")
        preset = replace(preset, altitude_m=(float(low), float(high)))
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    videos: list[Video] = []
    image_records: list[ImageRecord] = []
    annotations: list[Annotation] = []
    width, height = size
    for c in range(clips):
        index = first_clip + c
        spec = draw_clip(preset, index, width, height, frames / fps)
        renderer = ClipRenderer(spec)
        clip_name = f"{name}_{index:02d}"
        rng = np.random.default_rng([spec.seed, 1])
        extra: dict[str, object] = {
            "width": width,
            "height": height,
            "fps": fps,
            "seed": spec.seed,
            "kind": spec.kind,
            "sea_state": spec.sea_state,
            "altitude_m": round(spec.path.altitude_m, 2),
            "tilt_deg": round(spec.path.tilt_deg, 2),
            "hfov_deg": round(spec.lens.hfov_deg, 4),
            "speed_m_s": round(spec.path.speed_m_s, 2),
        }
        if images:
            writer: H264Writer | JpegWriter = JpegWriter(out / clip_name, int(rng.integers(70, 93)))
        else:
            extra["file_name"] = f"{clip_name}.mp4"
            writer = H264Writer(
                out / f"{clip_name}.mp4", width, height, fps, float(rng.uniform(0.08, 0.25))
            )
        video_id = len(videos) + 1
        videos.append(Video(video_id, clip_name, extra))
        try:
            for i in range(frames):
                t = i / fps
                frame, boxes = renderer.render(t, rng)
                writer.write(frame)
                image_id = len(image_records) + 1
                image_records.append(
                    ImageRecord(
                        id=image_id,
                        file_name=f"{clip_name}/{i:06d}.jpg",
                        height=height,
                        width=width,
                        video_id=video_id,
                        frame_index=i,
                        meta=spec.path.meta(t, spec.home),
                    )
                )
                for box in boxes:
                    annotations.append(_annotation(box, len(annotations) + 1, image_id, video_id))
                if progress:
                    print(f"\r{clip_name}: frame {i + 1}/{frames}", end="", file=sys.stderr)
        finally:
            writer.close()
        if progress:
            print(file=sys.stderr)
    categories = [
        Category(cid, cname, "person" if cname in TARGETS else "object")
        for cname, cid in CATEGORIES.items()
    ]
    dataset = VideoDataset(
        videos=videos,
        images=image_records,
        annotations=annotations,
        categories=categories,
        info={
            "description": f"held-out {preset.kind} world {name}",
            "world": name,
            "seed": preset.seed,
            "clips": clips,
            "first_clip": first_clip,
            "fps": fps,
            "altitude_m": list(preset.altitude_m),
        },
    )
    path = out / f"{name}.json"
    write_coco_video(dataset, path)
    return path


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT, got {text!r}") from None
    if w < 16 or h < 16 or w % 2 or h % 2:
        raise argparse.ArgumentTypeError(f"size must be even and at least 16x16, got {text!r}")
    return w, h


def altitude_range(text: str) -> tuple[float, float]:
    """``LOW,HIGH`` metres, as ``--altitude`` takes it."""
    try:
        low, high = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LOW,HIGH in metres, got {text!r}") from None
    return low, high


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m heldout.generate",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--world", default="heldout_maritime", choices=sorted(WORLDS))
    parser.add_argument("--clips", type=int, default=2)
    parser.add_argument("--frames", type=int, default=60)
    parser.add_argument(
        "--first-clip", type=int, default=0, help="index of the first clip (default: %(default)s)"
    )
    parser.add_argument(
        "--size", type=_size, default=(1920, 1080), help="WIDTHxHEIGHT (default: 1920x1080)"
    )
    parser.add_argument("--fps", type=float, default=30.0)
    parser.add_argument("--images", action="store_true", help="JPEG folders instead of MP4")
    parser.add_argument("--out", required=True)
    parser.add_argument("--progress", action="store_true")
    parser.add_argument(
        "--altitude",
        type=altitude_range,
        default=None,
        help="LOW,HIGH: fly the clips at this altitude range (m) instead of the world's, to "
        "see the same world from nearer or farther (default: the world's)",
    )
    args = parser.parse_args(argv)
    try:
        path = render_world(
            args.world,
            args.clips,
            args.frames,
            args.out,
            args.size,
            args.fps,
            args.images,
            args.first_clip,
            args.progress,
            args.altitude,
        )
    except (ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {args.clips} x {args.frames} frames of {args.world} -> {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
