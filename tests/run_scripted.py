"""``sarmission run`` with the blob detector and the dot scene, for tests that need a separate
process (killed and restarted). Usage: ``python tests/run_scripted.py TARGETS_JSON RUN_ARGS...``
where ``TARGETS_JSON`` is a list of ``[north, east]`` ground points."""

import json
import sys

from dot_scene import DotRenderer
from scripted_detector import BlobDetector

from sarmission.cli import build_parser
from sarmission.commands import run as run_command
from sarmission.commands.mission_options import load_mission_from_args


def main(argv: list[str]) -> int:
    targets = [tuple(p) for p in json.loads(argv[0])]
    args = build_parser().parse_args(["run", *argv[1:]])
    mission = load_mission_from_args(args)
    renderer = DotRenderer(targets, mission.camera.intrinsics(), mission.area.home)
    return run_command.run(args, detector=BlobDetector(), renderer=renderer)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
