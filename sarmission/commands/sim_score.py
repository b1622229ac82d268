"""``sarmission sim score``: fly the scenario suite through the real MAVLink path and score the
confirmed alerts against the simulator's truth.

Each scenario of :mod:`sim.suite` is flown by the simulated vehicle over loopback UDP, filmed by
its camera at 30 frames/s in real time, and run through :class:`~sarmission.mission.live.
LiveSession` with the mission ``run`` uses (the built-in defaults unless ``--mission`` /
``--set`` / detector options say otherwise), the suite setting only the area, flight and lens.
One table: people in view (>= 3 s), found, false alerts (and per hour of flight), time from
first view to alert (p50, p90), geolocation error (p50, p95); ``--json`` for tools.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from sarmission.commands.cli_helpers import positive_seconds
from sarmission.commands.mission_options import add_mission_options

if TYPE_CHECKING:
    from sarmission.evaluation.alert_scoring import FlightScore
    from sarmission.mission.config import MissionConfig
    from sim.suite import ObliqueScenario, SuiteScenario


def add_score_parser(sim_sub: argparse._SubParsersAction) -> None:
    """Register ``sim score``."""
    from sim.suite import DEVELOPMENT, OBLIQUE, SUITE

    score = sim_sub.add_parser(
        "score",
        help="fly the scenario suite over MAVLink and score the alerts",
        description="Fly each scenario of the suite (seeded seas, people among boats, birds, "
        "debris and glint, none of them seen in training) through the simulated vehicle and "
        "the real onboard pipeline, and score the confirmed alerts: people found, false "
        "alerts per hour, time to alert, geolocation error.",
    )
    score.add_argument(
        "--scenarios",
        default=None,
        metavar="NAME[,NAME...]",
        help="run only these (default: the suite, "
        + ", ".join(s.name for s in SUITE)
        + "; also the development flights, "
        + ", ".join(s.name for s in DEVELOPMENT)
        + ", and the oblique flights, "
        + ", ".join(s.name for s in OBLIQUE)
        + ")",
    )
    score.add_argument(
        "--seconds",
        type=positive_seconds,
        default=None,
        help="fly each scenario this long instead of its own duration",
    )
    score.add_argument("--json", action="store_true", help="print the figures as JSON")
    add_mission_options(score)
    score.set_defaults(func=run)


@dataclass
class Flown:
    """One scenario flown: its score, the session's summary, and what tools look into: the
    controller (candidates, evidence) and the camera's ground truth per frame."""

    score: FlightScore
    summary: str
    controller: Any
    truth: list[Any]


def fly(
    scenario: SuiteScenario | ObliqueScenario,
    base: MissionConfig,
    detector: Any,
    seconds: float,
    workdir: Path,
) -> Flown:
    """One scenario through the live pipeline (see :class:`Flown`)."""
    from sarmission.commands.cli_helpers import free_udp_port
    from sarmission.evaluation.alert_scoring import score_flight
    from sarmission.mission.live import LiveSession
    from sim.camera import SimCamera
    from sim.suite import SIZE
    from sim.vehicle import SimVehicle

    mission = scenario.mission(base)
    port = free_udp_port()
    detector.reset()
    vehicle = SimVehicle(
        f"udpout:127.0.0.1:{port}", mission, seed=scenario.seed, stream_on_request=True
    ).start()
    try:
        camera = SimCamera(vehicle, scenario=scenario.scenario(mission), size=SIZE, fps=30.0)
        session = LiveSession(
            mission,
            detector,
            camera,
            f"udpin:127.0.0.1:{port}",
            str(workdir / f"{scenario.name}.db"),
            transport_latency_s=mission.telemetry.latency_s,
            connect_timeout_s=10.0,
            console=lambda line: None,
        )
        try:
            session.run(duration_s=seconds)
        finally:
            confirmed = list(session.controller.stats.confirmed)
            stored = session.store.list()
            summary = session.close()
    finally:
        vehicle.stop()
    truth = camera.truth
    alerts = [
        (alert, index, truth[index].sim_time)
        for alert, index, _ in confirmed
        if 0 <= index < len(truth)
    ]
    evidence = session.controller.candidates.evidence
    track_scores = {
        a.alert_id: float(np.mean([x.score for x in evidence[a.target_id].sightings]))
        for a in stored
        if a.target_id in evidence and evidence[a.target_id].sightings
    }
    return Flown(
        score_flight(
            truth,
            alerts,
            candidates=stored,
            track_scores=track_scores,
            final={a.alert_id: a for a in stored},
            position_frames=session.controller.stats.position_frames,
            sent_frames=session.controller.stats.confirmed_position_frames,
        ),
        summary,
        session.controller,
        truth,
    )


#: The columns after the first of :func:`table_header`.
COLUMNS = (
    "flight min",
    "people in view",
    "found",
    "false alerts",
    "false per hour",
    "duplicate alerts",
    "time to alert p50 / p90 s",
    "geolocation error p50 / p95 m",
    "at the end p50 / p95 m",
    "within 2x its error (alert / end)",
)


def table_header(first: str, columns: tuple[str, ...] = COLUMNS) -> list[str]:
    """A markdown table's header lines: ``first`` (one column, or several joined by " | "),
    then ``columns``."""
    return [
        "| " + " | ".join((first, *columns)) + " |",
        "|" + "---|" * (first.count("|") + 1 + len(columns)),
    ]


def table_row(name: str, d: dict[str, Any], minutes: bool = True) -> str:
    """One row of :data:`COLUMNS` (without "flight min" unless ``minutes``) from
    :meth:`FlightScore.as_dict`'s figures; figures an older file lacks read "-"."""

    def num(v: float | None, spec: str = ".1f") -> str:
        return "-" if v is None else format(v, spec)

    def pair(key: str, a: str, b: str) -> str:
        got = d.get(key) or {}
        return f"{num(got.get(a))} / {num(got.get(b))}"

    def share(v: float | None) -> str:
        return "-" if v is None else f"{100 * v:.0f} %"

    within = d.get("geo_within_2x") or {}
    found = d["found_share"]
    cells = [
        *([f"{d['flight_s'] / 60:.1f}"] if minutes else []),
        str(d["people_in_view"]),
        f"{d['found']} ({'-' if found is None else f'{100 * found:.0f} %'})",
        str(d["false_alerts"]),
        num(d["false_per_hour"]),
        num(d.get("duplicates"), "d"),
        pair("time_to_alert_s", "p50", "p90"),
        pair("geo_error_m", "p50", "p95"),
        pair("geo_error_final_m", "p50", "p95"),
        f"{share(within.get('at_alert'))} / {share(within.get('final'))}",
    ]
    return "| " + " | ".join((name, *cells)) + " |"


def table(rows: list[tuple[str, FlightScore]]) -> str:
    """The scores as a markdown table, one row per scenario and the suite's total."""
    lines = table_header("scenario")
    lines += [table_row(name, s.as_dict()) for name, s in rows]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from sarmission.commands.mission_options import build_detector, load_mission_from_args
    from sarmission.evaluation.alert_scoring import FlightScore
    from sarmission.evaluation.reliability import format_reliability
    from sim.suite import suite

    names = [n.strip() for n in args.scenarios.split(",")] if args.scenarios else None
    scenarios = suite(names)
    base = load_mission_from_args(args)
    detector, note = build_detector(args, base)
    if not args.json:
        print(note, flush=True)
    rows: list[tuple[str, FlightScore]] = []
    total = FlightScore()
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="sarmission-score-") as tmp:
        for scenario in scenarios:
            seconds = args.seconds or scenario.duration_s
            if not args.json:
                print(f"{scenario.name}: {seconds:.0f} s of flight ...", flush=True)
            score = fly(scenario, base, detector, seconds, Path(tmp)).score
            score.missed = [f"{scenario.name}: {m}" for m in score.missed]
            rows.append((scenario.name, score))
            total.add(score)
    rows.append(("suite", total))
    if args.json:
        print(
            json.dumps(
                {
                    "scenarios": {n: s.as_dict() for n, s in rows[:-1]},
                    "suite": total.as_dict(),
                    "wall_s": round(time.monotonic() - started, 1),
                },
                indent=2,
            )
        )
    else:
        print(table(rows))
        if total.false_on:
            print(
                "false alerts on: "
                + ", ".join(f"{what} {n}" for what, n in total.false_on.most_common())
            )
        print("What a candidate's track score means (share with a person under it):")
        figures = total.as_dict()
        print("\n".join(format_reliability(figures["candidate_reliability"], "track score")))
        if figures["alert_confidence_reliability"]["bins"]:
            print(
                "What an alert's confidence means (share with a person under it; nobody decides "
                "on the suite's alerts, so this is the confidence before any operator decision):"
            )
            print(
                "\n".join(format_reliability(figures["alert_confidence_reliability"], "confidence"))
            )
        if total.missed:
            print(f"missed ({len(total.missed)}):")
            for line in total.missed:
                print(f"  {line}")
    return 0
