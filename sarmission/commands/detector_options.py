"""Detector options shared by every command that runs MITE-Net, and the factory that uses them."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

from sarmission.perception.orientations import ORIENTATION_COUNTS
from sarmission.perception.types import (
    DEFAULT_COLOUR_SHARE,
    DEFAULT_CROP_SCALES,
    MAX_CROP_SCALE,
    VALID_DS,
)

if TYPE_CHECKING:
    from sarmission.perception.mitenet import MiteNet

DEFAULT_DS = 2
DEFAULT_TOPN = 25
DEFAULT_SCORE_THRESHOLD = 0.3


def add_detector_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--model --runtime --ds --topn --colour-share --crop-scales --refine-threshold
    --recentre --orientations --fit-boxes --ego-motion --conf`` to ``parser``."""
    group = parser.add_argument_group("detector")
    group.add_argument(
        "--model",
        default=None,
        help="head weights (.pt or .onnx) or a shipped head: maritime (the default) or land",
    )
    group.add_argument(
        "--runtime",
        choices=("onnx", "torch"),
        default="onnx",
        help="head runtime; onnxruntime is ~3x faster on CPU (default: %(default)s)",
    )
    group.add_argument(
        "--ds",
        type=int,
        choices=VALID_DS,
        default=DEFAULT_DS,
        help="vSTMD down-sampling factor (default: %(default)s)",
    )
    group.add_argument(
        "--topn", type=int, default=DEFAULT_TOPN, help="proposals per frame (default: %(default)s)"
    )
    group.add_argument(
        "--colour-share",
        type=float,
        default=DEFAULT_COLOUR_SHARE,
        help="share of the proposals taken from colour anomalies rather than motion "
        "(0 = motion only, as in the paper; default: %(default)s)",
    )
    group.add_argument(
        "--crop-scales",
        type=parse_crop_scales,
        default=DEFAULT_CROP_SCALES,
        metavar="S[,S...]",
        help="crop sides as multiples of the proposal box: every proposal at the "
        "first, would-be detections again at the others, keeping the best-scored "
        "crop; 1,2 lets the head box swimmers of 25-40 px whole, 1 is the paper's "
        "single crop (default: 1)",
    )
    add_refine_threshold_option(group)
    group.add_argument(
        "--recentre",
        action=argparse.BooleanOptionalAction,
        default=False,
        help="crop each proposal once more where the head placed the target's centre, and "
        "keep that crop's score and box (docs/recentring.md; default: off)",
    )
    group.add_argument(
        "--orientations",
        type=int,
        choices=ORIENTATION_COUNTS,
        default=1,
        help="score each would-be detection in this many orientations (quarter turns, "
        "mirrors) and average: 4 or 8 cost up to that many head passes "
        "(docs/experiments.md; default: 1)",
    )
    group.add_argument(
        "--fit-boxes",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="fit each detection's box to the object against its surroundings, up to 4 S "
        "long (docs/box_fit.md; default: on)",
    )
    group.add_argument(
        "--ego-motion",
        choices=("estimate", "none"),
        default="estimate",
        help="compensate the camera's own motion (moving drone) or assume a still "
        "camera (default: %(default)s)",
    )
    group.add_argument(
        "--conf",
        type=float,
        default=DEFAULT_SCORE_THRESHOLD,
        help="minimum detection score kept (default: %(default)s)",
    )


def detector_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The :class:`~sarmission.perception.mitenet.MiteNet` keyword options the detector flags
    set, checked, apart from the head, ds and N. One list for every command that builds the
    cascade, so that no command drops a flag the others honour."""
    check_colour_share(args.colour_share)
    check_refine_threshold(args.refine_threshold)
    return {
        "score_threshold": args.conf,
        "ego_motion": args.ego_motion,
        "colour_share": args.colour_share,
        "crop_scales": args.crop_scales,
        "refine_threshold": args.refine_threshold,
        "recentre": args.recentre,
        "orientations": args.orientations,
        "fit_boxes": args.fit_boxes,
    }


def build_mitenet(args: argparse.Namespace) -> MiteNet:
    """Create the MITE-Net cascade from parsed detector options (loads the head weights)."""
    from sarmission.models import default_model_path
    from sarmission.perception.mitenet import MiteNet
    from sarmission.perception.runtime import load_head_runtime

    if args.topn < 1:
        raise ValueError(f"--topn must be at least 1, got {args.topn}")
    settings = detector_settings(args)
    model_path = args.model or default_model_path(args.runtime)
    head = load_head_runtime(model_path, runtime=args.runtime)
    return MiteNet(head, ds=args.ds, topn=args.topn, **settings)


def add_refine_threshold_option(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """``--refine-threshold`` (MiteNet's ``refine_threshold``), for every command that runs it."""
    parser.add_argument(
        "--refine-threshold",
        type=float,
        default=None,
        metavar="SCORE",
        help="first-crop score from which a proposal is cropped again at the "
        "further scales; 0 = every proposal: more found, ~2 ms more per 4K "
        "frame (default: the detection score threshold, 0.3)",
    )


def check_refine_threshold(value: float | None) -> None:
    """``ValueError`` unless ``--refine-threshold`` is unset or in [0, 1]."""
    if value is not None and not 0.0 <= value <= 1.0:
        raise ValueError(f"--refine-threshold must be in [0, 1], got {value}")


def parse_crop_scales(text: str) -> tuple[float, ...]:
    """``"1,2"`` -> ``(1.0, 2.0)``; an argparse error for anything but positive numbers."""
    try:
        scales = tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError:
        scales = ()
    if not scales or any(not 0.0 < s <= MAX_CROP_SCALE for s in scales):
        raise argparse.ArgumentTypeError(
            f"expected comma-separated numbers in (0, {MAX_CROP_SCALE:g}], e.g. 1,2; got {text!r}"
        )
    return scales


def check_colour_share(value: float) -> None:
    """Raise ``ValueError`` unless ``--colour-share`` is in [0, 1]."""
    if not 0.0 <= value <= 1.0:
        raise ValueError(f"--colour-share must be in [0, 1], got {value}")


def add_range_crop_options(parser: argparse.ArgumentParser) -> None:
    """``--person-m --range-shift --hfov``: crops sized to the person from each frame's meta
    (:mod:`sarmission.mission.range_crops`), for commands that run MITE-Net over a dataset."""
    group = parser.add_argument_group("crops sized to the person (from each frame's meta)")
    group.add_argument(
        "--person-m",
        type=float,
        default=0.0,
        metavar="METRES",
        help="grow a proposal's crops where a person this wide (across the line of sight) "
        "would span more than the proposal box, from the frame's meta and the lens; "
        "0 = off, crops as at the survey's ranges (default: %(default)s)",
    )
    group.add_argument(
        "--range-shift",
        type=float,
        default=0.0,
        metavar="LOGITS",
        help="with --person-m: lower a grown crop's class logits by this much per doubling "
        "(docs/range_crops.md; default: %(default)s)",
    )
    group.add_argument(
        "--hfov",
        type=float,
        default=None,
        metavar="DEG",
        help="with --person-m: the lens's horizontal field of view (default: each video's "
        "hfov_deg; frames without one are cropped as at the survey's ranges)",
    )


def check_range_crop_options(args: argparse.Namespace) -> None:
    """``ValueError`` for a ``--person-m``, ``--range-shift`` or ``--hfov`` out of range."""
    import math

    if not (math.isfinite(args.person_m) and 0.0 <= args.person_m <= 10.0):
        raise ValueError(f"--person-m must be in [0, 10] metres, got {args.person_m}")
    if not (math.isfinite(args.range_shift) and 0.0 <= args.range_shift <= 10.0):
        raise ValueError(f"--range-shift must be in [0, 10], got {args.range_shift}")
    if args.hfov is not None and not (math.isfinite(args.hfov) and 0.0 < args.hfov < 180.0):
        raise ValueError(f"--hfov must be in (0, 180) degrees, got {args.hfov}")
