"""TelemetryBuffer: interpolation, staleness, boot-time mapping, gimbal frames (no network)."""

import math

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.geo.frames import (
    GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME,
    GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME,
    GIMBAL_DEVICE_FLAGS_YAW_LOCK,
    euler_to_matrix,
    euler_to_quaternion,
    matrix_to_quaternion,
    rot_z,
    rotation_ned_from_camera,
)
from sarmission.mavlink.telemetry import BootClock, StaleTelemetry, TelemetryBuffer

NAN = float("nan")


def axis_angle(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    c, s = math.cos(angle), math.sin(angle)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + s * k + (1 - c) * k @ k


def home_buffer(**kwargs) -> TelemetryBuffer:
    """A buffer whose home is known (a pose needs one), for samples pushed directly."""
    buf = TelemetryBuffer(**kwargs)
    buf.set_home(54.0, 7.0, 0.0)
    return buf


def gps_fix(arrival: float, buf: TelemetryBuffer, fix_type: int = 3) -> None:
    """The autopilot's GPS_RAW_INT with a 3D fix (positions are believed only with one)."""
    msg = M.MAVLink_gps_raw_int_message(0, fix_type, 0, 0, 0, 120, 200, 0, 0, 10)
    buf.handle_message(msg, arrival)


def camera_rotation(pose):
    return rotation_ned_from_camera(pose.vehicle_rpy, pose.gimbal_rpy, pose.gimbal_frame)


def test_midpoint_equals_truth_for_linear_motion_and_constant_rate_rotation():
    buf = home_buffer(stale_after_s=1.0)
    r0 = euler_to_matrix(0.1, -0.2, 2.9)  # near the +-pi yaw wrap
    axis = (0.3, -0.5, 1.0)
    g0 = euler_to_matrix(0.0, -1.2, 0.3)
    for t, frac in ((10.0, 0.0), (10.5, 1.0)):
        buf.push_position(t, 54.0 + 1e-5 * frac, 7.0 - 2e-5 * frac, 60.0 + 2.0 * frac)
        buf.push_attitude_quaternion(t, matrix_to_quaternion(r0 @ axis_angle(axis, 0.4 * frac)))
        buf.push_gimbal(t, matrix_to_quaternion(g0 @ axis_angle((0, 1, 0), 0.2 * frac)), "earth")
    pose = buf.pose_at(10.25)
    assert pose is not None
    assert pose.lat == pytest.approx(54.0 + 0.5e-5, abs=1e-12)
    assert pose.lon == pytest.approx(7.0 - 1e-5, abs=1e-12)
    assert pose.rel_alt_m == pytest.approx(61.0)
    np.testing.assert_allclose(
        euler_to_matrix(*pose.vehicle_rpy), r0 @ axis_angle(axis, 0.2), atol=1e-9
    )
    np.testing.assert_allclose(
        euler_to_matrix(*pose.gimbal_rpy), g0 @ axis_angle((0, 1, 0), 0.1), atol=1e-9
    )
    assert pose.gimbal_frame == "earth"


def test_stale_and_missing_telemetry_give_reasons():
    buf = home_buffer(stale_after_s=1.0)
    assert buf.lookup(0.0).reason == "no position yet"
    buf.push_position(0.0, 54.0, 7.0, 50.0)
    assert buf.lookup(0.0).reason == "no attitude yet"
    buf.push_attitude(0.0, 0.0, 0.0, 0.0)
    assert buf.pose_at(0.5) is not None  # within the limit: held / extrapolated
    stale = buf.lookup(3.2)
    assert isinstance(stale, StaleTelemetry) and str(stale) == "no position for 3.2 s"
    assert buf.pose_at(3.2) is None
    assert "after this time" in buf.lookup(-5.0).reason
    for t in (10.0, 10.1):
        buf.push_position(t, 54.0, 7.0, 50.0)
        buf.push_attitude(t, 0.0, 0.0, 0.0)
    assert "gap of 10.0 s" in buf.lookup(5.0).reason
    assert buf.pose_at(0.9) is not None and buf.pose_at(9.2) is not None


def test_position_extrapolates_with_velocity_within_the_limit():
    buf = home_buffer(stale_after_s=1.0)
    buf.push_position(0.0, 54.0, 7.0, 50.0, velocity_ned=(10.0, 0.0, -2.0))
    buf.push_attitude(0.0, 0.0, 0.0, 0.0)
    pose = buf.pose_at(0.5)
    north_m = (pose.lat - 54.0) * math.pi / 180 * 6_363_000  # meridian radius near 54 deg N
    assert north_m == pytest.approx(5.0, rel=0.01)
    assert pose.rel_alt_m == pytest.approx(51.0)


def test_fixed_mount_until_a_gimbal_reports_then_gimbal_required():
    buf = home_buffer(stale_after_s=1.0, mount_rpy=(0.0, math.radians(-45), 0.0))
    buf.push_position(0.0, 54.0, 7.0, 50.0)
    buf.push_attitude(0.0, 0.05, 0.02, 1.0)
    pose = buf.pose_at(0.0)
    assert pose.gimbal_frame == "body" and pose.gimbal_rpy[1] == pytest.approx(math.radians(-45))
    buf.push_gimbal(0.0, (0.0, -1.0, 0.0), "vehicle")
    for t in (2.0, 2.1):
        buf.push_position(t, 54.0, 7.0, 50.0)
        buf.push_attitude(t, 0.0, 0.0, 0.0)
    assert buf.lookup(2.0).reason == "no gimbal attitude for 2.0 s"


def test_boot_time_mapping_with_jittery_arrival():
    rng = np.random.default_rng(0)
    offset, min_latency = 1000.0, 0.02  # local = boot + 1000 s; network takes >= 20 ms
    buf = TelemetryBuffer(stale_after_s=1.0)
    for k in range(200):
        boot = 5.0 + 0.05 * k
        arrival = boot + offset + min_latency + rng.exponential(0.08)  # jitter up to ~0.5 s
        yaw = (0.1 * k) % (2 * math.pi) - math.pi
        msg = M.MAVLink_attitude_message(int(round(boot * 1000)), 0.0, 0.0, yaw, 0, 0, 0)
        buf.handle_message(msg, arrival)
    assert buf.clock.offset == pytest.approx(offset + min_latency, abs=0.005)
    newest = buf.newest_time("attitude")
    assert newest == pytest.approx(5.0 + 0.05 * 199 + offset + min_latency, abs=0.005)
    # the same with a known transport latency removes the bias
    clock = BootClock(transport_latency_s=min_latency)
    for k in range(50):
        clock.observe(1.0 + 0.1 * k, 1.0 + 0.1 * k + offset + min_latency + rng.exponential(0.05))
    assert clock.to_local(3.0) == pytest.approx(3.0 + offset, abs=0.01)
    # autopilot reboot: boot time jumps back; the old timeline has gone quiet, so once the new
    # one holds for a second (three samples), the estimate restarts on it
    assert clock.observe(0.5, 2000.0) is None
    assert clock.observe(1.0, 2000.5) is None
    assert clock.observe(1.5, 2001.0) == pytest.approx(2001.0 - min_latency)
    assert clock.reboots == 1
    assert clock.offset == pytest.approx(1999.5 - min_latency)


def gimbal_msg(boot_ms, q, flags, delta_yaw=NAN):
    return M.MAVLink_gimbal_device_attitude_status_message(
        0, 0, boot_ms, flags, list(q), NAN, NAN, NAN, 0, delta_yaw, NAN, 1
    )


@pytest.mark.parametrize(
    ("flags", "delta_yaw", "frame"),
    [
        (GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME, NAN, "earth"),
        (GIMBAL_DEVICE_FLAGS_YAW_LOCK, NAN, "earth"),
        (GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME, NAN, "vehicle"),
        (0, NAN, "vehicle"),
        (GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME, 0.7, "earth"),  # turned into earth frame
    ],
)
def test_gimbal_flags_pick_the_frame(flags, delta_yaw, frame):
    vehicle = (0.03, -0.05, 0.7)
    g = (0.01, -0.9, 0.25)
    buf = home_buffer(stale_after_s=1.0)
    gps_fix(50.0, buf)
    for k, ms in enumerate((1000, 1100)):
        arrival = 50.0 + 0.1 * k
        buf.handle_message(
            M.MAVLink_global_position_int_message(ms, 541700000, 78900000, 0, 60000, 0, 0, 0, 0),
            arrival,
        )
        buf.handle_message(M.MAVLink_attitude_message(ms, *vehicle, 0, 0, 0), arrival)
        buf.handle_message(gimbal_msg(ms, euler_to_quaternion(*g), flags, delta_yaw), arrival)
    pose = buf.pose_at(50.05)
    assert pose.gimbal_frame == frame
    expected_frame = "earth" if frame == "earth" and math.isnan(delta_yaw) else "vehicle"
    expected = rotation_ned_from_camera(vehicle, g, expected_frame)
    np.testing.assert_allclose(camera_rotation(pose), expected, atol=1e-9)
    if not math.isnan(delta_yaw):  # q_earth = Rz(delta_yaw) q_vehicle
        np.testing.assert_allclose(
            euler_to_matrix(*pose.gimbal_rpy), rot_z(0.7) @ euler_to_matrix(*g), atol=1e-9
        )


def test_a_precise_fix_keeps_the_height_error_of_a_barometer():
    """h_acc 0.3 m: the GNSS sigma follows it, the height's stays at the buffer's floor (a
    barometer drifts whatever the satellites say); 4 m: the height's grows to 6 m; an RTK
    fix's 1 cm (or a sender's 1 mm) is taken as 0.1 m; h_acc 0 (unknown) changes nothing."""
    buf = home_buffer(alt_sigma_m=1.0)
    cases = ((300, 0.3, 1.0), (4000, 4.0, 6.0), (0, 4.0, 6.0), (10, 0.1, 1.0), (1, 0.1, 1.0))
    for h_acc_mm, gnss, alt in cases:
        gps = M.MAVLink_gps_raw_int_message(
            0, 3, 0, 0, 0, 120, 200, 0, 0, 10, 0, h_acc_mm, 2500, 0, 0, 0
        )
        buf.handle_message(gps, 10.0)
        assert (buf.gnss_sigma_m, buf.alt_sigma_m) == pytest.approx((gnss, alt)), h_acc_mm


def test_messages_home_gps_accuracy_mount_orientation_and_no_origin():
    buf = TelemetryBuffer(stale_after_s=1.0)
    buf.handle_message(
        M.MAVLink_global_position_int_message(1000, 0, 0, 0, 0, 0, 0, 0, 0), 10.0
    )  # no EKF origin yet: 0, 0
    assert buf.newest_time("position") is None
    home = M.MAVLink_home_position_message(
        541700000, 78900000, 12500, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0, 0
    )
    buf.handle_message(home, 10.0)
    assert buf.home == pytest.approx((54.17, 7.89, 12.5))
    gps = M.MAVLink_gps_raw_int_message(0, 3, 0, 0, 0, 120, 200, 0, 0, 10, 0, 1500, 2500, 0, 0, 0)
    buf.handle_message(gps, 10.0)
    assert buf.rejected["GLOBAL_POSITION_INT: no position yet (N, N)"] == 1
    buf.handle_message(M.MAVLink_attitude_message(1000, 0.0, 0.0, 1.0, 0, 0, 0), 10.0)
    buf.handle_message(
        M.MAVLink_global_position_int_message(1000, 541700000, 78900000, 0, 1, 0, 0, 0, 0), 10.0
    )
    buf.handle_message(M.MAVLink_mount_orientation_message(1000, 0.0, -60.0, 10.0, 70.0), 10.0)
    pose = buf.pose_at(10.0)
    assert pose.gnss_sigma_m == pytest.approx(1.5)
    # the height is no better than 1.5 times the horizontal error (satellites are above)
    assert pose.alt_sigma_m == pytest.approx(2.25)
    assert pose.gimbal_frame == "earth"
    assert np.degrees(pose.gimbal_rpy) == pytest.approx((0.0, -60.0, 70.0), abs=1e-9)
    buf.handle_message(M.MAVLink_mount_orientation_message(1100, 0.0, -60.0, 10.0, NAN), 10.1)
    assert buf.pose_at(10.1).gimbal_frame == "vehicle"


def from_source(msg, system: int, component: int):
    """``msg`` as received from ``system``/``component`` (encoded and parsed)."""
    mav = M.MAVLink(None, srcSystem=system, srcComponent=component)
    parser = M.MAVLink(None)
    (parsed,) = parser.parse_buffer(msg.pack(mav))
    return parsed


def two_gimbals(buf: TelemetryBuffer, second: bool = True, until_s: float = 1.5) -> None:
    """The autopilot 1/1 with position and attitude; gimbal 1/154 nadir and (``second``)
    1/171 at 30 degrees below the horizon, interleaved, every 0.05 s from 50.0."""
    nadir = euler_to_quaternion(0.0, -math.pi / 2 + 1e-3, 0.0)
    oblique = euler_to_quaternion(0.0, math.radians(-30.0), 0.0)
    flags = GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME
    for k in range(round(until_s / 0.05)):
        arrival, ms = 50.0 + 0.05 * k, 1000 + 50 * k
        gps_fix(arrival, buf)
        buf.handle_message(
            from_source(
                M.MAVLink_global_position_int_message(
                    ms, 541700000, 78900000, 0, 60000, 0, 0, 0, 0
                ),
                1,
                1,
            ),
            arrival,
        )
        buf.handle_message(
            from_source(M.MAVLink_attitude_message(ms, 0, 0, 0, 0, 0, 0), 1, 1), arrival
        )
        buf.handle_message(from_source(gimbal_msg(ms, nadir, flags), 1, 154), arrival)
        if second:
            buf.handle_message(
                from_source(gimbal_msg(ms + 25, oblique, flags), 1, 171), arrival + 0.025
            )


def test_two_gimbals_one_is_used_the_other_rejected():
    """The first gimbal heard is the camera's; the second one's attitude never mixes in, so
    consecutive frames do not alternate between nadir and 30 degrees down."""
    buf = home_buffer(stale_after_s=1.0)
    two_gimbals(buf)
    pitches = [math.degrees(buf.pose_at(50.5 + 0.025 * k).gimbal_rpy[1]) for k in range(10)]
    assert pitches == pytest.approx([-89.9] * 10, abs=0.1)
    rejected = [why for why in buf.rejected if "a second gimbal" in why]
    assert len(rejected) == 1 and buf.rejected[rejected[0]] == 30


def test_a_pinned_gimbal_is_used_even_when_heard_second():
    buf = home_buffer(stale_after_s=1.0, gimbal_pin=(171, None))
    two_gimbals(buf)
    assert math.degrees(buf.pose_at(51.0).gimbal_rpy[1]) == pytest.approx(-30.0, abs=0.1)


def test_the_gimbal_in_use_falling_silent_makes_the_pose_stale():
    """Gimbal 1/154 stops at 51.5; 1/171 keeps reporting: no pose, not 1/171's attitude."""
    buf = home_buffer(stale_after_s=1.0)
    two_gimbals(buf, until_s=1.5)
    nadir_until = 50.0 + 1.45
    oblique = euler_to_quaternion(0.0, math.radians(-30.0), 0.0)
    for k in range(1, 60):
        arrival, ms = nadir_until + 0.05 * k, 1000 + 50 * (29 + k)
        gps_fix(arrival, buf)
        position = M.MAVLink_global_position_int_message(
            ms, 541700000, 78900000, 0, 60000, 0, 0, 0, 0
        )
        buf.handle_message(from_source(position, 1, 1), arrival)
        buf.handle_message(
            from_source(M.MAVLink_attitude_message(ms, 0, 0, 0, 0, 0, 0), 1, 1), arrival
        )
        msg = gimbal_msg(ms, oblique, GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME)
        buf.handle_message(from_source(msg, 1, 171), arrival)
    assert buf.newest_time("position") == pytest.approx(nadir_until + 0.05 * 59)
    result = buf.lookup(nadir_until + 2.5)
    assert isinstance(result, StaleTelemetry) and "gimbal attitude" in result.reason, result
