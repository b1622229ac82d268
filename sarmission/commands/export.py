"""``sarmission export``: write the head as ONNX (opset 17, variable number of proposals)."""

from __future__ import annotations

import argparse


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
    parser.add_argument("--out", default="mitenet_head.onnx", help="ONNX file to write")
    parser.add_argument("--opset", type=int, default=17)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Export and verify."""
    from sarmission.models import default_model_path, is_head_name, shipped_head_path
    from sarmission.perception.export import export_head_onnx

    model = args.model or default_model_path("torch")
    if is_head_name(model):
        model = shipped_head_path(model, "torch")
    report = export_head_onnx(model, args.out, opset=args.opset)
    print(f"wrote {args.out}: {report}")
    return 0
