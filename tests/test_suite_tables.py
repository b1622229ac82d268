"""The suite's tables (``sarmission sim score`` and ``tools/alert_suite.py render``) show the
duplicate alerts: a second alert for a person already alerted is a cost to the rescue team
that neither the found nor the false count shows."""

from __future__ import annotations

import json

from conftest import load_tool

from sarmission.commands.sim_score import table
from sarmission.evaluation.alert_scoring import FlightScore


def _cells(line: str) -> list[str]:
    return [c.strip() for c in line.strip().strip("|").split("|")]


def test_sim_score_table_has_a_duplicates_column() -> None:
    score = FlightScore(flight_s=240.0, people_in_view=3, found=2, alerts=5, duplicates=2)
    header, _, row = table([("calm", score)]).splitlines()
    cells = dict(zip(_cells(header), _cells(row), strict=True))
    assert cells["duplicate alerts"] == "2"
    assert cells["found"] == "2 (67 %)"


def test_alert_suite_page_shows_each_runs_duplicates(tmp_path) -> None:
    tool = load_tool("alert_suite")
    figures = FlightScore(flight_s=240.0, people_in_view=4, found=3, duplicates=3).as_dict()
    run = {"label": "dups", "note": "three", "command": "x", "commit": "abc"}
    (tmp_path / "dups.json").write_text(
        json.dumps({"run": run, "scenarios": {"calm": figures}, "suite": figures})
    )
    lines = tool.render(tmp_path).splitlines()
    header = next(line for line in lines if line.startswith("| run |"))
    row = next(line for line in lines if line.startswith("| dups |"))
    assert dict(zip(_cells(header), _cells(row), strict=True))["duplicate alerts"] == "3"
    scenario_header = next(line for line in lines if line.startswith("| scenario |"))
    calm = next(line for line in lines if line.startswith("| calm |"))
    assert dict(zip(_cells(scenario_header), _cells(calm), strict=True))["duplicate alerts"] == "3"
