"""Replay from dataset meta: heights are above take-off, a mission's ground and terrain above sea
level. The two meet only through the take-off's altitude (``--takeoff-alt``); without it the
ground plane is the take-off's, never a plane hundreds of metres off."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from test_meta_conventions import write_dataset

from sarmission.cli import main
from sarmission.data.meta_conventions import MetaPose
from sarmission.geo.geolocate import geolocate
from sarmission.mission.config import load_mission
from sarmission.mission.live import telemetry_buffer
from sarmission.mission.replay_telemetry import (
    ReplaySource,
    meta_ground,
    push_frame_telemetry,
)

URBAN = Path(__file__).resolve().parents[1] / "missions" / "urban_demo.toml"
POSE = MetaPose(48.137, 11.575, 100.0, 0.0, -90.0, 0.0)


def _meta_source() -> ReplaySource:
    return ReplaySource("dataset meta", kind="meta")


def test_without_the_takeoff_altitude_the_ground_plane_is_the_takeoffs() -> None:
    mission = load_mission(URBAN)
    assert mission.area.ground_alt_m == 519.0
    source = _meta_source()
    used = meta_ground(source, mission, None, dem=False)
    assert used.area.ground_alt_m is None
    assert used.area.home_alt_m == mission.area.home_alt_m
    assert any("ground_alt_m (519 m above sea level) is not used" in line for line in source.lines)
    buffer = telemetry_buffer(used)
    push_frame_telemetry(buffer, 0.0, POSE, source.takeoff_alt_m or 0.0)
    assert buffer.home is not None and buffer.home[2] == 0.0
    # the controller's ground below home: 0 with no ground_alt_m, so a nadir ray meets it
    # 100 m below the camera (with 519 it would be 519 m below home, above the camera)
    ground = 0.0 if used.area.ground_alt_m is None else buffer.home[2] - used.area.ground_alt_m
    pose = buffer.lookup(0.0)
    fix = geolocate((160.0, 90.0), used.camera.intrinsics().scaled(320, 180), pose, ground)
    assert fix.ok, fix.note
    assert math.isclose(fix.lat, POSE.latitude, abs_tol=1e-5)


def test_the_takeoff_altitude_places_meta_heights_above_sea_level() -> None:
    mission = load_mission(URBAN)
    source = _meta_source()
    used = meta_ground(source, mission, 519.0, dem=True)
    assert used is mission and used.area.ground_alt_m == 519.0
    assert source.takeoff_alt_m == 519.0
    assert "take-off at 519 m above sea level (--takeoff-alt)" in source.lines
    wrapped = source.buffer(lambda: telemetry_buffer(used))
    source.before(wrapped, 0.0, POSE, used.area.home)  # what the replay does each frame
    home = wrapped.buffer.home
    assert home is not None and home[2] == 519.0


def test_a_mission_without_a_ground_altitude_is_used_as_it_is() -> None:
    mission = load_mission(None)
    source = _meta_source()
    assert meta_ground(source, mission, None, dem=False) is mission
    assert source.lines == []


@pytest.mark.parametrize(
    ("kind", "takeoff", "dem", "message"),
    [
        ("meta", None, True, "--dem with dataset meta needs --takeoff-alt"),
        ("meta", float("nan"), False, "--takeoff-alt must be metres above sea level"),
        ("meta", 12000.0, False, "--takeoff-alt must be metres above sea level"),
        ("log", 100.0, False, "carries its own home altitude"),
        ("sim", 100.0, False, "carries its own home altitude"),
    ],
)
def test_what_cannot_be_placed_is_refused_in_one_line(kind, takeoff, dem, message) -> None:
    source = ReplaySource(f"{kind} telemetry", kind=kind)
    with pytest.raises(ValueError, match=message):
        meta_ground(source, load_mission(URBAN), takeoff, dem)


def test_replay_says_which_ground_and_lens_it_uses(tmp_path, capsys) -> None:
    ann = write_dataset(tmp_path, [-90.0])
    args = ["replay", str(ann), "--fps", "10", "--max-frames", "3", "--no-progress"]
    assert main([*args, "--mission", str(URBAN)]) == 0
    out = capsys.readouterr().out
    assert "the mission's ground_alt_m (519 m above sea level) is not used" in out
    assert "camera: 70 degrees across at 3840x2160 (the mission's [camera]" in out
    assert main([*args, "--mission", str(URBAN), "--takeoff-alt", "519"]) == 0
    assert "take-off at 519 m above sea level" in capsys.readouterr().out
    assert main([*args, "--set", "camera.hfov_deg=44.5", "--telemetry", "none"]) == 0
    assert "camera:" not in capsys.readouterr().out  # no position, no lens to name
    assert main([*args, "--set", "camera.hfov_deg=44.5"]) == 0
    assert "camera: 44.5 degrees across" in capsys.readouterr().out
    assert main([*args, "--telemetry", "none", "--takeoff-alt", "519"]) == 2
    assert "carries its own home altitude" in capsys.readouterr().err
