"""``sarmission bench``: the scalability table (ds × N) on 3840x2160 frames in memory, and the
same configurations end to end on an encoded clip (decoding beside detection)."""

from __future__ import annotations

import argparse

from sarmission.commands.cli_helpers import parse_frame_size
from sarmission.commands.detector_options import (
    add_refine_threshold_option,
    check_colour_share,
    check_refine_threshold,
    parse_crop_scales,
)
from sarmission.commands.progress import add_progress_option, progress_for
from sarmission.perception.types import DEFAULT_COLOUR_SHARE, DEFAULT_CROP_SCALES, VALID_DS


def _int_list(text: str) -> list[int]:
    try:
        return [int(v) for v in text.split(",") if v]
    except ValueError:
        message = f"expected comma-separated integers, got {text!r}"
        raise argparse.ArgumentTypeError(message) from None


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the ``bench`` sub-command."""
    parser = sub.add_parser(
        "bench",
        help="time MITE-Net per stage over ds and N",
        description="Time MITE-Net on synthetic frames already in memory: ms per stage, FPS, "
        "FLOPs and peak memory for each (ds, N), beside a plain memory pass (BGR copy + "
        "grayscale) on each frame. Then end to end on the same frames encoded as a video "
        "(H.264 by ffmpeg where installed, else MPEG-4), or on --clip: a plain decoding pass "
        "against decoding overlapped with MITE-Net, both reading the decoder's YUV planes as "
        "detect does. Each configuration runs in its own processes.",
    )
    parser.add_argument(
        "--ds",
        type=_int_list,
        default=list(VALID_DS),
        help="down-sampling factors (default: 1,2,4,8)",
    )
    parser.add_argument(
        "--topn",
        type=_int_list,
        default=[10, 25, 50, 100],
        help="proposal counts (default: 10,25,50,100)",
    )
    parser.add_argument(
        "--size",
        type=parse_frame_size,
        default=(3840, 2160),
        help="frame size WIDTHxHEIGHT (default: 3840x2160)",
    )
    parser.add_argument(
        "--frames",
        type=int,
        default=20,
        help="timed frames per configuration, after 8 warm-up frames (default: %(default)s)",
    )
    parser.add_argument(
        "--quick", action="store_true", help="only ds 2 and 4 at N=25 with 10 frames"
    )
    parser.add_argument(
        "--model",
        default=None,
        help="head weights; default: the shipped model, else an untrained head "
        "(weights do not change the timing)",
    )
    parser.add_argument(
        "--runtime",
        choices=("onnx", "torch"),
        default="onnx",
        help="head runtime (default: %(default)s)",
    )
    parser.add_argument(
        "--ego-motion",
        choices=("estimate", "none"),
        default="estimate",
        help="vSTMD ego-motion compensation (default: %(default)s)",
    )
    parser.add_argument(
        "--colour-share",
        type=float,
        default=DEFAULT_COLOUR_SHARE,
        help="share of the proposals from colour anomalies (default: %(default)s)",
    )
    parser.add_argument(
        "--crop-scales",
        type=parse_crop_scales,
        default=DEFAULT_CROP_SCALES,
        metavar="S[,S...]",
        help="crop sides as multiples of the proposal box: every proposal at the "
        "first, would-be detections also at the others (default: 1,2)",
    )
    add_refine_threshold_option(parser)
    parser.add_argument(
        "--fit-boxes",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="fit each detection's box to the object (the detector's default; "
        "--no-fit-boxes times the head's boxes alone)",
    )
    clip = parser.add_mutually_exclusive_group()
    clip.add_argument(
        "--clip",
        default=None,
        metavar="VIDEO",
        help="video for the end-to-end passes (default: the benchmark's frames, encoded)",
    )
    clip.add_argument("--no-clip", action="store_true", help="frames in memory only")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    add_progress_option(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the sweep and print the table (or JSON)."""
    import tempfile
    from pathlib import Path

    from sarmission.benchmark import encode_clip, format_table, rows_to_json, run_sweep

    ds_values, topn_values, frames = args.ds, args.topn, args.frames
    if args.quick:
        ds_values, topn_values, frames = [2, 4], [25], 10
    bad = [d for d in ds_values if d not in VALID_DS]
    if bad:
        raise ValueError(f"--ds accepts {', '.join(map(str, VALID_DS))}, got {bad}")
    if frames < 1 or min(topn_values) < 1:
        raise ValueError("--frames and --topn must be positive")
    width, height = args.size
    check_colour_share(args.colour_share)
    check_refine_threshold(args.refine_threshold)
    if args.clip is not None and not Path(args.clip).is_file():
        raise ValueError(f"--clip {args.clip}: no such file")
    with tempfile.TemporaryDirectory(prefix="sarmission-bench-") as tmp:
        clip = None if args.no_clip else args.clip or encode_clip(width, height, frames + 8, tmp)
        with progress_for(args, "bench", len(ds_values) * len(topn_values), "config") as bar:
            rows = run_sweep(
                ds_values,
                topn_values,
                width,
                height,
                frames,
                args.model,
                args.runtime,
                args.ego_motion,
                on_row=lambda _row: bar.update(1),
                colour_share=args.colour_share,
                crop_scales=args.crop_scales,
                refine_threshold=args.refine_threshold,
                clip=clip,
                fit_boxes=args.fit_boxes,
            )
    print(rows_to_json(rows) if args.json else format_table(rows))
    return 0
