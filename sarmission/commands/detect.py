"""``sarmission detect``: run MITE-Net over a video file or an image folder, write COCO results."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from sarmission.commands.detector_options import add_detector_options, build_mitenet


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the ``detect`` sub-command."""
    parser = sub.add_parser(
        "detect",
        help="detect tiny targets in a video or image folder",
        description="Run MITE-Net over every frame of INPUT and write COCO-style results "
        "(image_id, frame_index, bbox [x, y, w, h], score, category_id).",
    )
    parser.add_argument("input", help="video file or folder of images")
    parser.add_argument("--out", default="dets.json", help="results file (default: %(default)s)")
    parser.add_argument("--annotations", default=None,
                        help="COCO video annotation file: take image ids from it (matched by "
                        "frame index) so the results can be evaluated against it")
    parser.add_argument("--max-frames", type=int, default=None, help="stop after this many frames")
    add_detector_options(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Detect over the input and write the results file."""
    from tqdm import tqdm

    from sarmission.data.coco_results import detections_to_coco
    from sarmission.data.frames import open_frame_source

    source = open_frame_source(args.input)
    net = build_mitenet(args)
    image_ids = _image_ids_by_frame(args.annotations) if args.annotations else None
    results: list[dict] = []
    total = source.length
    if args.max_frames is not None:
        total = min(total or args.max_frames, args.max_frames)
    with tqdm(total=total, unit="frame", desc="detect", file=sys.stderr) as bar:
        for frame in source:
            if args.max_frames is not None and bar.n >= args.max_frames:
                break
            result = net.process(frame.image_bgr, frame.timestamp_s)
            image_id = image_ids.get(frame.index, frame.index) if image_ids else frame.index
            results.extend(detections_to_coco(result.detections, image_id, frame.index))
            bar.update(1)
            bar.set_postfix(dets=len(results))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results))
    skipped = getattr(source, "skipped", 0)
    print(f"{bar.n} frames, {len(results)} detections -> {out}"
          + (f" ({skipped} unreadable frames skipped)" if skipped else ""))
    return 0


def _image_ids_by_frame(annotation_path: str) -> dict[int, int]:
    """Map frame index → image id from the first video of a COCO video annotation file."""
    from sarmission.data.coco_video import read_coco_video

    dataset = read_coco_video(annotation_path)
    first_video = dataset.videos[0].id if dataset.videos else None
    return {img.frame_index: img.id for img in dataset.images
            if first_video is None or img.video_id == first_video}
