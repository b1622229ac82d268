"""``sarmission demo``: a short maritime search against the simulated vehicle over real UDP,
scored against the simulator's ground truth."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sarmission.commands.cli_helpers import (
    free_udp_port,
    parse_frame_size,
    positive_seconds,
    rate_or_zero,
)
from sarmission.commands.detector_options import add_detector_options
from sarmission.commands.truth_score import score

if TYPE_CHECKING:
    from sarmission.mission.config import MissionConfig

DEMO_MISSION = Path(__file__).resolve().parents[2] / "missions" / "maritime_demo.toml"
#: The demo's shortened survey: two 160 m legs 40 m apart (frames 960 px wide at 35 deg cover
#: about 44 m across the track).
DEMO_OVERRIDES = {
    "area.rectangle_m": [90.0, -80.0, 150.0, 80.0],
    "area.leg_spacing_m": 40.0,
    "flight.takeoff": False,
}
#: What the demo does with a confirmed target by default (see add_parser).
DEMO_ACTIONS = ("alert",)


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``demo``."""
    parser = sub.add_parser(
        "demo",
        help="short simulated maritime search over real UDP, scored against ground truth",
        description="Starts the simulated vehicle on a free loopback UDP port and its camera, "
        "runs the mission controller against it (MAVLink telemetry, alerts, ROI commands), "
        "then compares the alerts with the simulator's truth: people found vs in view, "
        "geolocation error of each alert, false alerts. Writes demo.rrd and alerts.db.",
    )
    parser.add_argument(
        "--out",
        default="demo_out",
        help="output folder for demo.rrd and alerts.db (default: %(default)s)",
    )
    parser.add_argument(
        "--duration",
        type=positive_seconds,
        default=None,
        help="seconds of flight (default: the whole shortened survey)",
    )
    parser.add_argument(
        "--size",
        type=parse_frame_size,
        default="960x540",
        help="frame size WxH (default: %(default)s)",
    )
    parser.add_argument(
        "--hfov",
        type=float,
        default=35.0,
        help="horizontal field of view in degrees; narrow keeps swimmers about "
        "10 px wide at 70 m in small frames (default: %(default)s)",
    )
    parser.add_argument(
        "--fps",
        type=rate_or_zero,
        default=30.0,
        help="most camera frames per second, as a real camera delivers them "
        "(the motion front-end is tuned for 30); 0: as fast as processed "
        "(default: %(default)s)",
    )
    parser.add_argument("--seed", type=int, default=0, help="scenario seed (default: 0)")
    parser.add_argument(
        "--actions",
        type=parse_actions,
        default=DEMO_ACTIONS,
        metavar="A[,A...]",
        help="what to do with a confirmed target: alert (STATUSTEXT), roi "
        "(point the camera at it for [actions] roi_hold_s, the search paused "
        "meanwhile), loiter, mission (default: alert)",
    )
    add_detector_options(parser)
    parser.set_defaults(func=run)


def parse_actions(text: str) -> tuple[str, ...]:
    """``"alert,roi"`` -> ``("alert", "roi")``; an argparse error for an unknown action."""
    from sarmission.mission.config import ACTION_POLICIES

    actions = tuple(a.strip() for a in text.split(",") if a.strip())
    unknown = [a for a in actions if a not in ACTION_POLICIES]
    if not actions or unknown:
        raise argparse.ArgumentTypeError(
            f"expected a comma-separated list of {', '.join(ACTION_POLICIES)}; got {text!r}"
        )
    return actions


def demo_mission(size: tuple[int, int], hfov: float, args: argparse.Namespace) -> MissionConfig:
    """The maritime demo mission, shortened, with the demo's camera and detector settings."""
    from sarmission.mission.config import load_mission

    overrides: dict[str, Any] = dict(DEMO_OVERRIDES)
    overrides.update(
        {
            "camera.width": size[0],
            "camera.height": size[1],
            "camera.hfov_deg": hfov,
            "detector.ds": args.ds,
            "detector.topn": args.topn,
            "detector.colour_share": args.colour_share,
            "actions.policy": list(args.actions),
            "detector.crop_scales": list(args.crop_scales),
            "detector.refine_threshold": args.refine_threshold,
            "detector.recentre": args.recentre,
            "detector.orientations": args.orientations,
            "detector.fit_boxes": args.fit_boxes,
            "detector.score_threshold": args.conf,
        }
    )
    return load_mission(DEMO_MISSION if DEMO_MISSION.is_file() else None, overrides)


def run(args: argparse.Namespace) -> int:
    from sarmission.commands.mission_options import build_detector
    from sarmission.mission.live import LiveSession
    from sarmission.viz.recorder import Recorder
    from sim.camera import SimCamera, mission_scenario
    from sim.vehicle import SimVehicle

    size = args.size
    mission = demo_mission(size, args.hfov, args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    db = out / "alerts.db"
    for stale in (db, out / "alerts.db-wal", out / "alerts.db-shm"):
        stale.unlink(missing_ok=True)  # each demo starts a fresh search
    detector, note = build_detector(args, mission)
    print(note, flush=True)
    port = free_udp_port()
    vehicle = SimVehicle(
        f"udpout:127.0.0.1:{port}", mission, seed=args.seed, stream_on_request=True
    ).start()
    duration = args.duration or vehicle.flight.survey_duration
    print(
        f"demo: mission '{mission.name}' shortened to {vehicle.flight.survey_duration:.0f} s "
        f"of flight at {mission.flight.altitude_m:.0f} m, {size[0]}x{size[1]} frames at "
        f"{args.hfov:g} deg HFOV; vehicle on udp 127.0.0.1:{port}",
        flush=True,
    )
    try:
        camera = SimCamera(
            vehicle,
            scenario=mission_scenario(vehicle, seed=args.seed),
            size=size,
            fps=args.fps or None,
        )
        session = LiveSession(
            mission,
            detector,
            camera,
            f"udpin:127.0.0.1:{port}",
            str(db),
            recorder=Recorder("save", out / "demo.rrd"),
            transport_latency_s=mission.telemetry.latency_s,
            connect_timeout_s=10.0,
            console=lambda line: print(line, flush=True),
        )
        started = time.monotonic()
        try:
            session.run(duration_s=duration)
        finally:
            alerts = list(session.controller.stats.alerts)
            summary = session.close()
        wall = time.monotonic() - started
    finally:
        vehicle.stop()
    print("\n== demo summary ==")
    print(summary)
    print(
        f"wall time {wall:.0f} s; simulator received {len(vehicle.statustexts)} STATUSTEXT, "
        f"{len(vehicle.commands)} commands"
    )
    for line in score(alerts, camera, mission.lock.m):
        print(line)
    print(f"wrote {out / 'demo.rrd'} and {db}")
    return 0
