"""Several trained heads as one ONNX head that averages their class probabilities.

For studies only: it asks whether the heads' disagreement is noise an average removes, or
whether they share their mistakes. It runs every member on every crop (N times the cost of
one head), which the detector's budget does not allow; a head that is shipped stays one head
(weight averages of heads fine-tuned from one start: ``sarmission export --average``)::

    python tools/ensemble_head.py --out /tmp/three.onnx A.pt B.pt C.pt
    python tools/heldout_eval.py ... --model /tmp/three.onnx

The members must share their configuration (classes, crop size); the output keeps the
sarmission ONNX format (metadata of the first member), with class logits the logit of the
mean probability and boxes the mean of the members' boxes.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))


def ensemble_module(paths: list[Path]):
    """A torch module over the heads at ``paths``: ``crops -> (cls_logits, ltrb)``."""
    import torch
    from torch import nn

    from sarmission.perception.runtime import ModelLoadError, load_head_checkpoint

    heads = [load_head_checkpoint(p) for p in paths]
    first = heads[0].config.to_dict()
    for path, head in zip(paths[1:], heads[1:], strict=True):
        if head.config.to_dict() != first:
            raise ModelLoadError(f"{path}: its configuration differs from {paths[0]}'s")

    class Ensemble(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.members = nn.ModuleList(heads)
            self.config = heads[0].config

        def forward(self, crops: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
            outs = [member(crops) for member in self.members]
            p = torch.stack([torch.sigmoid(o[0]) for o in outs]).mean(0)
            p = p.clamp(1e-6, 1 - 1e-6)
            return torch.log(p / (1 - p)), torch.stack([o[1] for o in outs]).mean(0)

    return Ensemble().eval()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("heads", nargs="+", type=Path, help="two or more head checkpoints (.pt)")
    parser.add_argument("--out", type=Path, required=True, help="ONNX file to write")
    args = parser.parse_args(argv)
    from sarmission.perception.runtime import ModelLoadError

    if len(args.heads) < 2:
        print("error: an ensemble needs two heads or more", file=sys.stderr)
        return 2
    try:
        module = ensemble_module(args.heads)
    except ModelLoadError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    from sarmission.perception.export import head_onnx_bytes

    args.out.write_bytes(head_onnx_bytes(module))
    print(f"wrote {args.out}: the mean of {len(args.heads)} heads")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
