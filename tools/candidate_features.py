"""What tells a person from clutter in a candidate's evidence? Features of every candidate on the
development scenarios (never the suite), with its truth, to choose the confirmation's
thresholds from.

    python tools/candidate_features.py [--scenarios dev_calm,...] [--seconds 120] [--csv F]

For each candidate: whether a person was under it at its lock, its sightings, the time they
span, the share of frames it was seen in over that span, the head's scores (mean, better half,
lowest), its size across the line of sight (median, quartiles), its drift over the ground, how
much its look changed over a second (median over its sightings, :mod:`sarmission.perception.look`)
and the verdict the current rule gave it. Printed: the quantiles of each feature for people, for
clutter and for the clutter confirmed (the false alerts), with what lay under the clutter.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np

from sarmission.commands.mission_options import build_detector
from sarmission.commands.sim_score import fly
from sarmission.evaluation.alert_scoring import nearest
from sarmission.mission import candidates as candidate_book
from sarmission.mission.config import load_mission
from sarmission.mission.confirmation import TargetEvidence, drift_speed
from sim.suite import DEVELOPMENT, suite

FEATURES = (
    "decided_s",
    "sightings",
    "span_s",
    "seen_share",
    "score_mean",
    "score_top",
    "score_min",
    "score_std",
    "score_high",
    "size_m",
    "size_p25",
    "size_p75",
    "speed_m_s",
    "speed_sigma",
    "look_change",
)


def features(evidence, fps: float) -> dict[str, float]:
    s = evidence.sightings
    if not s:
        return {k: math.nan for k in FEATURES}
    decided = s[-1].t - evidence.first_seen
    span = s[-1].t - s[0].t
    scores = sorted((x.score for x in s), reverse=True)
    sizes = [x.size_m for x in s if x.size_m is not None]
    speed, sigma = drift_speed(s) if len(s) >= 3 else (math.nan, math.nan)
    look = evidence.figures(0.0).look_change  # the rule's own figure
    return {
        "decided_s": decided,
        "sightings": len(s),
        "span_s": span,
        "seen_share": len(s) / (span * fps + 1.0),
        "score_mean": float(np.mean(scores)),
        "score_top": float(np.mean(scores[: max(1, len(scores) // 2)])),
        "score_min": scores[-1],
        "score_std": float(np.std(scores)),
        "score_high": float(np.mean([x >= 0.9 for x in scores])),
        "size_m": float(np.median(sizes)) if sizes else math.nan,
        "size_p25": float(np.percentile(sizes, 25)) if sizes else math.nan,
        "size_p75": float(np.percentile(sizes, 75)) if sizes else math.nan,
        "speed_m_s": speed,
        "speed_sigma": sigma,
        "look_change": math.nan if look is None else look,
    }


class VerdictRecorder:
    """Remembers how many sightings each candidate had when its verdict fell, so that its
    features are those the rule saw (evidence keeps growing after the verdict)."""

    def __init__(self) -> None:
        self.sightings: dict[int, int] = {}  # id(evidence) -> sightings at the verdict
        self._assess = candidate_book.assess
        candidate_book.assess = self._recording

    def _recording(self, evidence, now, rule):
        found = self._assess(evidence, now, rule)
        if found.verdict != "wait":
            self.sightings.setdefault(id(evidence), len(evidence.sightings))
        return found

    def at_verdict(self, evidence: TargetEvidence) -> TargetEvidence:
        """``evidence`` as it stood at its verdict (all of it if none fell)."""
        n = self.sightings.get(id(evidence), len(evidence.sightings))
        return TargetEvidence(evidence.sightings[:n], evidence.first_seen, evidence.frames)


def development_detector(base, model: str | None = None):
    """The detector with the tools' defaults (ONNX, estimated ego-motion): the shipped head, or
    the head file ``model``."""
    detector_args = argparse.Namespace(model=model, runtime="onnx", ego_motion="estimate")
    detector, _ = build_detector(detector_args, base)
    return detector


def under_lock(truth_by_index: dict, alert) -> str:
    """What lay under ``alert`` at its lock (truth frames by index): "person", another
    object's category, or "water"."""
    frame = truth_by_index.get(alert.frame_index)
    if frame is None:
        return "water"
    cx, cy = alert.pixel_track[-1][1:]
    if nearest(frame.targets, cx, cy) is not None:
        return "person"
    other = nearest(frame.others, cx, cy)
    return other.category if other else "water"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenarios", default=",".join(s.name for s in DEVELOPMENT))
    parser.add_argument("--seconds", type=float, default=120.0)
    parser.add_argument("--csv", type=Path, default=None)
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    args = parser.parse_args()
    base = load_mission(None, args.overrides)
    detector = development_detector(base)
    rows = []
    recorder = VerdictRecorder()
    with tempfile.TemporaryDirectory() as tmp:
        for scenario in suite(args.scenarios.split(",")):
            flown = fly(scenario, base, detector, args.seconds, Path(tmp))
            by_index = {f.index: f for f in flown.truth}
            book = flown.controller.candidates
            confirmed = {a.target_id for a, _, _ in flown.controller.stats.confirmed}
            for alert in flown.controller.stats.candidates:
                under = under_lock(by_index, alert)
                row = {
                    "scenario": scenario.name,
                    "target": alert.target_id,
                    "person": int(under == "person"),
                    "under": under,
                }
                row.update(
                    features(recorder.at_verdict(book.evidence[alert.target_id]), 30.0)
                    if alert.target_id in book.evidence
                    else {k: math.nan for k in FEATURES}
                )
                row["verdict"] = "confirmed" if alert.target_id in confirmed else "candidate"
                rows.append(row)
            recorder.sightings.clear()
            print(
                f"{scenario.name}: {len(flown.controller.stats.candidates)} candidates, "
                f"score {flown.score.as_dict()['found']} found, "
                f"{flown.score.false_alerts} false",
                flush=True,
            )
    if args.csv:
        with open(args.csv, "w", newline="") as out:
            writer = csv.DictWriter(out, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    groups = (
        ("people", lambda r: r["person"] == 1),
        ("clutter", lambda r: r["person"] == 0),
        (
            "clutter confirmed (false alerts)",
            lambda r: r["person"] == 0 and r["verdict"] == "confirmed",
        ),
    )
    for label, keep in groups:
        sel = [r for r in rows if keep(r)]
        under = ", ".join(f"{k} {n}" for k, n in Counter(r["under"] for r in sel).most_common())
        print(f"\n{label}: {len(sel)} candidates ({under})")
        for k in FEATURES:
            v = np.array([r[k] for r in sel], dtype=float)
            v = v[np.isfinite(v)]
            if v.size:
                q = np.percentile(v, [5, 25, 50, 75, 95])
                print(f"  {k:12s} " + " ".join(f"{x:7.2f}" for x in q))
    return 0


if __name__ == "__main__":
    sys.exit(main())
