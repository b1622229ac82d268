"""``sarmission eval``: SAR metrics, box metrics and module recall on an annotated dataset.

Three modes:

- ``--detections dets.json``: evaluate a results file (as written by ``sarmission detect
  --annotations``); its image ids must exist in the annotations.
- otherwise MITE-Net runs over every video here (``--model``, else the shipped model, else an
  untrained head with a warning) and the report adds the RPN's recall and the timing;
- ``--sweep``: MITE-Net runs once per (ds, N) of the grid, one row each: SSR, FAR, median ms
  per frame and FPS measured in that run, GFLOPs per stage (the paper's Table 4).

JSON output (``--json``) of an evaluation has the keys of
:func:`sarmission.evaluation.report.evaluate_detections` (``dataset``, ``classes``,
``categories``, ``settings``, ``sar``, ``boxes``, ``module_recall``, ``definitions``) plus
``detector`` (``None`` for a results file; else ``model``, ``runtime``, ``ds``, ``topn``,
``conf``, ``frames``, ``skipped_frames``, ``median_ms``, ``fps``); of a sweep, a list of the
rows of :func:`sarmission.evaluation.run_model.run_sweep`.
"""

from __future__ import annotations

import argparse
import logging
from typing import Any

from sarmission.commands.cli_helpers import parse_pairs
from sarmission.commands.detector_options import (
    add_detector_options,
    add_range_crop_options,
    check_colour_share,
    check_range_crop_options,
    check_refine_threshold,
    detector_settings,
)
from sarmission.commands.progress import add_progress_option, bars_wanted
from sarmission.perception.types import VALID_DS

log = logging.getLogger(__name__)

DS_CHOICES = VALID_DS


def _int_list(text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected comma-separated integers, got {text!r}"
        ) from None
    if not values:
        raise argparse.ArgumentTypeError("expected at least one integer")
    return values


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the ``eval`` sub-command."""
    parser = sub.add_parser(
        "eval",
        help="evaluate detections or MITE-Net on an annotated dataset",
        description="Search success rate, false alarm rate and search time (m-of-k lock on "
        "NWD matching), AP/AR/F2 per size band, and the recall of the RPN proposals and of "
        "the head. Evaluates a results file (--detections) or runs MITE-Net itself.",
    )
    parser.add_argument(
        "--annotations", required=True, help="COCO video annotation file (SeaDronesSee style)"
    )
    parser.add_argument(
        "--detections",
        default=None,
        help="COCO results file to evaluate instead of running the detector",
    )
    parser.add_argument(
        "--m",
        type=int,
        default=3,
        help="hits needed inside the window to lock a target (default: 3)",
    )
    parser.add_argument("--k", type=int, default=5, help="lock window in frames (default: 5)")
    parser.add_argument(
        "--score-thr",
        type=float,
        default=0.5,
        help="a detection counts when its score is above this (default: 0.5)",
    )
    parser.add_argument(
        "--nwd-thr", type=float, default=0.5, help="a match needs NWD above this (default: 0.5)"
    )
    parser.add_argument(
        "--max-frames", type=int, default=None, help="evaluate only the first frames of each video"
    )
    parser.add_argument(
        "--sweep",
        action="store_true",
        help="run MITE-Net for every ds x N of the grid (scalability table)",
    )
    parser.add_argument(
        "--sweep-ds",
        type=_int_list,
        default=list(VALID_DS),
        help="sweep down-sampling factors (default: 1,2,4,8)",
    )
    parser.add_argument(
        "--sweep-topn",
        type=_int_list,
        default=[10, 25, 50, 100],
        help="sweep proposal counts (default: 10,25,50,100)",
    )
    parser.add_argument(
        "--rename",
        action="append",
        default=[],
        metavar="CATEGORY=CLASS",
        help="score an annotation category as one of the head's classes, e.g. person=swimmer "
        "(the shipped head reports people on land as swimmer); repeatable",
    )
    parser.add_argument("--json", action="store_true", help="print JSON instead of tables")
    add_progress_option(parser)
    add_detector_options(parser)
    add_range_crop_options(parser)
    parser.set_defaults(func=run)


def _check_args(args: argparse.Namespace) -> None:
    if not 1 <= args.m <= args.k:
        raise ValueError(f"need 1 <= --m <= --k, got --m {args.m} --k {args.k}")
    for name in ("score_thr", "nwd_thr", "conf"):
        value = getattr(args, name)
        if not 0.0 <= value <= 1.0:
            raise ValueError(f"--{name.replace('_', '-')} must be in [0, 1], got {value}")
    if args.max_frames is not None and args.max_frames < 1:
        raise ValueError(f"--max-frames must be at least 1, got {args.max_frames}")
    if args.detections is not None and (args.model is not None or args.sweep):
        raise ValueError(
            "--detections evaluates a results file; it cannot be combined with "
            "--model or --sweep, which run the detector"
        )
    topn = args.sweep_topn if args.sweep else [args.topn]
    if min(topn) < 1:
        raise ValueError(f"proposal counts must be at least 1, got {topn}")
    check_colour_share(args.colour_share)
    check_refine_threshold(args.refine_threshold)
    check_range_crop_options(args)
    if args.person_m and (args.detections is not None or args.sweep):
        raise ValueError(
            "--person-m sizes the detector's crops; it needs neither --detections nor --sweep"
        )
    bad = [d for d in args.sweep_ds if d not in DS_CHOICES]
    if args.sweep and bad:
        raise ValueError(f"--sweep-ds accepts {', '.join(map(str, DS_CHOICES))}, got {bad}")


def _model_label(args: argparse.Namespace) -> str:
    """The head that :func:`build_head_runtime` loads for these options, in words."""
    from sarmission.models import DEFAULT_ONNX_MODEL, DEFAULT_TORCH_MODEL

    if args.model is not None:
        return str(args.model)
    for path in ((DEFAULT_ONNX_MODEL,) if args.runtime == "onnx" else ()) + (DEFAULT_TORCH_MODEL,):
        if path.is_file():
            return str(path)
    log.warning("no shipped model and no --model: evaluating an untrained head")
    return "untrained head (no shipped model)"


def renamed(dataset: Any, mapping: dict[str, str]) -> Any:
    """``dataset`` with the categories named in ``mapping`` renamed (ids kept, so a results
    file still refers to the same images); ``ValueError`` for a category it does not have."""
    if not mapping:
        return dataset
    import dataclasses

    names = [c.name for c in dataset.categories]
    unknown = sorted(set(mapping) - set(names))
    if unknown:
        raise ValueError(
            f"--rename: the annotations have no category {', '.join(map(repr, unknown))} "
            f"(they have {', '.join(map(repr, names)) or 'none'})"
        )
    categories = [
        dataclasses.replace(c, name=mapping.get(c.name, c.name)) for c in dataset.categories
    ]
    return dataclasses.replace(dataset, categories=categories)


def _check_targets(dataset: Any, classes: tuple[str, ...]) -> None:
    """A clear line when no annotation category is a person class of the head."""
    from sarmission.evaluation.report import person_category_map

    try:
        person_category_map(dataset.categories, classes)
    except ValueError as exc:
        raise ValueError(
            f"{exc}; score a category as one of the head's classes with --rename, e.g. "
            f"--rename person={classes[0]}"
        ) from None


def run(args: argparse.Namespace) -> int:
    """Evaluate (or sweep) and print the tables, or JSON with ``--json``."""
    from sarmission.data.coco_video import read_coco_video
    from sarmission.evaluation.report import format_report, format_sweep, report_to_json

    _check_args(args)
    dataset = renamed(read_coco_video(args.annotations), parse_pairs(args.rename, "--rename"))
    metric_options = {
        "m": args.m,
        "k": args.k,
        "score_thr": args.score_thr,
        "nwd_thr": args.nwd_thr,
    }
    if args.detections is not None:
        report = _evaluate_file(args, dataset, metric_options)
        print(report_to_json(report) if args.json else format_report(report))
        return 0

    from sarmission.evaluation.run_model import run_sweep
    from sarmission.perception.mitenet import build_head_runtime

    label = _model_label(args)
    head = build_head_runtime(args.model, args.runtime)
    _check_targets(dataset, head.classes)
    if args.sweep:
        rows = run_sweep(
            head,
            dataset,
            args.sweep_ds,
            args.sweep_topn,
            max_frames=args.max_frames,
            progress=bars_wanted(args),
            **metric_options,
            **detector_settings(args),
        )
        print(report_to_json(rows) if args.json else f"model: {label}\n" + format_sweep(rows))
        return 0
    report = _evaluate_model(args, dataset, head, label, metric_options)
    print(
        report_to_json(report)
        if args.json
        else _format_detector(report["detector"]) + "\n" + format_report(report)
    )
    return 0


def _evaluate_file(
    args: argparse.Namespace, dataset: Any, metric_options: dict[str, Any]
) -> dict[str, Any]:
    from sarmission.data.coco_results import read_coco_results
    from sarmission.data.sequence import sequence_ids, sequence_images
    from sarmission.evaluation.report import detections_from_results, evaluate_detections
    from sarmission.perception.head import DEFAULT_CLASSES

    detections = detections_from_results(
        read_coco_results(args.detections), dataset, DEFAULT_CLASSES
    )
    image_ids = None
    if args.max_frames is not None:
        image_ids = [
            im.id
            for vid in sequence_ids(dataset)
            for im in sequence_images(dataset, vid)[: args.max_frames]
        ]
    report = evaluate_detections(
        dataset, detections, DEFAULT_CLASSES, image_ids=image_ids, **metric_options
    )
    return {**report, "detector": None}


def _evaluate_model(
    args: argparse.Namespace, dataset: Any, head: Any, label: str, metric_options: dict[str, Any]
) -> dict[str, Any]:
    from sarmission.evaluation.report import evaluate_detections, person_category_map
    from sarmission.evaluation.run_model import run_mitenet
    from sarmission.mission.range_crops import dataset_person_px
    from sarmission.perception.mitenet import MiteNet

    net = MiteNet(
        head,
        ds=args.ds,
        topn=args.topn,
        range_shift_per_octave=args.range_shift,
        **detector_settings(args),
    )
    person_category_map(dataset.categories, net.classes)  # fail before running, not after
    person_px_of = dataset_person_px(dataset, args.person_m, args.hfov) if args.person_m else None
    run = run_mitenet(
        net, dataset, args.max_frames, progress=bars_wanted(args), person_px_of=person_px_of
    )
    if not run.frame_ms:
        raise ValueError(f"{args.annotations}: none of the {run.skipped} frames could be read")
    report = evaluate_detections(
        dataset,
        run.detections,
        net.classes,
        run.proposals,
        image_ids=run.image_ids,
        **metric_options,
    )
    median = run.median_ms
    return {
        **report,
        "detector": {
            "model": label,
            "runtime": args.runtime,
            "ds": args.ds,
            "topn": args.topn,
            "colour_share": args.colour_share,
            "crop_scales": list(args.crop_scales),
            "person_m": args.person_m,
            "range_shift": args.range_shift,
            "refine_threshold": net.refine_threshold,
            "recentre": net.recentre,
            "orientations": net.orientations,
            "fit_boxes": net.fit_boxes,
            "conf": args.conf,
            "frames": len(run.frame_ms),
            "skipped_frames": run.skipped,
            "median_ms": median,
            "fps": 1e3 / median if median else None,
        },
    }


def _format_detector(detector: dict[str, Any]) -> str:
    skipped = detector["skipped_frames"]
    return (
        f"detector: {detector['model']} ({detector['runtime']}), ds={detector['ds']}, "
        f"N={detector['topn']}, colour share={detector['colour_share']:g}, "
        f"crop scales={','.join(f'{v:g}' for v in detector['crop_scales'])}"
        + (
            f" (further scales from score {detector['refine_threshold']:g})"
            if len(detector["crop_scales"]) > 1
            else ""
        )
        + (", recentred" if detector["recentre"] else "")
        + (f", {detector['orientations']} orientations" if detector["orientations"] > 1 else "")
        + ("" if detector.get("fit_boxes", True) else ", boxes not fitted")
        + f", conf={detector['conf']:g}; {detector['frames']} frames"
        + (f" ({skipped} unreadable, skipped)" if skipped else "")
        + f", median {detector['median_ms']:.2f} ms/frame ({detector['fps']:.1f} FPS)"
    )
