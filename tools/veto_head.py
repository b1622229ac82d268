"""One head's scores for people, another's names for everything else, as one ONNX head.

For studies: the class heads (``--classes maritime``) tell buoys and debris from people better
than the shipped head, but score people at another level on every renderer, so one threshold
does not serve both (docs/mooring_buoys.md). Here the two jobs are kept apart: the *scorer*
(the shipped head) gives the person classes' probabilities, the *namer* (a class head) the
probabilities of its other classes, and the detector's usual rule (the most probable class
names the crop) decides::

    python tools/veto_head.py --scorer sarmission/models/mitenet_head.pt \\
        --namer W/mitenet_head_buoys.pt --out /tmp/veto.onnx [--gate]
    python tools/heldout_eval.py ... --model /tmp/veto.onnx

``--gate`` also zeroes the person probabilities where the namer's own most probable class is
not a person (each head compared with itself, whatever their score levels). The output has the
namer's classes and the scorer's boxes; both heads run on every crop (twice one head's cost).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))


def veto_module(scorer_path: Path, namer_path: Path, gate: bool):
    """A torch module ``crops -> (cls_logits, ltrb)`` over the two heads (see the docstring)."""
    import torch
    from torch import nn

    from sarmission.class_roles import role_of
    from sarmission.perception.runtime import ModelLoadError, load_head_checkpoint

    scorer, namer = load_head_checkpoint(scorer_path), load_head_checkpoint(namer_path)
    shared = ("in_channels", "crop_size")
    for key in shared:
        if getattr(scorer.config, key) != getattr(namer.config, key):
            raise ModelLoadError(f"{namer_path}: its {key} differs from {scorer_path}'s")
    person_in_namer = [i for i, c in enumerate(namer.config.classes) if role_of(c) == "person"]
    try:
        person_in_scorer = [
            scorer.config.classes.index(namer.config.classes[i]) for i in person_in_namer
        ]
    except ValueError:
        raise ModelLoadError(
            f"{scorer_path}: it does not name every person class of {namer_path}"
        ) from None
    others = [i for i in range(len(namer.config.classes)) if i not in person_in_namer]
    if not others:
        raise ModelLoadError(f"{namer_path}: it names people only, nothing to veto with")

    class Veto(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.scorer, self.namer = scorer, namer
            self.config = namer.config

        def forward(self, crops: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
            scored, ltrb = self.scorer(crops)
            named, _ = self.namer(crops)
            logits = named.clone()
            people = scored[:, person_in_scorer]
            if gate:
                own_person = named[:, person_in_namer].max(dim=1).values
                own_other = named[:, others].max(dim=1).values
                people = torch.where((own_other > own_person)[:, None], people - 1e4, people)
            logits[:, person_in_namer] = people
            return logits, ltrb

    return Veto().eval()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--scorer", type=Path, required=True, help="head giving people's scores")
    parser.add_argument("--namer", type=Path, required=True, help="class head naming the rest")
    parser.add_argument("--gate", action="store_true", help="the namer vetoes by its own verdict")
    parser.add_argument("--out", type=Path, required=True, help="ONNX file to write")
    args = parser.parse_args(argv)
    from sarmission.perception.runtime import ModelLoadError

    try:
        module = veto_module(args.scorer, args.namer, args.gate)
    except ModelLoadError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    from sarmission.perception.export import head_onnx_bytes

    args.out.write_bytes(head_onnx_bytes(module))
    rule = "gated by the namer's own verdict" if args.gate else "most probable class"
    print(f"wrote {args.out}: people by {args.scorer.name}, the rest by {args.namer.name} ({rule})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
