"""The ``sarmission`` command line: one sub-command per job, each in ``sarmission.commands``."""

from __future__ import annotations

import argparse
import logging
import os
import sys
from collections.abc import Sequence

from sarmission import __version__
from sarmission.commands import COMMANDS
from sarmission.errors import SarmissionError


def build_parser() -> argparse.ArgumentParser:
    """Build the top-level parser with every sub-command registered."""
    parser = argparse.ArgumentParser(
        prog="sarmission",
        description="Onboard search-and-rescue: tiny-target detection on 4K video (MITE-Net), "
        "tracking, geolocation from MAVLink telemetry, alerts.",
    )
    parser.add_argument("--version", action="version", version=f"sarmission {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for module in COMMANDS:
        module.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``sarmission`` console script; returns the process exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    try:
        from sarmission.threads import apply_thread_plan

        apply_thread_plan()  # before any command loads its compute libraries
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("sarmission: interrupted", file=sys.stderr)
        return 130
    except (ValueError, OSError, SarmissionError) as exc:
        # Expected failures (bad files, bad arguments) carry a message written for the user.
        if os.environ.get("SARMISSION_DEBUG"):
            raise
        print(f"sarmission {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
