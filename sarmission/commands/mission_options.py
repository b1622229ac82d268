"""Options shared by the commands that run a mission (``run``, ``replay``, ``demo``): mission
file and overrides, detector (defaults from the mission file), recorder, alert store."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from sarmission.commands.cli_helpers import positive_seconds
from sarmission.commands.detector_options import add_detector_options

if TYPE_CHECKING:
    from sarmission.mission.config import MissionConfig
    from sarmission.perception.mitenet import MiteNet
    from sarmission.viz.recorder import Recorder


def mission_id(text: str) -> str:
    """``--mission-id``: printable characters only, since it goes into CoT and KML (XML)."""
    from sarmission.mission.config_rules import mission_id_problem

    problem = mission_id_problem(text)
    if problem is not None:
        raise argparse.ArgumentTypeError(problem)
    return text


def add_mission_options(parser: argparse.ArgumentParser, mission_required: bool = False) -> None:
    """``--mission --set --alerts-db --rerun --max-frames --duration`` and the detector options
    (``--ds --topn --colour-share --conf`` default to the mission file's ``[detector]``
    values)."""
    group = parser.add_argument_group("mission")
    group.add_argument(
        "--mission",
        required=mission_required,
        default=None,
        help="mission file (TOML); default: built-in defaults",
    )
    group.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="SECTION.KEY=VALUE",
        help="override a mission value, e.g. --set flight.altitude_m=80 (repeatable)",
    )
    group.add_argument(
        "--mission-id",
        type=mission_id,
        default=None,
        help="id the alerts are stored under (default: the mission's name)",
    )
    group.add_argument(
        "--rerun",
        nargs="+",
        metavar=("MODE", "FILE"),
        default=None,
        help="log to rerun: 'spawn' a viewer or 'save FILE.rrd'",
    )
    group.add_argument("--max-frames", type=int, default=None, help="stop after this many frames")
    group.add_argument(
        "--duration", type=positive_seconds, default=None, help="stop after this many seconds"
    )
    add_detector_options(parser)
    # None = the mission file's [detector] value (the file overrides code, the CLI the file).
    parser.set_defaults(
        ds=None,
        topn=None,
        colour_share=None,
        crop_scales=None,
        refine_threshold=None,
        recentre=None,
        orientations=None,
        fit_boxes=None,
        conf=None,
    )


def load_mission_from_args(args: argparse.Namespace) -> MissionConfig:
    """The mission file with ``--set`` overrides, then ``--ds/--topn/--colour-share/
    --crop-scales/--refine-threshold/--recentre/--orientations/--fit-boxes/--conf`` on top."""
    from sarmission.mission.config import load_mission

    overrides: list[str] = list(args.overrides)
    for option, key in (
        ("ds", "detector.ds"),
        ("topn", "detector.topn"),
        ("colour_share", "detector.colour_share"),
        ("crop_scales", "detector.crop_scales"),
        ("refine_threshold", "detector.refine_threshold"),
        ("recentre", "detector.recentre"),
        ("orientations", "detector.orientations"),
        ("fit_boxes", "detector.fit_boxes"),
        ("conf", "detector.score_threshold"),
    ):
        value = getattr(args, option)
        if isinstance(value, bool):
            value = "true" if value else "false"
        elif isinstance(value, tuple):
            value = "[" + ", ".join(repr(v) for v in value) + "]"
        if value is not None:
            overrides.append(f"{key}={value}")
    if args.max_frames is not None and args.max_frames < 1:
        raise ValueError(f"--max-frames must be at least 1, got {args.max_frames}")
    if args.duration is not None and args.duration <= 0:
        raise ValueError(f"--duration must be positive, got {args.duration}")
    return load_mission(args.mission, overrides)


def build_detector(args: argparse.Namespace, mission: MissionConfig) -> tuple[MiteNet, str]:
    """MITE-Net with the mission's detector settings; returns it and a line naming the model
    (saying so plainly when the package has no trained model and the head is untrained) and
    the alert confidence fitted for it, if any (:mod:`sarmission.mission.confidence`).
    ``--model`` wins over the mission's ``[detector] model``, which wins over the shipped head."""
    from sarmission.mission.config_rules import DEFAULT_MODEL
    from sarmission.models import DEFAULT_ONNX_MODEL, DEFAULT_TORCH_MODEL
    from sarmission.perception.mitenet import MiteNet, build_head_runtime

    model, origin = args.model, ""
    if model is None and mission.detector.model != DEFAULT_MODEL:
        model, origin = mission.detector.model, " (the mission's [detector] model)"
    head = build_head_runtime(model, args.runtime)
    from sarmission.class_roles import person_class_ids

    if not person_class_ids(head.classes).size:  # it would never alert, and say nothing
        raise ValueError(
            f"{model}{origin}: the head names no person ({', '.join(head.classes)}); "
            "a mission needs a head that finds people"
        )
    if model is not None:
        note = f"model: {model}{origin}"
    elif DEFAULT_ONNX_MODEL.is_file() or DEFAULT_TORCH_MODEL.is_file():
        shipped = (
            DEFAULT_ONNX_MODEL
            if args.runtime == "onnx" and DEFAULT_ONNX_MODEL.is_file()
            else DEFAULT_TORCH_MODEL
        )
        note = f"model: the shipped default ({shipped.name}, {args.runtime})"
    else:
        note = (
            "model: NONE TRAINED - the package has no default model "
            f"({DEFAULT_TORCH_MODEL.name} / {DEFAULT_ONNX_MODEL.name}); running an untrained "
            "head with fixed random weights, so its alerts mean nothing (expect none or "
            "many false ones). Pass --model PATH."
        )
    from sarmission.mission.confidence import confidence_of_head

    note += f"; {confidence_of_head(head).note}"
    note += adopt_head_min_score(mission, model)
    d = mission.detector
    detector = MiteNet(
        head,
        ds=d.ds,
        topn=d.topn,
        score_threshold=d.score_threshold,
        ego_motion=args.ego_motion,
        colour_share=d.colour_share,
        crop_scales=tuple(d.crop_scales),
        refine_threshold=d.refine_threshold,
        recentre=d.recentre,
        orientations=d.orientations,
        fit_boxes=d.fit_boxes,
        range_shift_per_octave=d.range_shift,
    )
    return detector, note


def adopt_head_min_score(mission: MissionConfig, model: str | None) -> str:
    """Give ``mission`` the ``[confirm] min_score`` of the shipped head ``model`` names (None:
    the default head) unless the mission file or an override set one; returns a note for the
    model line ("" when nothing changed). A model file keeps the mission's threshold."""
    from sarmission.models import shipped_min_score

    shipped = shipped_min_score(model)
    if shipped is None or "confirm.min_score" in mission.explicit:
        return ""
    name, threshold = shipped
    if mission.confirm.min_score == threshold:
        return ""
    mission.confirm.min_score = threshold
    return f"; alerts need a mean score of {threshold:g}, the {name} head's [confirm] min_score"


def build_recorder(args: argparse.Namespace) -> Recorder | None:
    """The rerun recorder of ``--rerun spawn | save FILE`` (None without the option)."""
    if args.rerun is None:
        return None
    from sarmission.viz.recorder import Recorder

    mode, *rest = args.rerun
    if mode == "spawn" and not rest:
        return Recorder("spawn")
    if mode == "save" and len(rest) == 1:
        return Recorder("save", rest[0])
    raise ValueError(f"--rerun expects 'spawn' or 'save FILE', got {' '.join(args.rerun)!r}")
