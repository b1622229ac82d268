"""Fit the alert confidence of a head on the development flights -> its .confidence.json, docs.

    python tools/fit_confidence.py [--record F.json] [--out PATH] [--doc docs/confidence.md]

The development flights (``sim.suite.DEVELOPMENT``, never the scored suite) are flown once with
the defaults by ``tools/confirmation_rules.py`` (``--record`` keeps and reuses them). Every
candidate is replayed through the default confirmation to its verdict; the sightings it had
then, and whether a person was under it, are one sample when the confirmation judged it on its
score (enough sightings over ``min_seen_s``: where alerts come from). A confirmed alert's
confidence is computed from exactly that evidence (:mod:`sarmission.mission.confidence`).

Two feature sets are compared by leaving one flight out at a time (fitted on the others,
predicted on it): the mean score alone, and with the share of sightings called each person
class after the first (a life jacket). Printed and written to the page: log-loss, and the
reliability of the predictions over all candidates and over those the confirmation confirmed
(what an operator sees). The chosen set is fitted on every flight and written to ``--out``;
the page then shows, from the runs labelled :data:`LABEL` (``python tools/alert_suite.py fly
confidence``, ``python tools/heldout_alerts.py fly confidence [--split validation]`` with the
model beside the head), how far it carries to worlds it was not fitted on.
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for folder in (ROOT, ROOT / "tools"):  # runnable from a checkout that is not installed
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

from alert_suite import head_commit, reliability_markdown  # noqa: E402
from confirmation_rules import fly_development, recorded, replay  # noqa: E402

from sarmission.class_roles import role_of  # noqa: E402
from sarmission.evaluation.reliability import PROBABILITY_EDGES, reliability_table  # noqa: E402
from sarmission.mission.confidence import (  # noqa: E402
    ConfidenceModel,
    confidence_beside,
    fit_confidence,
)
from sarmission.mission.config import ConfirmConfig  # noqa: E402
from sarmission.mission.confirmation import Sighting  # noqa: E402
from sarmission.models import DEFAULT_TORCH_MODEL  # noqa: E402
from sim.suite import DEVELOPMENT  # noqa: E402

DOC = ROOT / "docs" / "confidence.md"
L2 = 0.1


def samples(record: dict) -> list[tuple[int, list[Sighting], bool, bool]]:
    """``(flight, sightings at the verdict, person, confirmed)`` per candidate of ``record`` the
    confirmation judged on its score: one with enough sightings over ``min_seen_s`` (alerts
    come from these; the rest, clutter that flickered for a moment, would teach the model
    nothing about them)."""
    rule = ConfirmConfig()
    out = []
    for k, flight in enumerate(record["flights"]):
        for frames, candidate in recorded({"flights": [flight]}):
            verdict, delay = replay(frames, candidate, rule)
            until = math.inf if verdict == "wait" else candidate.first_review + delay
            seen = [s for s in candidate.sightings if s.t <= until]
            if len(seen) >= rule.min_sightings and seen[-1].t - seen[0].t >= rule.min_seen_s:
                out.append((k, seen, candidate.person, verdict == "confirm"))
    return out


def head_classes() -> tuple[str, ...]:
    from sarmission.perception.mitenet import build_head_runtime

    return build_head_runtime(None, "torch").classes


def weighted_classes(classes: tuple[str, ...]) -> list[str]:
    """The classes whose share the model weighs: the person classes after the first."""
    return [c for c in classes[1:] if role_of(c) == "person"]


def leave_one_flight_out(
    data: list[tuple[int, list[Sighting], bool, bool]],
    classes: tuple[str, ...],
    weighted: list[str],
) -> np.ndarray:
    """Each sample's confidence from a model fitted on the other flights."""
    predicted = np.zeros(len(data))
    for flight in sorted({d[0] for d in data}):
        train = [(s, y) for f, s, y, _ in data if f != flight]
        model = fit_confidence(train, classes, weighted, L2)
        for k, (f, s, _, _) in enumerate(data):
            if f == flight:
                predicted[k] = model.probability(s)
    return predicted


def log_loss(p: np.ndarray, y: np.ndarray) -> float:
    p = np.clip(p, 1e-6, 1 - 1e-6)
    return float(-np.mean(y * np.log(p) + (1 - y) * np.log(1 - p)))


def reliability_rows(table: dict) -> list[str]:
    return reliability_markdown(table, ("confidence", "targets", "mean confidence"), 1)


def page(results: list[dict], model: ConfidenceModel, data: list, out: Path, command: str) -> str:
    people = sum(d[2] for d in data)
    confirmed = [d for d in data if d[3]]
    lines = [
        "# What an alert's confidence means",
        "",
        f"Generated by `{command}` at {head_commit()} (`tools/fit_confidence.py`; its "
        "docstring says how). The head's score is no probability (the reliability tables of "
        "docs/alert_suite.md). A confirmed alert carries a calibrated confidence when a model "
        "lies beside its head (`sarmission/mission/confidence.py`; the maritime head's ships, "
        "its level learnt per mission from the operator's decisions, last section): a "
        "logistic model of its evidence, here fitted on the "
        f"development flights ({', '.join(s.name for s in DEVELOPMENT)}; never the scored "
        f"suite): the {len(data)} candidates the confirmation judged on their score (enough "
        f"sightings over its `min_seen_s`), {people} of them on a person; "
        f"{len(confirmed)} confirmed by the defaults, {sum(d[2] for d in confirmed)} of those "
        "on a person. Each feature set is judged on flights it was not fitted on (one left out "
        "at a time); the figures on the suite and on held-out footage are in "
        "docs/alert_suite.md and docs/heldout_alerts.md.",
        "",
        "| features | log-loss, judged candidates | calibration error, judged | "
        "calibration error, confirmed |",
        "|---|---|---|---|",
    ]
    for r in results:
        lines.append(
            f"| {r['name']} | {r['log_loss']:.4f} | {r['all']['ece']:.3f} | "
            f"{r['confirmed']['ece']:.3f} |"
        )
    for r in results:
        lines += [
            "",
            f"## {r['name']}: the confirmed candidates, each predicted by a model fitted "
            "without its flight",
            "",
            *reliability_rows(r["confirmed"]),
        ]
    weights = ", ".join(f"{c} share {w:+.2f}" for c, w in model.class_weights.items())
    lines += [
        "",
        f"## Fitted on every development flight: `{out.name}`",
        "",
        f"Bias {model.bias:+.2f}, logit of the mean score {model.score_weight:+.2f}"
        + (f", {weights}" if weights else "")
        + f". Flown beside the head as `{LABEL}` (its confidence on every confirmed alert), "
        "it is judged on worlds it was not fitted on (the model alone, as flown before the "
        "mission's calibration came):",
        "",
        *carried(),
        "Alone, it would mislead. The share of people among what the head confirms depends on "
        "how much clutter a scene holds: the simulator's seas are thick with debris the head "
        "calls a swimmer, the held-out generator's are not, and the model learnt the "
        "simulator's share. On held-out footage it called most confirmed alerts a few percent "
        "likely while most were people: an operator would be told to pass over them. So it "
        "ships only with the mission's calibration (`sarmission/alerts/"
        "operator_calibration.py`): its log-odds are kept, their level is learnt from the "
        "operator's decisions on the mission's alerts, and until those say enough the "
        "confidence is shown with its wide range. How that fares on the same footage: "
        "docs/confidence_adaptation.md.",
        "",
    ]
    return "\n".join(lines)


#: The label of the runs that flew the fitted model (docs/suite, docs/heldout_alerts).
LABEL = "confidence"
#: Where those runs keep their figures: the scenario suite and the held-out replays.
CARRIED = (
    ("the scenario suite, the simulator's own worlds", ROOT / "docs" / "suite"),
    ("held-out validation clips", ROOT / "docs" / "heldout_alerts" / "validation"),
    ("held-out test clips", ROOT / "docs" / "heldout_alerts"),
)


def carried() -> list[str]:
    """The confirmed alerts' confidence against what lay under them, from each run named
    :data:`LABEL` (none yet: a line saying so)."""
    lines: list[str] = []
    for what, folder in CARRIED:
        path = folder / f"{LABEL}.json"
        if not path.is_file():
            lines += [f"- {what}: not flown yet (`{LABEL}`).", ""]
            continue
        figures = json.loads(path.read_text())
        table = figures["suite"]["alert_confidence_reliability"]
        alerts = sum(b["n"] for b in table["bins"])
        people = sum(round(b["n"] * b["share_correct"]) for b in table["bins"])
        mean = sum(b["n"] * b["mean_score"] for b in table["bins"]) / alerts
        lines += [
            f"- {what} (`{figures['run']['command']}` at {figures['run']['commit']}): "
            f"{alerts} confirmed alerts, {people} on a person ({100 * people / alerts:.0f} %); "
            f"their mean confidence {100 * mean:.0f} %:",
            "",
            *reliability_rows(table),
            "",
        ]
    return lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--record", type=Path, default=None, help="evidence JSON, kept/reused")
    parser.add_argument("--seconds", type=float, default=240.0)
    parser.add_argument(
        "--out",
        type=Path,
        required=True,
        help="the model file to write; a head uses it when it lies beside the head as "
        f"<head stem>.confidence.json (e.g. {confidence_beside(DEFAULT_TORCH_MODEL).name})",
    )
    parser.add_argument("--doc", type=Path, default=DOC)
    args = parser.parse_args()
    if args.record and args.record.exists():
        record = json.loads(args.record.read_text())
    else:
        record = fly_development([s.name for s in DEVELOPMENT], args.seconds)
        if args.record:
            args.record.write_text(json.dumps(record))
    classes = head_classes()
    data = samples(record)
    y = np.array([d[2] for d in data], float)
    confirmed = np.array([d[3] for d in data])
    results = []
    for name, weighted in (
        ("mean score", []),
        ("mean score and class shares", weighted_classes(classes)),
    ):
        p = leave_one_flight_out(data, classes, weighted)
        results.append(
            {
                "name": name,
                "weighted": weighted,
                "log_loss": log_loss(p, y),
                "all": reliability_table(p, y.astype(bool), PROBABILITY_EDGES),
                "confirmed": reliability_table(
                    p[confirmed], y[confirmed].astype(bool), PROBABILITY_EDGES
                ),
            }
        )
        print(f"{name}: log-loss {results[-1]['log_loss']:.4f}, confirmed", flush=True)
        print("\n".join(reliability_rows(results[-1]["confirmed"])), flush=True)
    best = min(results, key=lambda r: r["log_loss"])
    scenarios = ", ".join(f["scenario"] for f in record["flights"])
    model = fit_confidence(
        [(d[1], d[2]) for d in data],
        classes,
        best["weighted"],
        L2,
        fitted_on=f"development flights {scenarios} ({len(data)} candidates, "
        f"{int(y.sum())} on a person), tools/fit_confidence.py at {head_commit()}",
    )
    args.out.write_text(model.to_json() + "\n")
    print(f"wrote {args.out} ({best['name']})")
    command = "python tools/fit_confidence.py " + " ".join(shlex.quote(a) for a in sys.argv[1:])
    args.doc.write_text(page(results, model, data, args.out, command.strip()))
    print(f"wrote {args.doc}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
