"""Flight and telemetry model: lawnmower coverage, banked turns, determinism, noise levels."""

import math

import numpy as np
import pytest

from sarmission.geo.wgs84 import geodetic_to_ned
from sarmission.mission.config import load_mission
from sim.flight import Flight, lawnmower_legs
from sim.telemetry import TelemetryModel


@pytest.fixture(scope="module")
def mission():
    return load_mission(
        overrides={
            "area.rectangle_m": [40.0, -100.0, 200.0, 100.0],
            "area.leg_spacing_m": 60.0,
            "area.heading_deg": 90.0,
            "flight.altitude_m": 70.0,
            "flight.speed_m_s": 10.0,
        }
    )


@pytest.fixture(scope="module")
def flight(mission):
    return Flight(mission, seed=3)


def test_lawnmower_legs_cover_rectangle():
    legs = lawnmower_legs([(0, 0), (0, 200), (120, 200), (120, 0)], 40.0, 90.0)
    assert len(legs) == 3
    norths = sorted(float(a[0]) for a, _ in legs)
    np.testing.assert_allclose(norths, [20.0, 60.0, 100.0])
    for a, b in legs:
        assert abs(a[0] - b[0]) < 1e-9 and abs(abs(b[1] - a[1]) - 200.0) < 1e-9
    # alternating directions
    assert np.sign(legs[0][1][1] - legs[0][0][1]) == -np.sign(legs[1][1][1] - legs[1][0][1])


def test_path_flies_every_leg_at_altitude(flight, mission):
    ts = np.arange(0.0, flight.survey_duration, 0.1)
    pos = np.array([flight.state_at(t).position_ned for t in ts])
    for a, b in flight.legs:
        for frac in (0.4, 0.5, 0.65):  # corners are rounded, so check the leg interiors
            p = a + frac * (b - a)
            d = np.linalg.norm(pos[:, :2] - p, axis=1)
            i = int(np.argmin(d))
            assert d[i] < 0.5, f"leg point {p} missed by {d[i]:.2f} m"
            assert pos[i, 2] == pytest.approx(-mission.flight.altitude_m, abs=0.1)
    # Cruise speed on the legs, never faster.
    speeds = np.array([np.linalg.norm(flight.state_at(t).velocity_ned) for t in ts])
    assert speeds.max() <= mission.flight.speed_m_s + 0.1
    assert np.percentile(speeds, 70) == pytest.approx(mission.flight.speed_m_s, abs=0.2)
    # Starts on the ground at home (takeoff) and ends hovering at the last leg's end.
    np.testing.assert_allclose(flight.state_at(0.0).position_ned, 0.0, atol=1e-6)
    end = flight.state_at(flight.survey_duration + 10).position_ned
    np.testing.assert_allclose(end[:2], flight.legs[-1][1], atol=0.2)


def test_attitude_banks_into_turns_and_is_level_on_legs(flight):
    ts = np.arange(5.0, flight.survey_duration - 5, 0.1)
    states = [flight.state_at(t) for t in ts]
    max_bank = 0.0
    for s in states:
        v = s.velocity_ned[:2]
        a = s.acceleration_ned[:2]
        speed = np.linalg.norm(v)
        if speed < 5:
            continue
        lateral = (v[0] * a[1] - v[1] * a[0]) / speed  # + = turning right
        if abs(lateral) > 2.0:
            assert np.sign(s.roll) == np.sign(lateral), "must bank into the turn"
            max_bank = max(max_bank, abs(s.roll))
    assert math.degrees(max_bank) > 10.0
    # Yaw follows the track on straight legs; multicopter flies nose down.
    mid = flight.state_at(45.0)
    track = math.atan2(mid.velocity_ned[1], mid.velocity_ned[0])
    assert abs((mid.yaw - track + math.pi) % (2 * math.pi) - math.pi) < math.radians(3)
    assert mid.pitch < 0


def test_same_seed_same_telemetry_and_different_seed_differs(mission):
    a = TelemetryModel(Flight(mission, seed=5), seed=5)
    b = TelemetryModel(Flight(mission, seed=5), seed=5)
    c = TelemetryModel(Flight(mission, seed=6), seed=6)
    # Different query order must not matter.
    late = b.position(30.0)
    pa = [a.position(k / 10) for k in range(301)]
    pb = [b.position(k / 10) for k in range(301)]
    assert pa == pb and pa[-1] == late
    att_a = [a.attitude(t) for t in (1.0, 10.0, 20.0)]
    assert att_a == [b.attitude(t) for t in (1.0, 10.0, 20.0)]
    assert [c.position(t) for t in (10.0, 20.0)] != [a.position(t) for t in (10.0, 20.0)]


def test_noise_statistics_match_configuration(mission):
    cfg = load_mission(
        overrides={
            "telemetry.gnss_noise_m": 2.0,
            "telemetry.gnss_noise_tau_s": 1.0,
            "telemetry.attitude_noise_deg": 0.5,
            "telemetry.latency_s": 0.1,
            "flight.takeoff": False,
        }
    )
    flight = Flight(cfg, seed=11)
    tm = TelemetryModel(flight, seed=11)
    ts = np.arange(0.0, 400.0, 0.5)
    err_n, err_d, err_roll = [], [], []
    for t in ts:
        p = tm.position(float(t))
        truth = tm.truth(float(t))
        n, e, d = geodetic_to_ned(p.lat_deg, p.lon_deg, p.alt_m, *cfg.area.home)
        err_n.append(float(n) - truth.position_ned[0])
        err_d.append(float(d) - truth.position_ned[2])
        att = tm.attitude(float(t))
        err_roll.append(att.roll - truth.roll)
        assert p.t_available == pytest.approx(t + 0.1)
    assert np.std(err_n) == pytest.approx(2.0, rel=0.25)
    assert np.std(err_d) == pytest.approx(3.0, rel=0.25)
    assert abs(np.mean(err_n)) < 0.6
    assert math.degrees(np.std(err_roll)) == pytest.approx(0.5, rel=0.15)


def test_samples_follow_rates_and_latency(flight):
    tm = TelemetryModel(flight, seed=1)
    pos = tm.samples("position", 10.0, 12.0)
    att = tm.samples("attitude", 10.0, 12.0)
    gim = tm.samples("gimbal", 10.0, 12.0)
    assert (len(pos), len(att), len(gim)) == (20, 40, 10)
    for s in pos:
        assert 10.0 <= s.t_available < 12.0
        assert s.t_available - s.t == pytest.approx(tm.latency_s)


def test_reposition_and_roi_change_the_future_only(mission):
    f = Flight(mission, seed=2)
    before = f.state_at(20.0)
    target = np.array([0.0, 0.0, -50.0])
    eta = f.reposition(30.0, target)
    np.testing.assert_allclose(f.state_at(20.0).position_ned, before.position_ned)
    assert eta > 30.0
    p31 = f.state_at(31.0).position_ned
    p40 = f.state_at(40.0).position_ned
    assert np.linalg.norm(p40 - target) < np.linalg.norm(p31 - target)
    np.testing.assert_allclose(f.state_at(eta + 5).position_ned, target, atol=0.05)
    assert np.linalg.norm(f.state_at(eta + 5).velocity_ned) < 1e-6
    # ROI: after the slew the optical axis points at the target.
    roi = np.array([30.0, 40.0, 0.0])
    f.set_roi(eta + 6, roi)
    s = f.state_at(eta + 10)
    axis = s.camera_pose().optical_axis_ned
    to_roi = roi - s.position_ned
    angle = math.degrees(math.acos(axis @ to_roi / np.linalg.norm(to_roi)))
    assert angle < 0.5


def test_hard_mount_has_no_gimbal_telemetry_and_roi_yaws_the_vehicle():
    cfg = load_mission(
        overrides={"camera.gimbal": False, "camera.mount_pitch_deg": -60.0, "flight.takeoff": False}
    )
    f = Flight(cfg, seed=0)
    tm = TelemetryModel(f, seed=0)
    assert tm.gimbal(5.0) is None and tm.samples("gimbal", 0.0, 2.0) == []
    s = f.state_at(5.0)
    assert s.gimbal_frame == "body"
    f.reposition(5.0, s.position_ned)  # hold here
    roi = s.position_ned + np.array([-80.0, -80.0, 70.0])
    f.set_roi(6.0, roi)
    s = f.state_at(20.0)
    bearing = math.atan2(roi[1] - s.position_ned[1], roi[0] - s.position_ned[0])
    assert abs((s.yaw - bearing + math.pi) % (2 * math.pi) - math.pi) < math.radians(1)
