"""Terrain fixes obey the same FixLimits as plane fixes: off-nadir and error limits refuse them
with the same note, and the grazing margin is measured from the terrain's surface (a level ray
meeting a hillside stands; a ray skimming a slope falling away is refused)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from test_terrain import write_geotiff

from sarmission.geo.camera import CameraIntrinsics
from sarmission.geo.geolocate import FixLimits, PlatformPose, geolocate
from sarmission.geo.terrain import HOME_AMSL_SIGMA_M, TerrainGround, geolocate_terrain, read_dem

LAT0, LON0 = 43.0, 10.0
INTR = CameraIntrinsics(1920, 1080, 1000.0, 1000.0, 960.0, 540.0)
CENTRE = (960.0, 540.0)
HOME = (LAT0 - 0.001, LON0, 200.0)


def looking_east(depression_deg: float, rel_alt: float = 80.0) -> PlatformPose:
    """Level drone facing east, gimbal ``depression_deg`` down: the centre ray points east."""
    return PlatformPose(
        LAT0,
        LON0,
        rel_alt,
        0.0,
        0.0,
        math.radians(90.0),
        gimbal_rpy=(0.0, -math.radians(depression_deg), 0.0),
        gimbal_frame="vehicle",
    )


@pytest.fixture
def flat_dem(tmp_path: Path):
    write_geotiff(tmp_path / "flat.tif", lambda n, e: np.full(n.shape, 200.0))
    return read_dem(tmp_path / "flat.tif", vertical_sigma_m=2.0)


def test_off_nadir_limit_refuses_as_on_the_plane(flat_dem) -> None:
    pose = looking_east(20.0)  # the centre ray is 70 degrees from straight down
    strict = FixLimits(max_off_nadir_deg=60.0)
    refused = geolocate_terrain(CENTRE, INTR, pose, flat_dem, HOME, limits=strict)
    plane = geolocate(
        CENTRE, INTR, pose, 0.0, ground_sigma_m=math.hypot(HOME_AMSL_SIGMA_M, 2.0), limits=strict
    )
    assert not refused.ok and not plane.ok
    assert "70.0 deg from straight down (a fix needs at most 60" in refused.note
    assert refused.note == plane.note
    assert geolocate_terrain(
        CENTRE, INTR, pose, flat_dem, HOME, limits=FixLimits(max_off_nadir_deg=75.0)
    ).ok


def test_error_limit_refuses_a_fix_whose_estimate_exceeds_it(flat_dem) -> None:
    pose = looking_east(20.0)
    fix = geolocate_terrain(CENTRE, INTR, pose, flat_dem, HOME)
    assert fix.ok and fix.error_m is not None
    below = FixLimits(max_error_m=fix.error_m * 0.99)
    refused = geolocate_terrain(CENTRE, INTR, pose, flat_dem, HOME, limits=below)
    assert not refused.ok and refused.note.startswith(f"error estimate {fix.error_m:.0f} m")
    assert geolocate_terrain(
        CENTRE, INTR, pose, flat_dem, HOME, limits=FixLimits(max_error_m=fix.error_m * 1.01)
    ).ok


def test_the_ground_models_limits_apply_unless_the_call_gives_its_own(flat_dem) -> None:
    pose = looking_east(20.0)
    ground = TerrainGround(flat_dem, limits=FixLimits(max_off_nadir_deg=60.0))
    assert not ground.locate(CENTRE, INTR, pose, HOME, 0.0).ok
    assert ground.locate(CENTRE, INTR, pose, HOME, 0.0, FixLimits()).ok


def test_a_level_ray_meeting_a_hillside_stands(tmp_path: Path) -> None:
    # Ground rising 0.3 m per metre eastwards from 200 m; a ray 1 degree down from 280 m meets
    # it where 280 - e tan(1) = 200 + 0.3 e (e = 262 m), crossing its surface at about
    # 1 + atan(0.3) = 17.7 degrees. A plane fix of the same ray, 1 degree below the horizon
    # (within 3 sigmas of 0.5 degrees), is refused.
    write_geotiff(tmp_path / "hill.tif", lambda n, e: 200.0 + 0.3 * np.maximum(e, 0.0))
    dem = read_dem(tmp_path / "hill.tif", vertical_sigma_m=2.0)
    pose = looking_east(1.0)
    fix = geolocate_terrain(CENTRE, INTR, pose, dem, HOME)
    assert fix.ok, fix.note
    assert fix.range_m == pytest.approx(
        80.0 / (math.tan(math.radians(1.0)) + 0.3) / math.cos(math.radians(1.0)), rel=0.02
    )
    assert not geolocate(CENTRE, INTR, pose, 0.0).ok


def test_a_ray_skimming_a_slope_that_falls_away_is_refused(tmp_path: Path) -> None:
    # Ground falling 0.12 m per metre eastwards (6.8 degrees); a ray 8 degrees down from 20 m up
    # meets it about 980 m out at 8 - 6.8 = 1.2 degrees, inside 3 pointing sigmas (1.5).
    write_geotiff(tmp_path / "fall.tif", lambda n, e: 200.0 - 0.12 * e)
    dem = read_dem(tmp_path / "fall.tif", vertical_sigma_m=2.0)
    pose = looking_east(8.0, rel_alt=20.0)
    refused = geolocate_terrain(CENTRE, INTR, pose, dem, HOME)
    assert not refused.ok
    assert "deg from grazing the terrain" in refused.note
    assert float(refused.note.split()[1]) == pytest.approx(
        8.0 - math.degrees(math.atan(0.12)), abs=0.1
    )
    # With a tighter attitude sigma the same ray is far enough from grazing to stand.
    steady = PlatformPose(**{**pose.__dict__, "attitude_sigma_rad": math.radians(0.1)})
    assert geolocate_terrain(CENTRE, INTR, steady, dem, HOME).ok


def test_the_mission_controller_gives_the_missions_limits_to_the_terrain(tmp_path: Path) -> None:
    """A mission's [geolocation] limits reach fixes on a DEM as they reach plane fixes."""
    from scripted_detector import ScriptedDetector
    from test_controller import (
        FPS,
        confirm_at_lock,
        filled_buffer,
        run_frames,
        script_3_of_5,
        truth_latlon,
    )

    from sarmission.alerts.store import AlertStore
    from sarmission.mission.config import load_mission
    from sarmission.mission.controller import MissionController
    from sarmission.mission.targets import distance_m

    write_geotiff(tmp_path / "flat.tif", lambda n, e: np.full(n.shape, 200.0))
    dem = read_dem(tmp_path / "flat.tif", vertical_sigma_m=2.0)
    positions = {}
    for max_error_m in (250.0, 0.05):
        mission = load_mission(
            overrides={
                "camera.width": 960,
                "camera.height": 540,
                "camera.hfov_deg": 30.0,
                "name": "terrain_limits",
                "area.home_lat": LAT0,
                "area.home_lon": LON0,
                "area.home_alt_m": 200.0,
                "geolocation.max_error_m": max_error_m,
            }
        )
        confirm_at_lock(mission)
        n = 12
        with AlertStore(tmp_path / f"alerts_{max_error_m}.db") as store:
            ctl = MissionController(
                mission,
                ScriptedDetector(script_3_of_5(mission, n)),
                filled_buffer(mission, n / FPS),
                store,
                console=lambda s: None,
                ground_model=TerrainGround(dem),
            )
            run_frames(ctl, n)
            (alert,) = store.list()
            positions[max_error_m] = (alert.position, alert.error_m, truth_latlon(mission))
    kept, error_m, truth = positions[250.0]
    assert kept is not None and distance_m(kept, truth) < 1.0 and 0.05 < error_m < 250.0
    refused, _, _ = positions[0.05]
    assert refused is None
