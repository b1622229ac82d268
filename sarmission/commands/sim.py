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
    add_generate_parser(sim_sub)


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
    gen.add_argument("--scenario", default="maritime",
                     help="maritime, urban, or a preset: " + ", ".join(sorted(PRESETS))
                     + " (default: %(default)s = maritime_test)")
    gen.add_argument("--frames", type=int, default=300, help="frames to render (default: 300)")
    gen.add_argument("--size", default="3840x2160", help="WIDTHxHEIGHT (default: %(default)s)")
    gen.add_argument("--seed", type=int, default=None,
                     help="world and flight seed (default: the preset's own)")
    gen.add_argument("--fps", type=float, default=30.0)
    gen.add_argument("--start", type=float, default=5.0,
                     help="seconds into the flight of the first clip (default: %(default)s)")
    gen.add_argument("--sequences", type=int, default=1,
                     help="clips to render along the flight, merged into one annotation file "
                     "(default: %(default)s)")
    gen.add_argument("--spacing", type=float, default=15.0,
                     help="seconds of flight between clip starts (default: %(default)s)")
    gen.add_argument("--images", action="store_true",
                     help="write a JPEG image folder instead of an MP4 video")
    gen.add_argument("--out", required=True, help="output folder")
    gen.set_defaults(func=_run_generate)


def _run_generate(args: argparse.Namespace) -> int:
    from sarmission.commands.bench import _size
    from sim.generate import generate_split

    name = {"maritime": "maritime_test", "urban": "urban_test"}.get(args.scenario, args.scenario)
    if args.frames < 1:
        raise ValueError(f"--frames must be at least 1, got {args.frames}")
    annotations = generate_split(
        name, args.sequences, args.frames, args.out, size=_size(args.size), fps=args.fps,
        first_start_s=args.start, spacing_s=args.spacing, video=not args.images, seed=args.seed)
    print(f"wrote {args.sequences} x {args.frames} frames of {name} -> {annotations}")
    return 0
