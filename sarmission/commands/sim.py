"""``sarmission sim ...``: the simulator (MAVLink vehicle, scene generation, dataset replay)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from sarmission.commands.cli_helpers import (
    non_negative_int,
    non_negative_seconds,
    parse_frame_size,
    positive_rate,
    positive_seconds,
)
from sarmission.commands.progress import add_progress_option, bars_wanted

if TYPE_CHECKING:
    from sarmission.mission.config import MissionConfig
    from sim.footage import FootageCamera
    from sim.vehicle import SimVehicle


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``sim`` and its own sub-commands."""
    parser = sub.add_parser(
        "sim",
        help="simulator: MAVLink vehicle, synthetic scenes, dataset replay",
        description="The stand-in for the aircraft, its camera and the sea below.",
    )
    sim_sub = parser.add_subparsers(dest="sim_command", metavar="SIM_COMMAND", required=True)

    vehicle = sim_sub.add_parser(
        "vehicle",
        help="fly a mission as a MAVLink vehicle over UDP",
        description="Fly the synthetic flight of a mission file in real time (or faster) and "
        "speak MAVLink like an autopilot: telemetry streams, COMMAND_ACK, mission protocol.",
    )
    vehicle.add_argument(
        "--listen",
        default="udpin:127.0.0.1:14550",
        help="pymavlink connection string to serve (default: %(default)s)",
    )
    vehicle.add_argument(
        "--mission", default=None, help="mission file (TOML); default: the built-in maritime demo"
    )
    vehicle.add_argument(
        "--speedup",
        type=float,
        default=1.0,
        help="sim seconds per wall second (default: %(default)s)",
    )
    vehicle.add_argument("--seed", type=int, default=0)
    vehicle.add_argument(
        "--duration",
        type=positive_seconds,
        default=None,
        help="stop after this many wall-clock seconds (default: run until Ctrl-C)",
    )
    vehicle.set_defaults(func=_run_vehicle)
    add_generate_parser(sim_sub)
    add_replay_parser(sim_sub)
    from sarmission.commands.sim_score import add_score_parser

    add_score_parser(sim_sub)


def _run_vehicle(args: argparse.Namespace) -> int:
    from sim.vehicle import run_vehicle

    if args.speedup <= 0:
        raise ValueError(f"--speedup must be positive, got {args.speedup}")
    return run_vehicle(args.listen, args.mission, args.speedup, args.seed, args.duration)


def add_generate_parser(sim_sub: argparse._SubParsersAction) -> None:
    """Register ``sim generate``."""
    from sim.scenarios import PRESETS

    gen = sim_sub.add_parser(
        "generate",
        help="render a synthetic sequence with ground truth and telemetry",
        description="Render frames of a scenario seen from its survey flight and write them as MP4 "
        "(or an image folder) with a COCO video annotation file (boxes, track ids, each "
        "target's true latitude/longitude, per-frame telemetry in 'meta').",
    )
    gen.add_argument(
        "--scenario",
        default="maritime",
        help="maritime, urban, or a preset: "
        + ", ".join(sorted(PRESETS))
        + " (default: %(default)s = maritime_test)",
    )
    gen.add_argument("--frames", type=int, default=300, help="frames to render (default: 300)")
    gen.add_argument(
        "--size",
        type=parse_frame_size,
        default="3840x2160",
        help="WIDTHxHEIGHT (default: %(default)s)",
    )
    gen.add_argument(
        "--seed",
        type=non_negative_int,
        default=None,
        help="world and flight seed (default: the preset's own)",
    )
    gen.add_argument("--fps", type=positive_rate, default=30.0)
    gen.add_argument(
        "--start",
        type=non_negative_seconds,
        default=5.0,
        help="seconds into the flight of the first clip (default: %(default)s)",
    )
    gen.add_argument(
        "--sequences",
        type=int,
        default=1,
        help="clips to render along the flight, merged into one annotation file "
        "(default: %(default)s)",
    )
    gen.add_argument(
        "--spacing",
        type=float,
        default=15.0,
        help="seconds of flight between clip starts (default: %(default)s)",
    )
    gen.add_argument(
        "--images", action="store_true", help="write a JPEG image folder instead of an MP4 video"
    )
    gen.add_argument(
        "--mot", action="store_true", help="also write MOT ground truth (mot/<video>.txt)"
    )
    gen.add_argument(
        "--yolo", action="store_true", help="also write YOLO labels (yolo/<video>/<frame>.txt)"
    )
    gen.add_argument("--out", required=True, help="output folder")
    add_progress_option(gen)
    gen.set_defaults(func=_run_generate)


def _run_generate(args: argparse.Namespace) -> int:
    from sim.generate import generate_split

    name = {"maritime": "maritime_test", "urban": "urban_test"}.get(args.scenario, args.scenario)
    if args.frames < 1:
        raise ValueError(f"--frames must be at least 1, got {args.frames}")
    annotations = generate_split(
        name,
        args.sequences,
        args.frames,
        args.out,
        size=args.size,
        fps=args.fps,
        first_start_s=args.start,
        spacing_s=args.spacing,
        video=not args.images,
        seed=args.seed,
        progress=bars_wanted(args),
    )
    print(f"wrote {args.sequences} x {args.frames} frames of {name} -> {annotations}")
    if args.mot or args.yolo:
        from sarmission.data.coco_video import read_coco_video
        from sarmission.data.convert import write_mot_files, write_yolo_files

        dataset = read_coco_video(annotations)
        if args.mot:
            paths = write_mot_files(dataset, annotations.parent / "mot")
            print(f"wrote MOT ground truth: {', '.join(str(p) for p in paths)}")
        if args.yolo:
            count = write_yolo_files(dataset, annotations.parent / "yolo")
            print(f"wrote {count} YOLO label files under {annotations.parent / 'yolo'}")
    return 0


def add_replay_parser(sim_sub: argparse._SubParsersAction) -> None:
    """Register ``sim replay``."""
    from sarmission.commands.live_options import add_session_options
    from sarmission.commands.mission_options import add_mission_options

    rep = sim_sub.add_parser(
        "replay",
        help="play recorded footage through the simulated vehicle and camera into a live run",
        description="Play a video, an image folder or a COCO video annotation file as the "
        "simulated camera while the simulated vehicle (on the --connect port, as 'run --sim') "
        "streams the footage's own per-frame telemetry ('meta') over MAVLink - or, without "
        "usable meta, the mission's synthetic flight - and run the live mission controller on "
        "it until the footage ends. Reposition and ROI commands are answered "
        "MAV_RESULT_DENIED while following the footage's telemetry: recorded footage cannot be "
        "steered. Ground truth in the annotations scores the alerts.",
    )
    rep.add_argument(
        "footage",
        metavar="VIDEO_OR_FOLDER_OR_ANNOTATIONS_JSON",
        help="video file, image folder, or COCO video annotation file (.json)",
    )
    rep.add_argument(
        "--annotations",
        metavar="ANN.json",
        default=None,
        help="COCO video annotation file for a video or folder: per-frame meta "
        "telemetry and ground truth",
    )
    rep.add_argument(
        "--video-id",
        type=int,
        default=None,
        help="which video of the annotation file (default: the first)",
    )
    rep.add_argument(
        "--connect",
        required=True,
        metavar="URL",
        help="the controller's MAVLink connection string (udp:, udpin: or udpout:); "
        "the vehicle takes the other end, e.g. udp:127.0.0.1:14550",
    )
    rep.add_argument(
        "--speedup",
        type=float,
        default=1.0,
        help="sim seconds per wall second; frames are paired with telemetry "
        "exactly only at 1 (default: %(default)s)",
    )
    rep.add_argument(
        "--fps",
        type=positive_rate,
        default=None,
        help="frame rate of the footage; when given, frames are timed by "
        "frame index / fps instead of their meta time (default: the video's own "
        "rate, else the annotation file's, else 30)",
    )
    rep.add_argument(
        "--loop",
        action="store_true",
        help="start the footage (and its flight) again after the last frame; "
        "stop with Ctrl-C, --duration or --max-frames",
    )
    rep.add_argument("--seed", type=int, default=0, help="synthetic flight and telemetry seed")
    add_session_options(rep)
    add_mission_options(rep)
    rep.set_defaults(func=_run_replay)


def _run_replay(args: argparse.Namespace) -> int:
    from sarmission.commands.live_options import run_live, vehicle_url
    from sarmission.commands.mission_options import load_mission_from_args
    from sarmission.commands.truth_score import score
    from sim.footage import FootageCamera, FootageRenderer
    from sim.meta_flight import MetaFlight, NoUsableMeta
    from sim.vehicle import SimVehicle

    if args.speedup <= 0:
        raise ValueError(f"--speedup must be positive, got {args.speedup}")
    url = vehicle_url(args.connect)
    mission = load_mission_from_args(args)
    renderer = FootageRenderer(
        args.footage,
        fps=args.fps,
        annotations=args.annotations,
        video_id=args.video_id,
        loop=args.loop,
    )
    flight = None
    if renderer.dataset is None:
        print(
            "replay: no annotation file: telemetry from the mission's synthetic flight", flush=True
        )
    else:
        try:
            flight = MetaFlight(
                renderer.dataset,
                renderer.video_id,
                mission=mission,
                fps=renderer.fps,
                use_meta_time=args.fps is None,
                loop=args.loop,
                start_s=None,
            )
        except NoUsableMeta as exc:
            print(
                f"replay: {exc}; telemetry from the mission's synthetic flight instead", flush=True
            )
        else:
            mission = flight.mission
            print(f"replay: {flight.note}", flush=True)
    if args.speedup != 1.0:
        print(
            f"replay: speedup {args.speedup:g}: telemetry time runs apart from the frames' "
            "clock, so positions are only approximate",
            flush=True,
        )
    length = renderer.length
    print(
        f"replay: {renderer.path or 'dataset images'}: "
        f"{length if length is not None else 'unknown number of'} frames at "
        f"{renderer.fps:g} fps{', looping' if args.loop else ''}; vehicle on {url}",
        flush=True,
    )
    camera: FootageCamera | None = None

    def open_source(m: MissionConfig) -> tuple[FootageCamera, SimVehicle]:
        nonlocal camera
        vehicle = SimVehicle(
            url, m, speedup=args.speedup, seed=args.seed, stream_on_request=True, flight=flight
        ).start()
        try:
            camera = FootageCamera(vehicle, renderer=renderer, fps=renderer.fps * args.speedup)
        except BaseException:
            vehicle.stop()
            raise
        return camera, vehicle

    try:
        session = run_live(args, mission, open_source)
    finally:
        renderer.close()
    assert camera is not None
    shown = len(renderer.frames_shown)
    total = renderer.length
    print(
        f"replay: {len(camera.truth)} frames delivered, {shown} distinct footage frames "
        f"shown"
        + (f" of {total}" if total is not None else "")
        + (
            f" ({total - shown} passed while processing)"
            if total and not args.loop and total > shown
            else ""
        ),
        flush=True,
    )
    if renderer.has_ground_truth:
        for line in score(list(session.controller.stats.alerts), camera, mission.lock.m):
            print(line, flush=True)
    return 0
