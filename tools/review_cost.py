"""What reviewing the undecided candidates costs per frame, measured side by side in one process.

    python tools/review_cost.py --record F.json [--block 20] [--repeats 3]

Every processed frame the controller assesses each undecided candidate
(:meth:`~sarmission.mission.candidates.CandidateBook.review`). Most of them are clutter that
has not been seen again, and the figures of their sightings (a drift fit over hundreds of
them, medians, the mean score) have not changed since the last frame; the evidence keeps them
until its sightings change (:meth:`~sarmission.mission.confirmation.TargetEvidence.figures`).
This replays a development record (``tools/confirmation_rules.py --record``: every
candidate's sightings and the flight's reviewed frame times) frame by frame with the defaults,
assessing every candidate still undecided, as the controller does: in alternating blocks of
frames, with the figures kept between frames or fitted again on every call, so both see the
same candidates, clock and neighbours. Prints, per flight and in all, the median and 95th
percentile of the review's time per frame (microseconds), their ratio, and the candidates
assessed per frame, as a markdown table.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for folder in (ROOT, ROOT / "tools"):  # runnable from a checkout that is not installed
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

from confirmation_rules import catch_up, recorded  # noqa: E402

from sarmission.mission.config import ConfirmConfig  # noqa: E402
from sarmission.mission.confirmation import TargetEvidence, assess  # noqa: E402


def review_times(
    frames: list[float], candidates: list, rule: ConfirmConfig, block: int
) -> dict[str, list[float]]:
    """Microseconds per reviewed frame with the figures ``kept`` and ``refitted``, and the
    candidates assessed in each (``count``), over one flight's ``frames``."""
    evidence = [TargetEvidence(first_seen=c.first_seen) for c in candidates]
    taken = [0] * len(candidates)
    open_ = set(range(len(candidates)))
    out: dict[str, list[float]] = {"kept": [], "refitted": [], "count": []}
    for index, now in enumerate(frames):
        mode = "kept" if (index // block) % 2 == 0 else "refitted"
        due = [i for i in open_ if candidates[i].first_review <= now]
        for i in due:
            taken[i] = catch_up(evidence[i], candidates[i].sightings, taken[i], now)
        started = time.perf_counter()
        for i in due:
            if mode == "refitted":
                evidence[i]._figures = None
            if assess(evidence[i], now, rule).verdict != "wait":
                open_.discard(i)
        out[mode].append((time.perf_counter() - started) * 1e6)
        out["count"].append(len(due))
    return out


def row(name: str, times: dict[str, list[float]]) -> str:
    kept, refitted = times["kept"], times["refitted"]
    ratio = statistics.median(refitted) / statistics.median(kept)
    return (
        f"| {name} | {statistics.median(kept):.0f} / {np.percentile(kept, 95):.0f} | "
        f"{statistics.median(refitted):.0f} / {np.percentile(refitted, 95):.0f} | "
        f"{ratio:.1f} | {statistics.mean(times['count']):.1f} |"
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--record", required=True, type=Path, help="a development record")
    parser.add_argument("--block", type=int, default=20, help="frames per block of one mode")
    parser.add_argument("--repeats", type=int, default=3, help="measurements, each printed")
    args = parser.parse_args(argv)
    try:
        record = json.loads(args.record.read_text())
    except (OSError, ValueError) as exc:
        parser.error(f"cannot read the record {args.record}: {exc}")
    if args.block < 1:
        parser.error("--block must be at least 1")
    rule = ConfirmConfig()
    flights = [
        (flight["scenario"], flight["frames"], [c for _, c in recorded({"flights": [flight]})])
        for flight in record["flights"]
    ]
    for repeat in range(args.repeats):
        print(f"\nrun {repeat + 1} of {args.repeats}")
        print("| flight | kept us p50 / p95 | refitted us p50 / p95 | ratio | candidates |")
        print("|---|---|---|---|---|")
        total: dict[str, list[float]] = {"kept": [], "refitted": [], "count": []}
        for name, frames, candidates in flights:
            times = review_times(frames, candidates, rule, args.block)
            for key in total:
                total[key] += times[key]
            print(row(name, times), flush=True)
        print(row("all", total), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
