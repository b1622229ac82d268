"""Confirmation rules compared on the same evidence: fly the development scenarios once, then
replay every candidate's sightings frame by frame through each rule.

    python tools/confirmation_rules.py [--record F.json] [--seconds 240] [--model HEAD] [--jobs 2]
        [--variant NAME:KEY=VALUE,KEY=VALUE ...] [--doc docs/confirmation_rules.md]

A flight keeps each candidate's whole evidence (sightings go on after its verdict), the times
of the frames the controller reviewed and the truth under it at its lock (as in
``tools/candidate_features.py``; never the scored suite). ``--record`` keeps that as JSON, and
a later run with the same file replays without flying. Each variant is the defaults with
``[confirm]`` keys changed; its candidates are judged by :func:`assess` itself, once per
reviewed frame from the candidate's lock on, until a verdict. The defaults' replay must give
the flight's own verdicts: a replay that disagrees is reported, and its figures mean nothing.

Printed: per variant, candidates with a person under them and how many were confirmed, clutter
candidates and how many were confirmed (false alerts), and time from lock to confirmation. A
confirmed alert sends the simulated drone to look, so a rule that confirms other candidates
would have flown a slightly different path: the figures are a ranking, not a suite result.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import shlex
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for folder in (ROOT, ROOT / "tools"):  # runnable from a checkout that is not installed
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

from alert_suite import head_commit  # noqa: E402

from sarmission.mission.candidates import CandidateBook  # noqa: E402
from sarmission.mission.config import ConfirmConfig  # noqa: E402
from sarmission.mission.config_rules import confirm_problem  # noqa: E402
from sarmission.mission.confirmation import Sighting, TargetEvidence, assess  # noqa: E402


@dataclasses.dataclass
class Recorded:
    """One candidate as flown: whether a person was under it at its lock, the flight's verdict,
    the time of its first review, its first sighting and all its sightings."""

    person: bool
    verdict: str
    first_review: float
    first_seen: float
    sightings: list[Sighting]


@contextmanager
def recording() -> Iterator[dict]:
    """While flying: the times ``CandidateBook.review`` ran (every processed frame) and, per
    book and target, the first review after the candidate was added."""
    seen: dict = {"frames": [], "first_review": {}}
    pending: list[tuple[int, int]] = []
    review, add = CandidateBook.review, CandidateBook.add

    def recording_review(book, now, when=None, **options):
        seen["frames"].append(now)
        for key in pending:
            seen["first_review"].setdefault(key, now)
        pending.clear()
        return review(book, now, when, **options)

    def recording_add(book, target_id, alert):
        pending.append((id(book), target_id))
        return add(book, target_id, alert)

    CandidateBook.review, CandidateBook.add = recording_review, recording_add
    try:
        yield seen
    finally:
        CandidateBook.review, CandidateBook.add = review, add


def fly_development(scenarios: list[str], seconds: float, model: str | None = None) -> dict:
    """Fly ``scenarios`` with the defaults (the head file ``model`` if given) and keep every
    candidate's evidence (see module)."""
    from candidate_features import development_detector, under_lock

    from sarmission.commands.sim_score import fly
    from sarmission.mission.config import load_mission
    from sim.suite import suite

    base = load_mission(None, [])
    detector = development_detector(base, model)
    flights = []
    with tempfile.TemporaryDirectory() as tmp:
        for scenario in suite(scenarios):
            with recording() as seen:
                flown = fly(scenario, base, detector, seconds, Path(tmp))
            book = flown.controller.candidates
            by_index = {f.index: f for f in flown.truth}
            confirmed = {a.target_id for a, _, _ in flown.controller.stats.confirmed}
            candidates = []
            for alert in flown.controller.stats.candidates:
                under = under_lock(by_index, alert)
                evidence = book.evidence.get(alert.target_id, TargetEvidence())
                if alert.target_id in confirmed:
                    verdict = "confirm"
                elif alert.target_id in book.candidates:
                    verdict = "wait"
                else:
                    verdict = "discard"
                candidates.append(
                    {
                        "target": alert.target_id,
                        "person": under == "person",
                        "under": under,
                        "verdict": verdict,
                        "first_review": seen["first_review"].get((id(book), alert.target_id)),
                        "first_seen": evidence.first_seen,
                        "sightings": [dataclasses.astuple(s) for s in evidence.sightings],
                    }
                )
            flights.append(
                {"scenario": scenario.name, "frames": seen["frames"], "candidates": candidates}
            )
            print(
                f"{scenario.name}: {len(candidates)} candidates, "
                f"{sum(c['person'] for c in candidates)} on people",
                flush=True,
            )
    return {"seconds": seconds, "model": model, "flights": flights}


def recorded(record: dict) -> Iterator[tuple[list[float], Recorded]]:
    """Each candidate of ``record`` with the reviewed frame times of its flight."""
    for flight in record["flights"]:
        for c in flight["candidates"]:
            if c["first_review"] is None:  # added in the flight's last frame: never reviewed
                continue
            yield (
                flight["frames"],
                Recorded(
                    bool(c["person"]),
                    c["verdict"],
                    c["first_review"],
                    c["first_seen"],
                    [Sighting(*s) for s in c["sightings"]],
                ),
            )


def catch_up(evidence: TargetEvidence, sightings: list[Sighting], taken: int, now: float) -> int:
    """One reviewed frame at ``now``: the recorded ``sightings`` from index ``taken`` captured
    by then join ``evidence``, and the frame counts; returns how many are taken now."""
    while taken < len(sightings) and sightings[taken].t <= now:
        evidence.sightings.append(sightings[taken])
        taken += 1
    if not math.isnan(evidence.first_seen):
        evidence.frames += 1
    return taken


def replay(frames: list[float], candidate: Recorded, rule: ConfirmConfig) -> tuple[str, float]:
    """The verdict ``rule`` gives ``candidate`` reviewed at ``frames`` from its first review on,
    and the time from that review to it (``wait``: none fell before the flight ended)."""
    evidence = TargetEvidence(first_seen=candidate.first_seen)
    taken = 0
    for now in frames:
        if now < candidate.first_review:
            continue
        taken = catch_up(evidence, candidate.sightings, taken, now)
        found = assess(evidence, now, rule)
        if found.verdict != "wait":
            return found.verdict, now - candidate.first_review
    return "wait", math.nan


def variant(text: str) -> tuple[str, ConfirmConfig]:
    """``NAME:KEY=VALUE,...`` as the default rule with those keys changed."""
    name, _, changes = text.partition(":")
    rule = ConfirmConfig()
    fields = {f.name: f.type for f in dataclasses.fields(ConfirmConfig)}
    for change in filter(None, changes.split(",")):
        key, _, value = change.partition("=")
        if key not in fields:
            raise SystemExit(f"error: unknown [confirm] key {key!r} in {text!r}")
        try:
            setattr(rule, key, int(value) if fields[key] in ("int", int) else float(value))
        except ValueError:
            raise SystemExit(f"error: {key} expects a number, got {value!r}") from None
    problem = confirm_problem(rule)
    if problem is not None:
        raise SystemExit(f"error: [confirm] {problem[0]} in {text!r}: {problem[1]}")
    return name, rule


def compare_one(record: dict, name: str, rule: ConfirmConfig) -> dict:
    """The row of one variant (see module)."""
    is_default = rule == ConfirmConfig()
    people = clutter = found = false = 0
    delays: list[float] = []
    disagree = 0
    for frames, candidate in recorded(record):
        verdict, delay = replay(frames, candidate, rule)
        if is_default and verdict != candidate.verdict:
            disagree += 1
        people += candidate.person
        clutter += not candidate.person
        if verdict == "confirm":
            found += candidate.person
            false += not candidate.person
            if candidate.person:
                delays.append(delay)
    return {
        "variant": name,
        "people": people,
        "people confirmed": found,
        "clutter": clutter,
        "clutter confirmed": false,
        "delay p50": float(np.median(delays)) if delays else math.nan,
        "delay p90": float(np.percentile(delays, 90)) if delays else math.nan,
        "disagree": disagree if is_default else None,
    }


def compare(record: dict, variants: list[tuple[str, ConfirmConfig]], jobs: int = 1) -> list[dict]:
    """One row per variant, in their order; ``jobs`` > 1 replays that many variants at once
    in processes of their own, since each replays every candidate frame by frame."""
    if jobs <= 1 or len(variants) <= 1:
        return [compare_one(record, name, rule) for name, rule in variants]
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=min(jobs, len(variants))) as pool:
        futures = [pool.submit(compare_one, record, name, rule) for name, rule in variants]
        return [f.result() for f in futures]


def table(rows: list[dict]) -> str:
    head = "| variant | people confirmed | clutter confirmed | lock to confirmation p50 / p90 s |"
    lines = [head, "|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['variant']} | {r['people confirmed']} of {r['people']} | "
            f"{r['clutter confirmed']} of {r['clutter']} | "
            f"{r['delay p50']:.1f} / {r['delay p90']:.1f} |"
        )
    return "\n".join(lines)


def page(rows: list[dict], record: dict, command: str) -> str:
    """The comparison as a Markdown page with the command and commit that made it."""
    scenarios = ", ".join(f["scenario"] for f in record["flights"])
    head = f"the head {record['model']}" if record.get("model") else "the shipped head"
    return "\n".join(
        [
            "# Confirmation rules on the development flights",
            "",
            f"Generated by `{command}` at {head_commit()}. The development scenarios "
            f"({scenarios}; never the scored suite), {record['seconds']:g} s each, flown once "
            "with the defaults; every candidate's whole evidence is then replayed frame by "
            "frame through each rule (`[confirm]` keys as given, the rest the defaults), "
            f"with {head}. A "
            "candidate is a person's when a person was under it at its lock. A confirmed "
            "alert sends the simulated drone to look, so another rule would have flown a "
            "slightly different path: a ranking, not a suite result (docs/alert_suite.md).",
            "",
            table(rows),
            "",
        ]
    )


def main() -> int:
    from sim.suite import DEVELOPMENT

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenarios", default=",".join(s.name for s in DEVELOPMENT))
    parser.add_argument("--seconds", type=float, default=240.0)
    parser.add_argument("--record", type=Path, default=None, help="evidence JSON, kept/reused")
    parser.add_argument("--variant", action="append", default=[], help="NAME:KEY=VALUE,...")
    parser.add_argument("--doc", type=Path, default=None, help="write the table as a page")
    parser.add_argument("--model", default=None, help="head weights (default: the shipped head)")
    parser.add_argument("--jobs", type=int, default=1, help="variants replayed at once")
    args = parser.parse_args()
    variants = [("defaults", ConfirmConfig()), *map(variant, args.variant)]
    if args.record and args.record.exists():
        record = json.loads(args.record.read_text())
    else:
        record = fly_development(args.scenarios.split(","), args.seconds, args.model)
        if args.record:
            args.record.write_text(json.dumps(record))
    rows = compare(record, variants, args.jobs)
    print(table(rows))
    disagree = rows[0]["disagree"]
    if disagree:
        print(f"warning: the defaults' replay disagrees with the flight on {disagree} candidates")
        return 1
    if args.doc:
        args.doc.write_text(
            page(
                rows,
                record,
                "python tools/confirmation_rules.py "
                + " ".join(shlex.quote(a) for a in sys.argv[1:]),
            )
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
