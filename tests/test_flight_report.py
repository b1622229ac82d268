"""The post-flight report in a real headless Chromium: a self-contained page (no request leaves
it) with the map of the track and the alerts, a card per alert with its thumbnail, and the
summary table; the screenshot is written under the test's ``tmp_path``."""

from __future__ import annotations

import csv
import json
from collections.abc import Iterator
from pathlib import Path

import pytest
from alert_samples import make_alert
from chromium import NEEDS_CHROMIUM, Chromium

from sarmission.alerts.report import ReportInput, write_report

SCREENSHOT = Path("/tmp/sarmission_report.png")


def sample_report() -> ReportInput:
    alerts = [
        make_alert(1, confidence=0.4),
        make_alert(2, frame_index=240),
        make_alert(3, positioned=False),
    ]
    alerts[2].position_note = "no telemetry"
    track = [(float(k), -35.3635 + k * 2e-5, 149.1648 + (k % 20) * 3e-5) for k in range(60)]
    return ReportInput(
        title="replay of flight.mp4",
        alerts=alerts,
        track=track,
        frame_times={101: 3.37, 240: 8.0, 103: 3.43},
        facts=[("telemetry", "MAVLink tlog flight.tlog"), ("", "alignment: camera trigger 1 of 1")],
    )


def test_report_files_hold_every_alert_and_say_why_one_has_no_position(tmp_path: Path) -> None:
    paths = write_report(tmp_path, sample_report())
    assert sorted(p.name for p in paths) == [
        "alerts.csv",
        "alerts.geojson",
        "alerts.kml",
        "report.html",
    ]
    rows = list(csv.DictReader((tmp_path / "alerts.csv").open()))
    assert [r["frame_index"] for r in rows] == ["101", "240", "103"]
    assert rows[0]["footage_time_s"] == "3.370" and rows[0]["lat"] and rows[0]["error_m"]
    assert rows[2]["lat"] == "" and rows[2]["position_note"] == "position unknown: no telemetry"
    assert rows[2]["pixel_x"] != ""
    assert [r["confidence"] for r in rows] == ["0.400", "", ""]
    geo = json.loads((tmp_path / "alerts.geojson").read_text())
    assert [f["geometry"] and f["geometry"]["type"] for f in geo["features"]] == [
        "Point",
        "Point",
        None,
        "LineString",
    ]
    kml = (tmp_path / "alerts.kml").read_text()
    assert kml.count("<Placemark") == 2 and "no telemetry" in kml
    page = (tmp_path / "report.html").read_text()
    assert "http://" not in page.replace('xmlns="http://www.w3.org/2000/svg"', "")
    assert "https://" not in page


@pytest.fixture
def browser(tmp_path: Path) -> Iterator[Chromium]:
    chromium = Chromium(tmp_path / "profile")
    try:
        yield chromium
    finally:
        chromium.close()


@NEEDS_CHROMIUM
def test_report_renders_offline_in_chromium(tmp_path: Path, browser: Chromium) -> None:
    write_report(tmp_path / "out", sample_report())
    browser.open_page((tmp_path / "out" / "report.html").as_uri())
    browser.wait_for("document.readyState === 'complete'", timeout=15.0)
    assert browser.js("document.querySelectorAll('svg.map polyline.track').length") == 1
    assert browser.js("document.querySelectorAll('svg.map .alert-marker').length") == 2
    assert browser.js("document.querySelectorAll('.card').length") == 3
    browser.wait_for(
        "[...document.querySelectorAll('.card img')].every(i => i.naturalWidth > 0)", timeout=5.0
    )
    assert browser.js("document.querySelectorAll('.card img').length") == 3
    text = browser.js("document.body.innerText")
    assert "position unknown: no telemetry" in text and "t = 8.00 s, frame 240" in text
    assert browser.js("document.getElementById('counts').textContent") == (
        "3 alerts, 2 with a position, 1 without"
    )
    marker_box = browser.js(
        "JSON.stringify(document.querySelector('.alert-marker').getBoundingClientRect())"
    )
    box = json.loads(marker_box)
    assert box["width"] > 0 and box["height"] > 0
    browser.screenshot(tmp_path / "report.png")
    SCREENSHOT.write_bytes((tmp_path / "report.png").read_bytes())
    assert (tmp_path / "report.png").stat().st_size > 10_000
