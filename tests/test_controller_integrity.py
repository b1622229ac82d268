"""The controller computes a position only from the autopilot's own state: not before its home is
known (the mission file's far-away home is never an origin), not from a drone on the ground,
never from non-finite telemetry; alerts without one get it later from buffered telemetry.

Truth is computed here from first principles (pymap3d's own local frame around the drone, a
pinhole at nadir), not with the project's geolocation."""

import math

import numpy as np
import pymap3d
import pytest
from scripted_detector import ScriptedDetector

from sarmission.alerts.store import AlertStore
from sarmission.mavlink.telemetry import TelemetryBuffer
from sarmission.mission.config import load_mission
from sarmission.mission.controller import MissionController

W, H = 960, 540
HFOV_DEG = 30.0
FPS = 10.0
# The vehicle flies at 43 N 10 E (as ArduPilot SITL does); the mission file says 54.17 N.
DRONE = (43.0, 10.0)
TARGET_OFFSET_NE = (12.0, -7.0)  # metres north/east of the point under the drone


@pytest.fixture
def mission():
    return load_mission(
        overrides={
            "camera.width": W,
            "camera.height": H,
            "camera.hfov_deg": HFOV_DEG,
            "name": "integrity",
        }
    )


def nadir_pixel(height_m: float) -> tuple[float, float]:
    """Where the target appears for a level camera looking straight down, yaw 0 (north up:
    image x to the east, image y to the south), focal length from the horizontal FOV."""
    f = (W / 2) / math.tan(math.radians(HFOV_DEG) / 2)
    north, east = TARGET_OFFSET_NE
    return (W - 1) / 2 + f * east / height_m, (H - 1) / 2 - f * north / height_m


def truth() -> tuple[float, float]:
    lat, lon, _ = pymap3d.ned2geodetic(*TARGET_OFFSET_NE, 0.0, *DRONE, 0.0)
    return float(lat), float(lon)


def metres(a, b) -> float:
    n, e, _ = pymap3d.geodetic2ned(a[0], a[1], 0.0, b[0], b[1], 0.0)
    return math.hypot(n, e)


def hover(buf: TelemetryBuffer, t_end: float, rel_alt_m: float, gimbal_pitch=None) -> None:
    for t in np.arange(0.0, t_end + 1e-9, 0.05):
        buf.push_position(float(t), *DRONE, rel_alt_m)
        buf.push_attitude(float(t), 0.0, 0.0, 0.0)
        if gimbal_pitch is not None:
            buf.push_gimbal(float(t), (0.0, gimbal_pitch, 0.0), "body")


def script(n: int, height_m: float):
    u, v = nadir_pixel(height_m)
    return [[((u - 4, v - 4, u + 4, v + 4), 0.9, 0)] for _ in range(n)]


def run(ctl, n: int):
    alerts = []
    for i in range(n):
        alerts += ctl.process(i, i / FPS, np.full((H, W, 3), 90, np.uint8))
    return alerts


def test_no_position_before_the_autopilot_reports_home_then_placed_from_the_buffer(
    tmp_path, mission
):
    assert metres(mission.area.home[:2], DRONE) > 1e6  # the mission file's home is far away
    buf = TelemetryBuffer(stale_after_s=mission.telemetry.stale_after_s)
    hover(buf, 3.0, 60.0)
    lines: list[str] = []
    with AlertStore(tmp_path / "a.db") as store:
        # seen in frames 0-9 only: the position must come from those sightings
        ctl = MissionController(
            mission, ScriptedDetector(script(10, 60.0) + [[]] * 5), buf, store, console=lines.append
        )
        run(ctl, 10)
        alerts = ctl.stats.candidates  # locked without a position: a candidate, unconfirmed
        assert len(alerts) == 1 and alerts[0].position is None
        assert "no home position from the autopilot yet" in alerts[0].position_note
        assert "position unknown: " in lines[0]
        # HOME_POSITION arrives (home 40 m below the drone's height reference: same plane)
        buf.set_home(DRONE[0] + 0.001, DRONE[1], 2.0)
        ctl.process(10, 1.0, np.full((H, W, 3), 90, np.uint8))
        stored = store.list()[0]
        assert stored.position is not None
        assert metres(stored.position, truth()) < 0.05
        assert any(line.startswith("POSITION target 1") for line in lines)
        assert ctl.stats.located_later == 1


def test_no_fix_for_a_drone_on_the_ground(tmp_path, mission):
    buf = TelemetryBuffer(stale_after_s=mission.telemetry.stale_after_s)
    buf.set_home(*DRONE, 2.0)
    hover(buf, 3.0, 0.4)  # landed after an autopilot restart: relative altitude ~0
    with AlertStore(tmp_path / "a.db") as store:
        ctl = MissionController(
            mission, ScriptedDetector(script(20, 0.4)), buf, store, console=lambda s: None
        )
        assert run(ctl, 20) == []  # nothing confirmed without a position
        alerts = ctl.stats.candidates
        assert len(alerts) == 1 and alerts[0].position is None
        assert "0.4 m above the ground" in alerts[0].position_note
        assert store.list()[0].position is None


def test_a_fix_needs_the_minimum_height_from_the_mission(tmp_path):
    mission = load_mission(
        overrides={
            "camera.width": W,
            "camera.height": H,
            "camera.hfov_deg": HFOV_DEG,
            "geolocation.min_height_m": 30.0,
        }
    )
    buf = TelemetryBuffer(stale_after_s=mission.telemetry.stale_after_s)
    buf.set_home(*DRONE, 2.0)
    hover(buf, 3.0, 25.0)
    with AlertStore(tmp_path / "a.db") as store:
        ctl = MissionController(
            mission, ScriptedDetector(script(10, 25.0)), buf, store, console=lambda s: None
        )
        run(ctl, 10)
        (alert,) = ctl.stats.candidates
        assert alert.position is None and "a fix needs 30 m" in alert.position_note


def test_exact_position_around_the_drone_not_the_mission_home(tmp_path, mission):
    buf = TelemetryBuffer(stale_after_s=mission.telemetry.stale_after_s)
    buf.set_home(DRONE[0] - 0.002, DRONE[1] + 0.003, 2.0)  # the autopilot's home, 300 m away
    hover(buf, 3.0, 60.0)
    with AlertStore(tmp_path / "a.db") as store:
        ctl = MissionController(
            mission, ScriptedDetector(script(10, 60.0)), buf, store, console=lambda s: None
        )
        run(ctl, 10)
        (alert,) = ctl.stats.candidates
        assert alert.position is not None and metres(alert.position, truth()) < 0.05
        assert alert.error_m is not None and alert.error_m < 5.0


def test_non_finite_gimbal_attitude_is_no_fix_and_no_crash(tmp_path, mission):
    buf = TelemetryBuffer(stale_after_s=mission.telemetry.stale_after_s)
    buf.set_home(*DRONE, 2.0)
    hover(buf, 3.0, 60.0, gimbal_pitch=math.nan)  # pushed directly, past the message checks
    with AlertStore(tmp_path / "a.db") as store:
        ctl = MissionController(
            mission, ScriptedDetector(script(10, 60.0)), buf, store, console=lambda s: None
        )
        run(ctl, 10)
        (alert,) = ctl.stats.candidates
        assert alert.position is None and "not finite" in alert.position_note
