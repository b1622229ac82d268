"""``sarmission run --connect URL``: the live mission - camera in, alerts out to the autopilot
and the operator - until the source ends, a limit is reached, or Ctrl-C / SIGTERM."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from sarmission.commands.cli_helpers import parse_frame_size, positive_rate
from sarmission.commands.live_options import add_session_options, run_live, vehicle_url
from sarmission.commands.mission_options import add_mission_options, load_mission_from_args

if TYPE_CHECKING:
    from sarmission.mission.config import MissionConfig
    from sarmission.mission.controller import Detector
    from sarmission.mission.live_sources import LiveSource


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``run``."""
    parser = sub.add_parser(
        "run",
        help="fly a live mission: camera -> MITE-Net -> lock -> geolocation -> alerts",
        description="Connect to the autopilot (own HEARTBEAT as an onboard controller, telemetry "
        "streams requested), run the detector on the camera, store every confirmed target "
        "durably and announce it per the mission's action policy. A restart with the same "
        "--alerts-db resumes without re-announcing known targets.",
    )
    parser.add_argument(
        "--connect",
        required=True,
        metavar="URL",
        help="autopilot MAVLink connection string (pymavlink), e.g. "
        "udp:127.0.0.1:14550, tcp:127.0.0.1:5760, /dev/ttyACM0",
    )
    src = parser.add_mutually_exclusive_group(required=True)
    src.add_argument(
        "--video",
        metavar="PATH|URL",
        help="play a video file as the camera, or read a live stream: "
        "rtsp://HOST/PATH, udp://IP:PORT (MPEG-TS), ...",
    )
    src.add_argument("--frames", metavar="DIR", help="play an image folder as the camera")
    src.add_argument("--camera", type=int, metavar="N", help="camera device N (OpenCV)")
    src.add_argument(
        "--sim",
        action="store_true",
        help="start the simulated vehicle on the --connect port and use its camera",
    )
    parser.add_argument(
        "--fps",
        type=positive_rate,
        default=30.0,
        help="frame rate of --frames (and of a video without one; default: %(default)s)",
    )
    add_session_options(parser)
    sim = parser.add_argument_group("simulator (--sim)")
    sim.add_argument(
        "--sim-size",
        type=parse_frame_size,
        default=None,
        metavar="WxH",
        help="simulated frame size (default: the mission camera's)",
    )
    sim.add_argument(
        "--sim-fps",
        type=float,
        default=None,
        help="most simulated frames per second (default: as fast as processed)",
    )
    sim.add_argument("--sim-seed", type=int, default=0, help="scenario and flight seed")
    sim.add_argument(
        "--sim-corrupt-every",
        type=int,
        default=0,
        metavar="N",
        help="deliver every N-th simulated frame truncated (sensor glitch)",
    )
    add_mission_options(parser)
    parser.set_defaults(func=run)


def _open_source(
    args: argparse.Namespace, mission: MissionConfig, renderer: Any
) -> tuple[LiveSource, Any]:
    """The frame source and, for --sim, the started simulated vehicle."""
    from sarmission.mission.live_sources import CameraSource, FileSource, open_video_source

    if args.video:
        return open_video_source(args.video, args.fps), None
    if args.frames:
        return FileSource(args.frames, args.fps), None
    if args.camera is not None:
        return CameraSource(args.camera), None
    from sim.camera import SimCamera
    from sim.vehicle import SimVehicle

    vehicle = SimVehicle(
        vehicle_url(args.connect), mission, seed=args.sim_seed, stream_on_request=True
    ).start()
    try:
        camera = SimCamera(
            vehicle,
            renderer=renderer,
            size=args.sim_size,
            fps=args.sim_fps,
            corrupt_every=args.sim_corrupt_every,
        )
    except BaseException:
        vehicle.stop()
        raise
    return camera, vehicle


def run(
    args: argparse.Namespace,
    detector: Detector | None = None,
    renderer: Any = None,
    console: Callable[[str], None] | None = None,
) -> int:
    """Run the live mission of ``args``. ``detector`` replaces MITE-Net and ``renderer`` the
    simulator's scene renderer when given (tests)."""
    mission = load_mission_from_args(args)
    run_live(args, mission, lambda m: _open_source(args, m, renderer), detector, console)
    return 0
