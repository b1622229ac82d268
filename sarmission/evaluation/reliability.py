"""What a reported confidence means: a reliability table of scores against how often they were
right.

Scores are binned (by default at 0.5, 0.6, 0.7, 0.8, 0.9, 0.95); per bin the count, the mean
score and the share that was right. For a calibrated score the two agree; the expected
calibration error (ECE) is their count-weighted mean absolute difference. An operator reading
"swimmer 0.92" learns from the table how often 0.92 was a swimmer on data like this.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

#: Bin edges of the table (the first bin starts at the lowest score reported).
DEFAULT_EDGES = (0.0, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 1.0)
#: Bin edges for a calibrated probability, which spans the whole range.
PROBABILITY_EDGES = (0.0, 0.1, 0.3, 0.5, 0.7, 0.9, 1.0)


def reliability_table(
    scores: Sequence[float], correct: Sequence[bool], edges: Sequence[float] = DEFAULT_EDGES
) -> dict[str, Any]:
    """``{"bins": [{"low", "high", "n", "mean_score", "share_correct"}], "ece": float | None}``;
    empty bins are left out. Scores outside ``[edges[0], edges[-1]]`` are clipped into it."""
    s = np.clip(np.asarray(scores, dtype=float), edges[0], edges[-1])
    ok = np.asarray(correct, dtype=bool)
    if s.shape != ok.shape:
        raise ValueError(f"{s.size} scores but {ok.size} outcomes")
    index = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, len(edges) - 2)
    rows, gap = [], 0.0
    for k in range(len(edges) - 1):
        sel = index == k
        n = int(sel.sum())
        if not n:
            continue
        mean, share = float(s[sel].mean()), float(ok[sel].mean())
        gap += n * abs(mean - share)
        rows.append(
            {
                "low": float(edges[k]),
                "high": float(edges[k + 1]),
                "n": n,
                "mean_score": round(mean, 4),
                "share_correct": round(share, 4),
            }
        )
    return {"bins": rows, "ece": round(gap / s.size, 4) if s.size else None}


def format_reliability(table: dict[str, Any], what: str = "score") -> list[str]:
    """Text lines of a reliability table."""
    lines = [f"  {what:<14}{'n':>8}{'mean':>8}{'right':>8}"]
    for row in table["bins"]:
        lines.append(
            f"  {row['low']:.2f}-{row['high']:.2f}{'':<4}{row['n']:>8}"
            f"{row['mean_score']:>8.2f}{row['share_correct']:>8.2f}"
        )
    ece = table["ece"]
    lines.append(f"  expected calibration error: {'-' if ece is None else f'{ece:.3f}'}")
    return lines
