"""``sarmission sim ...``: the simulator (MAVLink vehicle, scene generation, dataset replay)."""

from __future__ import annotations

import argparse


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
    vehicle.add_argument("--listen", default="udpin:127.0.0.1:14550",
                         help="pymavlink connection string to serve (default: %(default)s)")
    vehicle.add_argument("--mission", default=None,
                         help="mission file (TOML); default: the built-in maritime demo")
    vehicle.add_argument("--speedup", type=float, default=1.0,
                         help="sim seconds per wall second (default: %(default)s)")
    vehicle.add_argument("--seed", type=int, default=0)
    vehicle.add_argument("--duration", type=float, default=None,
                         help="stop after this many wall-clock seconds (default: run until Ctrl-C)")
    vehicle.set_defaults(func=_run_vehicle)


def _run_vehicle(args: argparse.Namespace) -> int:
    from sim.vehicle import run_vehicle

    if args.speedup <= 0:
        raise ValueError(f"--speedup must be positive, got {args.speedup}")
    return run_vehicle(args.listen, args.mission, args.speedup, args.seed, args.duration)
