"""Telemetry interpolated at asymmetric points, gimbal samples across a frame change, and the
boot clock's sliding window.

At the exact midpoint of two samples reversed weights give the right answer, so every time
here sits a quarter or a fifth of the way between samples. Expected rotations are built in the
test from first principles (Rodrigues' formula, ZYX Euler written out), not with
``sarmission.geo.frames``.
"""

import math

import numpy as np
import pytest

from sarmission.mavlink.telemetry import BootClock, TelemetryBuffer


def rodrigues(axis, angle: float) -> np.ndarray:
    """Rotation by ``angle`` about ``axis`` (right hand)."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * cross + (1.0 - math.cos(angle)) * cross @ cross


def zyx(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``R = Rz(yaw) Ry(pitch) Rx(roll)`` written out (body to NED)."""
    return rodrigues((0, 0, 1), yaw) @ rodrigues((0, 1, 0), pitch) @ rodrigues((1, 0, 0), roll)


def quaternion_of(r: np.ndarray) -> tuple[float, float, float, float]:
    """``(w, x, y, z)`` of a rotation matrix whose angle is well below pi (w > 0)."""
    w = math.sqrt(max(0.0, 1.0 + r[0, 0] + r[1, 1] + r[2, 2])) / 2.0
    return (
        w,
        (r[2, 1] - r[1, 2]) / (4 * w),
        (r[0, 2] - r[2, 0]) / (4 * w),
        (r[1, 0] - r[0, 1]) / (4 * w),
    )


def buffer_with_home() -> TelemetryBuffer:
    buf = TelemetryBuffer(stale_after_s=2.0)
    buf.set_home(54.0, 7.0, 0.0)
    return buf


@pytest.mark.parametrize("fraction", [0.25, 0.8])
def test_position_is_weighted_towards_the_nearer_sample(fraction):
    buf = buffer_with_home()
    buf.push_position(10.0, 54.0, 7.0, 50.0, alt_m=80.0)
    buf.push_position(11.0, 54.001, 7.002, 70.0, alt_m=100.0)
    buf.push_attitude(10.0, 0.0, 0.0, 0.0)
    pose = buf.pose_at(10.0 + fraction)
    assert pose is not None
    assert pose.lat == pytest.approx(54.0 + 0.001 * fraction, abs=1e-12)
    assert pose.lon == pytest.approx(7.0 + 0.002 * fraction, abs=1e-12)
    assert pose.rel_alt_m == pytest.approx(50.0 + 20.0 * fraction, abs=1e-9)


@pytest.mark.parametrize("fraction", [0.25, 0.8])
def test_attitude_turns_in_proportion_to_the_time_elapsed(fraction):
    """A constant-rate turn about a fixed axis: at fraction s of the interval the vehicle has
    turned s of the way (what slerp means)."""
    buf = buffer_with_home()
    buf.push_position(10.0, 54.0, 7.0, 50.0)
    r0 = zyx(0.1, -0.05, 0.3)
    axis, angle = (0.2, -0.4, 1.0), 0.9
    buf.push_attitude_quaternion(10.0, quaternion_of(r0))
    buf.push_attitude_quaternion(11.0, quaternion_of(r0 @ rodrigues(axis, angle)))
    pose = buf.pose_at(10.0 + fraction)
    assert pose is not None
    np.testing.assert_allclose(
        zyx(*pose.vehicle_rpy), r0 @ rodrigues(axis, fraction * angle), atol=1e-9
    )


def test_yaw_alone_interpolates_linearly_at_a_quarter():
    buf = buffer_with_home()
    buf.push_position(0.0, 54.0, 7.0, 50.0)
    buf.push_attitude(0.0, 0.0, 0.0, 0.2)
    buf.push_attitude(1.0, 0.0, 0.0, 1.0)
    pose = buf.pose_at(0.25)
    assert pose.yaw == pytest.approx(0.4, abs=1e-9)
    assert pose.roll == pytest.approx(0.0, abs=1e-12) and pose.pitch == pytest.approx(
        0.0, abs=1e-12
    )


@pytest.mark.parametrize(("t", "frame", "yaw"), [(10.3, "vehicle", 0.2), (10.7, "earth", 1.4)])
def test_gimbal_takes_the_nearer_sample_when_its_frame_changes(t, frame, yaw):
    """A vehicle-frame and an earth-frame gimbal sample cannot be blended: the nearer one is
    used whole."""
    buf = buffer_with_home()
    buf.push_position(10.0, 54.0, 7.0, 50.0)
    buf.push_attitude(10.0, 0.0, 0.0, 0.0)
    buf.push_gimbal(10.0, (0.0, -1.0, 0.2), "vehicle")
    buf.push_gimbal(11.0, (0.0, -1.2, 1.4), "earth")
    pose = buf.pose_at(t)
    assert pose.gimbal_frame == frame
    assert pose.gimbal_rpy[2] == pytest.approx(yaw, abs=1e-9)


def test_gimbal_in_one_frame_is_interpolated_at_a_quarter():
    buf = buffer_with_home()
    buf.push_position(10.0, 54.0, 7.0, 50.0)
    buf.push_attitude(10.0, 0.0, 0.0, 0.0)
    buf.push_gimbal(10.0, (0.0, -1.0, 0.0), "earth")
    buf.push_gimbal(11.0, (0.0, -1.0, 0.8), "earth")
    pose = buf.pose_at(10.25)
    np.testing.assert_allclose(
        zyx(*pose.gimbal_rpy), rodrigues((0, 0, 1), 0.2) @ zyx(0, -1, 0), atol=1e-9
    )


def test_boot_clock_minimum_follows_the_window():
    """The offset is the least delay of the last ``window_s`` seconds: a small delay is kept
    while it is inside the window and forgotten once it leaves it."""
    clock = BootClock(window_s=5.0)
    for k in range(5):  # delay 99.1 s (local - boot) at arrivals 100.1 .. 100.9
        clock.observe(1.0 + 0.2 * k, 100.1 + 0.2 * k)
    assert clock.offset == pytest.approx(99.1)
    arrival = 100.8
    while arrival < 104.6:  # later messages 0.5 s slower; the quick ones still in the window
        arrival += 0.2
        assert clock.observe(arrival - 99.6, arrival) == pytest.approx(arrival - 0.5)
    assert clock.offset == pytest.approx(99.1)
    while arrival < 106.4:  # the quick ones have left the window: the minimum is now 0.6 s
        arrival += 0.2
        clock.observe(arrival - 99.6, arrival)
    assert clock.offset == pytest.approx(99.6)
    assert clock.to_local(10.0) == pytest.approx(109.6)


def test_boot_clock_window_keeps_the_least_delay_not_the_newest():
    """A slow message after a quick one does not raise the estimate (only the window does)."""
    clock = BootClock(window_s=30.0)
    assert clock.observe(1.0, 101.3) == pytest.approx(101.3)
    assert clock.observe(2.0, 102.1) == pytest.approx(102.1)  # quicker: offset 100.1
    assert clock.observe(3.0, 104.0) == pytest.approx(103.1)  # 0.9 s late: offset kept
    assert clock.offset == pytest.approx(100.1)
