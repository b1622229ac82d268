"""``sarmission detect``: run MITE-Net over a video, an image folder or a live stream, write COCO
results.

A file is decoded in its own thread, one frame ahead of detection
(:class:`~sarmission.data.prefetch.Prefetcher`), to YUV planes that MITE-Net reads without a
BGR copy of the frame (:mod:`~sarmission.data.yuv_video`); a live stream (``rtsp://``,
``udp://``, ...) is read by :class:`~sarmission.data.stream.StreamSource`, newest frame first,
until ``--max-frames`` or Ctrl-C, which writes what was found so far.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from sarmission.commands.detector_options import add_detector_options, build_mitenet
from sarmission.commands.progress import add_progress_option, progress_for


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the ``detect`` sub-command."""
    parser = sub.add_parser(
        "detect",
        help="detect tiny targets in a video, image folder or live stream",
        description="Run MITE-Net over every frame of INPUT and write COCO-style results "
        "(image_id, frame_index, bbox [x, y, w, h], score, category_id). A live stream is read "
        "until --max-frames or Ctrl-C, taking the newest frame each time.",
    )
    parser.add_argument(
        "input",
        help="video file, folder of images, or stream URL "
        "(rtsp://HOST/PATH, udp://IP:PORT for MPEG-TS, ...)",
    )
    parser.add_argument("--out", default="dets.json", help="results file (default: %(default)s)")
    parser.add_argument(
        "--annotations",
        default=None,
        help="COCO video annotation file: take image ids from it (matched by "
        "frame index) so the results can be evaluated against it",
    )
    parser.add_argument("--max-frames", type=int, default=None, help="stop after this many frames")
    add_progress_option(parser)
    add_detector_options(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Detect over the input and write the results file."""
    from sarmission.commands.cli_helpers import check_output_path
    from sarmission.data.coco_results import detections_to_coco
    from sarmission.data.frames import open_frame_source
    from sarmission.data.prefetch import Prefetcher
    from sarmission.data.stream import StreamSource

    if args.max_frames is not None and args.max_frames < 1:
        raise ValueError(f"--max-frames must be at least 1, got {args.max_frames}")
    check_output_path(
        args.out,
        {"the input": args.input, "--annotations": args.annotations, "--model": args.model},
    )
    image_ids = _image_ids_by_frame(args.annotations) if args.annotations else None
    source = open_frame_source(args.input, yuv=True)
    live = isinstance(source, StreamSource)
    # The reader starts decoding while the model loads.
    frames = source if live else Prefetcher(source, depth=1)
    try:
        net = build_mitenet(args)
    except BaseException:
        _close(frames, source)
        raise
    results: list[dict] = []
    total = source.length
    if args.max_frames is not None:
        total = min(total or args.max_frames, args.max_frames)
    interrupted = False
    with progress_for(args, "detect", total) as bar:
        try:
            for frame in frames:
                result = net.process(frame.image, frame.timestamp_s)
                image_id = image_ids.get(frame.index, frame.index) if image_ids else frame.index
                results.extend(detections_to_coco(result.detections, image_id, frame.index))
                bar.update(1, dets=len(results))
                if args.max_frames is not None and bar.n >= args.max_frames:
                    break
        except KeyboardInterrupt:
            interrupted = True
        finally:
            _close(frames, source)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results))
    skipped = getattr(source, "skipped", 0)
    print(
        f"{bar.n} frames, {len(results)} detections -> {out}"
        + (f" ({skipped} unreadable frames skipped)" if skipped and not live else "")
        + (" (interrupted)" if interrupted else "")
    )
    return 130 if interrupted else 0


def _close(frames: object, source: object) -> None:
    """Stop the reader thread and release the video or stream."""
    for thing in (frames, source):
        close = getattr(thing, "close", None)
        if close is not None:
            close()


def _image_ids_by_frame(annotation_path: str) -> dict[int, int]:
    """Map frame index → image id from the first video of a COCO video annotation file."""
    from sarmission.data.coco_video import read_coco_video

    dataset = read_coco_video(annotation_path)
    first_video = dataset.videos[0].id if dataset.videos else None
    return {
        img.frame_index: img.id
        for img in dataset.images
        if first_video is None or img.video_id == first_video
    }
