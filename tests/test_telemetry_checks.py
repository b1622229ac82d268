"""Telemetry plausibility limits and time windows, each probed just inside and just outside.

The limits are physical and documented in :mod:`sarmission.mavlink.telemetry_checks` and
:mod:`sarmission.mavlink.telemetry`: a latitude within +-90 deg, heights above home in
[-1000, 12000] m and AMSL in [-1000, 15000] m (GLOBAL_POSITION_INT carries millimetres), at most
150 m/s (centimetres per second on the wire), pitch within +-90 deg, a home not at 0, 0, a 3D GPS
fix. Positions less than 2 s apart may differ by at most 150 m/s x max(dt, 0.1 s) + 10 m. The
boot clock keeps a sample whose boot time is at most 1 s behind the newest and whose delay is
within 1 s below and 3 s above the least one; a new timeline needs three samples over 1 s. The
distances below are made with pymap3d directly, not with the code under test.
"""

import math

import pymap3d
import pytest
from pymavlink.dialects.v20 import ardupilotmega as M
from test_telemetry_trust import HOME_LAT, HOME_LON, feed, wire

from sarmission.mavlink.telemetry import BootClock, TelemetryBuffer
from sarmission.mavlink.telemetry_checks import message_problem


def gpi(lat=HOME_LAT, lon=HOME_LON, rel_alt_mm=60_000, alt_mm=65_000, vx=0, vy=0, vz=0):
    return M.MAVLink_global_position_int_message(
        1000, round(lat * 1e7), round(lon * 1e7), alt_mm, rel_alt_mm, vx, vy, vz, 0
    )


@pytest.mark.parametrize(
    ("msg", "problem"),
    [
        (gpi(lat=90.0), ""),
        (gpi(lat=-90.0), ""),
        (gpi(lat=90.5), "lat 90.5 out of range"),
        (gpi(lat=-120.0), "lat -120 out of range"),
        (gpi(lon=180.0), ""),
        # heights: millimetres on the wire
        (gpi(rel_alt_mm=12_000_000), ""),
        (gpi(rel_alt_mm=12_000_001), "relative_alt 12000 out of range"),
        (gpi(rel_alt_mm=-1_000_000), ""),
        (gpi(rel_alt_mm=-1_000_001), "relative_alt -1000 out of range"),
        (gpi(alt_mm=15_000_000), ""),
        (gpi(alt_mm=15_000_001), "alt 15000 out of range"),
        # speed: centimetres per second on the wire; 150 m/s is the ceiling
        (gpi(vx=15_000), ""),
        (gpi(vx=15_001), "speed 150 m/s implausible"),
        (gpi(vx=9_000, vy=12_001), "speed 150 m/s implausible"),
        (M.MAVLink_attitude_message(0, 0.0, math.pi / 2, 0.0, 0, 0, 0), ""),
        (
            M.MAVLink_attitude_message(0, 0.0, math.pi / 2 + 0.01, 0.0, 0, 0, 0),
            "roll/pitch 0/1.58 rad out of range",
        ),
        (M.MAVLink_attitude_message(0, -math.pi, 0.0, 0.0, 0, 0, 0), ""),
        (
            M.MAVLink_attitude_message(0, math.pi + 0.01, 0.0, 0.0, 0, 0, 0),
            "roll/pitch 3.15/0 rad out of range",
        ),
        (M.MAVLink_attitude_message(0, 0.0, 0.0, 2 * math.pi, 0, 0, 0), ""),
        (
            M.MAVLink_attitude_message(0, 0.0, 0.0, 2 * math.pi + 0.01, 0, 0, 0),
            "yaw 6.29 rad out of range",
        ),
        (M.MAVLink_attitude_quaternion_message(0, 1.09, 0.0, 0.0, 0.0, 0, 0, 0), ""),
        (
            M.MAVLink_attitude_quaternion_message(0, 1.11, 0.0, 0.0, 0.0, 0, 0, 0),
            "quaternion norm 1.11",
        ),
        (
            M.MAVLink_home_position_message(0, 0, 0, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0, 0),
            "home at 0, 0",
        ),
        (M.MAVLink_home_position_message(0, 1, 0, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0, 0), ""),
    ],
)
def test_each_limit_just_inside_and_just_outside(msg, problem):
    assert message_problem(msg) == problem


def lat_north_of(lat, lon, metres):
    """The latitude ``metres`` due north of ``(lat, lon)`` (pymap3d)."""
    return float(pymap3d.ned2geodetic(metres, 0.0, 0.0, lat, lon, 0.0)[0])


def jump_accepted(dt_s: float, metres: float) -> bool:
    """Whether a position ``metres`` north of the last one, ``dt_s`` later, is believed."""
    buf = TelemetryBuffer()
    last = feed(buf, 10.0, 5)  # positions every 0.1 s, boot ms 10_000..10_400
    ms = 10_400 + round(dt_s * 1000)
    lat = lat_north_of(HOME_LAT, HOME_LON, metres)
    msg = M.MAVLink_global_position_int_message(
        ms, round(lat * 1e7), round(HOME_LON * 1e7), 60_000, 60_000, 0, 0, 0, 0
    )
    buf.handle_message(
        wire(M.MAVLink_gps_raw_int_message(0, 3, 0, 0, 0, 120, 200, 0, 0, 10)), last + dt_s
    )
    buf.handle_message(wire(msg), last + dt_s)
    rejected = buf.rejected["GLOBAL_POSITION_INT: position jump of N m in N s"]
    assert rejected in (0, 1)
    return rejected == 0


def test_position_jumps_at_the_speed_ceiling_and_its_slack():
    # 0.1 s apart: 150 m/s x 0.1 s + 10 m slack = 25 m
    assert jump_accepted(0.1, 20.0)  # beyond 15 m (no slack), within the slack
    assert not jump_accepted(0.1, 30.0)
    # closer than 0.1 s: still 0.1 s of flight allowed
    assert jump_accepted(0.02, 20.0)
    # 1.5 s apart: 235 m
    assert jump_accepted(1.5, 220.0)
    assert not jump_accepted(1.5, 260.0)
    # 2.5 s apart: 385 m; the allowance grows with the gap, it never stops
    assert jump_accepted(2.5, 380.0)
    assert not jump_accepted(2.5, 700.0)
    # 60 s apart: 9,010 m
    assert jump_accepted(60.0, 9000.0)
    assert not jump_accepted(60.0, 9100.0)


def test_a_2d_gps_fix_is_not_enough():
    for fix, believed in ((2, False), (3, True)):
        buf = TelemetryBuffer()
        feed(buf, 10.0, 3, gps_fix=fix)
        assert (buf.newest_time("position") is not None) is believed, fix
        assert (
            buf.rejected["GLOBAL_POSITION_INT: no 3D GPS fix (fix type N)"] == 3
        ) is not believed


def steady_clock() -> tuple[BootClock, float, float]:
    """A clock fed 20 samples every 0.1 s with a delay of exactly 100 s; returns it, the newest
    boot time and the newest arrival."""
    clock = BootClock()
    for k in range(20):
        assert clock.observe(1.0 + 0.1 * k, 101.0 + 0.1 * k) == pytest.approx(1.0 + 0.1 * k + 100)
    return clock, 2.9, 102.9


def test_boot_time_back_by_up_to_the_reboot_jump_is_kept():
    clock, boot, arrival = steady_clock()
    # a late sample from 0.9 s ago (delay 100.9 s: within the late tolerance)
    assert clock.observe(boot - 0.9, arrival) is not None
    # from 1.2 s ago: off the timeline (a forger, or a reboot to be confirmed)
    assert clock.observe(boot - 1.2, arrival) is None
    assert clock.rejected == 1


@pytest.mark.parametrize(
    ("delay_change", "kept"), [(2.9, True), (3.2, False), (-0.9, True), (-1.2, False)]
)
def test_delays_beyond_the_tolerances_are_off_the_timeline(delay_change, kept):
    clock, boot, arrival = steady_clock()
    # a sample 0.1 s newer on the boot clock whose delay differs from the least one
    result = clock.observe(boot + 0.1, arrival + 0.1 + delay_change)
    assert (result is not None) is kept


def test_a_new_timeline_needs_three_samples_over_a_second():
    clock, boot, arrival = steady_clock()
    t = arrival + 5.0  # silence, then boot times near zero (a reboot)
    assert clock.observe(0.5, t) is None
    assert clock.observe(1.7, t + 1.2) is None  # two samples over 1.2 s: not yet
    assert clock.reboots == 0
    assert clock.observe(1.8, t + 1.3) == pytest.approx(t + 1.3)
    assert clock.reboots == 1
