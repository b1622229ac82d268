"""One head from several: the weighted mean of their weights (``sarmission train --average``).

Heads fine-tuned from the same starting head on different data (the land recipe with and
without the alternative world's land) lie close enough in weight space that their weighted
mean is itself a working head, between the two in what it learnt: a single head of the same
size and speed, where an ensemble would run every head on every crop. The heads must share
architecture and classes (same order); batch-norm running statistics are averaged like the
weights, and integer buffers (batch counts) are taken from the first head.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from sarmission.perception.head import MiteHead
from sarmission.perception.runtime import load_head_checkpoint


class AverageError(ValueError):
    """The heads cannot be averaged (one line: which head and why)."""


def average_heads(paths: Sequence[str | Path], weights: Sequence[float] | None = None) -> MiteHead:
    """The head whose weights are the ``weights``-weighted mean of the heads at ``paths``.

    ``weights`` (default: equal) must be one finite non-negative number per head, not all 0;
    they are normalised to sum to 1. Raises :class:`AverageError` for fewer than two heads, a
    bad weight, or heads of different architecture or classes; a head that cannot be read
    raises :class:`~sarmission.perception.runtime.ModelLoadError`.
    """
    if len(paths) < 2:
        raise AverageError(f"averaging needs two heads or more, got {len(paths)}")
    weights = [1.0] * len(paths) if weights is None else [float(w) for w in weights]
    if len(weights) != len(paths):
        raise AverageError(f"{len(weights)} weights for {len(paths)} heads")
    if any(not (w >= 0.0 and w < float("inf")) for w in weights) or sum(weights) <= 0.0:
        raise AverageError(f"weights must be finite, non-negative and not all 0: {weights}")
    heads = [load_head_checkpoint(p) for p in paths]
    first = heads[0]
    for path, head in zip(paths[1:], heads[1:], strict=True):
        if head.config != first.config:
            raise AverageError(
                f"{path}: architecture or classes differ from {paths[0]} "
                f"({head.config.classes} vs {first.config.classes})"
            )
    total = sum(weights)
    states = [h.state_dict() for h in heads]
    merged = {}
    for key, value in states[0].items():
        if value.is_floating_point():
            merged[key] = sum(
                (w / total) * s[key].double() for w, s in zip(weights, states, strict=True)
            ).to(value.dtype)
        else:
            merged[key] = value.clone()
    out = MiteHead(first.config)
    out.load_state_dict(merged)
    out.eval()
    return out
