"""``sarmission info``: parameters and FLOPs per stage (the paper's Table 4 columns)."""

from __future__ import annotations

import argparse

from sarmission.commands.cli_helpers import parse_frame_size
from sarmission.perception.types import VALID_DS


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the ``info`` sub-command."""
    parser = sub.add_parser(
        "info",
        help="parameters and FLOPs per stage",
        description="Print the head's parameter count and the FLOPs per frame of each stage "
        "(vSTMD, the rest of the RPN with the crops, the head) for the given frame size, ds and N.",
    )
    parser.add_argument(
        "--size",
        type=parse_frame_size,
        default=(3840, 2160),
        help="frame size WIDTHxHEIGHT (default: 3840x2160)",
    )
    parser.add_argument("--ds", type=int, choices=VALID_DS, default=2)
    parser.add_argument("--topn", type=int, default=25)
    parser.add_argument(
        "--model",
        default=None,
        help="head weights (default: the shipped model, else an untrained head)",
    )
    parser.add_argument(
        "--ego-motion",
        choices=("estimate", "none"),
        default="estimate",
        help="count vSTMD's ego-motion compensation (default: %(default)s)",
    )
    parser.add_argument("--json", action="store_true", help="print JSON")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Print parameters and FLOPs."""
    import json

    from sarmission.perception.mitenet import MiteNet, build_head_runtime

    net = MiteNet(
        build_head_runtime(args.model, "torch"),
        ds=args.ds,
        topn=args.topn,
        ego_motion=args.ego_motion,
    )
    width, height = args.size
    report = net.complexity(height, width)
    if args.json:
        print(json.dumps(report, indent=2))
        return 0
    print(f"MITE-Net at {width}x{height}, ds={args.ds}, N={args.topn}")
    print(f"  head parameters: {report['parameters']['head']:,}")
    print(f"  {'stage':<22}{'GFLOPs/frame':>14}")
    labels = {
        "vstmd": "TTM-RPN: vSTMD",
        "rpn_other": "TTM-RPN: others",
        "head": "R-CNN-like head",
        "total": "total",
    }
    for key, label in labels.items():
        print(f"  {label:<22}{report['flops'][key] / 1e9:>14.4f}")
    return 0
