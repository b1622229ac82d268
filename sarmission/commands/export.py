"""``sarmission export``: write the head as ONNX (opset 17, variable number of proposals).

``--average A.pt B.pt`` exports the weighted mean of several heads' weights instead
(:mod:`sarmission.training.average`) and writes its ``.pt`` beside the ONNX file.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sarmission.commands.cli_helpers import check_output_path

#: ONNX opsets the export is known to write and onnxruntime to run (checked 9-23).
MIN_OPSET, MAX_OPSET = 9, 23


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the ``export`` sub-command."""
    parser = sub.add_parser(
        "export",
        help="export the head to ONNX",
        description="Export the MITE-Net head to ONNX (opset 17, dynamic proposal axis) and check "
        "that onnxruntime and torch agree on random crops.",
    )
    parser.add_argument(
        "--model",
        default=None,
        help="torch weights (.pt) or a shipped head's name (maritime, land); default: maritime",
    )
    parser.add_argument(
        "--average",
        nargs="+",
        type=Path,
        default=None,
        metavar="HEAD.pt",
        help="export the weighted mean of these heads' weights (two or more .pt files of one "
        "architecture and class list, fine-tuned from one head) instead of --model; the "
        "averaged .pt is written beside --out",
    )
    parser.add_argument(
        "--weights",
        default=None,
        help="with --average: one weight per head, comma-separated (default: equal)",
    )
    parser.add_argument("--out", default="mitenet_head.onnx", help="ONNX file to write")
    parser.add_argument("--opset", type=int, default=17)
    parser.set_defaults(func=run)


def _weights(text: str | None) -> list[float] | None:
    """``--weights`` as numbers (``ValueError`` naming the bad one)."""
    if text is None:
        return None
    values = []
    for part in text.split(","):
        try:
            values.append(float(part))
        except ValueError:
            raise ValueError(f"--weights: {part.strip()!r} is not a number") from None
    return values


def run(args: argparse.Namespace) -> int:
    """Export and verify."""
    from sarmission.models import default_model_path, is_head_name, shipped_head_path
    from sarmission.perception.export import export_head_onnx

    if args.weights is not None and args.average is None:
        raise ValueError("--weights needs --average")
    if not MIN_OPSET <= args.opset <= MAX_OPSET:
        raise ValueError(f"--opset must be {MIN_OPSET} to {MAX_OPSET}, got {args.opset}")
    inputs = {"--model": args.model} | {
        f"--average ({i + 1})": path for i, path in enumerate(args.average or [])
    }
    out = check_output_path(args.out, inputs, ".onnx")
    if args.average is not None:
        from sarmission.perception.runtime import save_head_checkpoint
        from sarmission.training.average import average_heads

        if args.model is not None:
            raise ValueError("--model and --average exclude each other")
        mean = out.with_suffix(".pt")  # the mean's checkpoint, written beside the ONNX
        if any(mean.resolve() == Path(path).resolve() for path in args.average):
            raise ValueError(
                f"--out {out}: the mean's checkpoint would go to {mean}, one of the heads "
                "averaged; write elsewhere"
            )
        model = save_head_checkpoint(average_heads(args.average, _weights(args.weights)), mean)
        print(f"wrote {model}: the mean of {len(args.average)} heads")
    else:
        model = args.model or default_model_path("torch")
        if is_head_name(model):
            model = shipped_head_path(model, "torch")
    print(export_head_onnx(model, out, opset=args.opset).summary())
    return 0
