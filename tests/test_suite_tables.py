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


def test_oblique_flights_fly_the_presets_views_in_worlds_of_their_own() -> None:
    from sarmission.mission.config import MissionConfig
    from sim.scenarios import preset
    from sim.suite import OBLIQUE, SIZE, SUITE, suite

    base = MissionConfig()
    seeds = {s.seed for s in SUITE}
    for flight in suite([s.name for s in OBLIQUE]):
        chosen = preset(flight.preset)
        mission = flight.mission(base)
        assert mission.camera.mount_pitch_deg == chosen.mission.camera.mount_pitch_deg
        assert (mission.camera.width, mission.camera.height) == SIZE
        assert mission.flight.altitude_m == chosen.mission.flight.altitude_m
        assert mission.confirm == base.confirm  # the defaults judge the alerts
        world = flight.scenario(mission)
        assert world.figures == "upright"
        assert world.seed == flight.seed != chosen.scenario.seed
        assert flight.seed not in seeds
    pitches = sorted(-preset(s.preset).mission.camera.mount_pitch_deg for s in OBLIQUE)
    assert pitches == [11.0, 36.0, 71.0]


def test_the_oblique_page_names_its_rows_flights(tmp_path) -> None:
    tool = load_tool("alert_suite")
    figures = FlightScore(flight_s=120.0, people_in_view=7, found=5).as_dict()
    run = {"label": "after", "note": "n", "command": "x", "commit": "abc"}
    (tmp_path / "after.json").write_text(
        json.dumps({"run": run, "scenarios": {"oblique_low": figures}, "suite": figures})
    )
    lines = tool.render(tmp_path, tool.OBLIQUE_INTRO, "flight").splitlines()
    assert lines[0] == "# Alerts in oblique views"
    assert any(line.startswith("| flight | flight min |") for line in lines)
    assert any(line.startswith("| oblique_low | 2.0 | 7 | 5 (71 %)") for line in lines)
    assert any(line.startswith("| **all** |") for line in lines)


def test_tables_show_the_position_at_the_end_and_its_honesty_and_read_older_files(
    tmp_path,
) -> None:
    """Both tables give the geolocation error as the alert went out and at the flight's end,
    and how often the truth lay within twice the alert's error; a run file written before
    those figures existed reads "-" there (and still has as many cells as the header)."""
    score = FlightScore(
        flight_s=120.0,
        people_in_view=2,
        found=2,
        geo_error_m=[20.0, 4.0],
        geo_error_final_m=[6.0, 2.0],
        geo_within_2x=[False, True],
        geo_within_2x_final=[True, True],
    )
    header, rule, row = table([("low", score)]).splitlines()
    cells = dict(zip(_cells(header), _cells(row), strict=True))
    assert rule.count("---") == len(_cells(header))
    assert cells["geolocation error p50 / p95 m"] == "12.0 / 19.2"
    assert cells["at the end p50 / p95 m"] == "4.0 / 5.8"
    assert cells["within 2x its error (alert / end)"] == "50 % / 100 %"
    tool = load_tool("alert_suite")
    old = score.as_dict()
    for key in ("geo_error_final_m", "geo_within_2x"):
        del old[key]
    run = {"label": "old", "note": "before", "command": "x", "commit": "abc"}
    (tmp_path / "old.json").write_text(
        json.dumps({"run": run, "scenarios": {"low": old}, "suite": old})
    )
    lines = tool.render(tmp_path).splitlines()
    header = next(line for line in lines if line.startswith("| run |"))
    rule = lines[lines.index(header) + 1]
    row = next(line for line in lines if line.startswith("| old |"))
    cells = dict(zip(_cells(header), _cells(row), strict=True))
    assert rule.count("---") == len(_cells(header))
    assert cells["at the end p50 / p95 m"] == "- / -"
    assert cells["within 2x its error (alert / end)"] == "- / -"
    assert cells["geolocation error p50 / p95 m"] == "12.0 / 19.2"
