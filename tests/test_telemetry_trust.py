"""TelemetryBuffer against bad telemetry: non-finite and absurd fields, no GPS fix, no home,
time jumps, reboots, position jumps. Messages are really encoded and parsed (pymavlink), so NaN
and the sender's system/component survive the trip as they would on the wire."""

import logging
import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.mavlink.telemetry import JUMP_CONFIRM_S, StaleTelemetry, TelemetryBuffer

NAN, INF = float("nan"), float("inf")
AUTOPILOT = (1, 1)
HOME_LAT, HOME_LON = 43.0, 10.0


class _Sink:
    def __init__(self) -> None:
        self.data = b""

    def write(self, data: bytes) -> None:
        self.data += data


def wire(msg, source=AUTOPILOT):
    """``msg`` as a receiver gets it from ``source``: encoded, then parsed."""
    sink = _Sink()
    M.MAVLink(sink, srcSystem=source[0], srcComponent=source[1]).send(msg)
    parser = M.MAVLink(None)
    parser.robust_parsing = True
    (parsed,) = parser.parse_buffer(sink.data)
    return parsed


def position(ms, lat=HOME_LAT, lon=HOME_LON, rel_alt_m=60.0):
    return M.MAVLink_global_position_int_message(
        ms,
        round(lat * 1e7),
        round(lon * 1e7),
        round(rel_alt_m * 1000),
        round(rel_alt_m * 1000),
        0,
        0,
        0,
        0,
    )


def attitude(ms, yaw=0.3):
    return M.MAVLink_attitude_message(ms, 0.01, -0.02, yaw, 0, 0, 0)


def gps(fix_type=3):
    return M.MAVLink_gps_raw_int_message(0, fix_type, 0, 0, 0, 120, 200, 0, 0, 10)


def home():
    return M.MAVLink_home_position_message(
        round(HOME_LAT * 1e7), round(HOME_LON * 1e7), 5000, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0, 0
    )


def feed(buf, t0, n, start_ms=10_000, step_ms=100, lat=HOME_LAT, source=AUTOPILOT, gps_fix=3):
    """``n`` samples of position + attitude every ``step_ms`` with GPS and home, from ``t0``."""
    for k in range(n):
        arrival = t0 + k * step_ms / 1000.0
        ms = start_ms + k * step_ms
        buf.handle_message(wire(gps(gps_fix), source), arrival)
        buf.handle_message(wire(home(), source), arrival)
        buf.handle_message(wire(position(ms, lat=lat), source), arrival)
        buf.handle_message(wire(attitude(ms), source), arrival)
    return t0 + (n - 1) * step_ms / 1000.0


def test_a_pose_needs_home_and_a_3d_gps_fix():
    buf = TelemetryBuffer()
    for k in range(5):  # position and attitude, but GPS without a fix and no home yet
        buf.handle_message(wire(gps(fix_type=1)), 100.0 + 0.1 * k)
        buf.handle_message(wire(position(1000 + 100 * k)), 100.0 + 0.1 * k)
        buf.handle_message(wire(attitude(1000 + 100 * k)), 100.0 + 0.1 * k)
    assert buf.rejected["GLOBAL_POSITION_INT: no 3D GPS fix (fix type N)"] == 5
    assert buf.lookup(100.2).reason == "no home position from the autopilot yet"
    buf.handle_message(wire(home()), 100.5)
    assert buf.lookup(100.2).reason == "no position yet"
    last = feed(buf, 101.0, 5, start_ms=2000)
    pose = buf.pose_at(last)
    assert pose is not None and pose.lat == pytest.approx(HOME_LAT)
    # the GPS_RAW_INT stream stops: positions are no longer believed
    buf.handle_message(wire(position(2400 + 6000)), last + 6.0)
    assert buf.rejected["GLOBAL_POSITION_INT: GPS_RAW_INT older than N s: GPS fix unknown"] == 1


def test_no_gps_raw_int_at_all_means_no_position():
    buf = TelemetryBuffer()
    buf.handle_message(wire(home()), 1.0)
    buf.handle_message(wire(position(1000)), 1.0)
    assert buf.newest_time("position") is None
    assert buf.rejected["GLOBAL_POSITION_INT: no GPS_RAW_INT heard: GPS fix unknown"] == 1


@pytest.mark.parametrize(
    ("bad", "reason"),
    [
        (
            M.MAVLink_mount_orientation_message(10_500, NAN, -60.0, 10.0, NAN),
            "MOUNT_ORIENTATION: mount angles not finite",
        ),
        (
            M.MAVLink_mount_orientation_message(10_500, 0.0, INF, 10.0, NAN),
            "MOUNT_ORIENTATION: mount angles not finite",
        ),
        (
            M.MAVLink_mount_orientation_message(10_500, 0.0, -60.0, 10.0, INF),
            "MOUNT_ORIENTATION: mount yaw_absolute out of range",
        ),
        (position(10_500, lat=214.7), "GLOBAL_POSITION_INT: lat N out of range"),
        (
            M.MAVLink_attitude_message(10_500, NAN, 0.0, 0.0, 0, 0, 0),
            "ATTITUDE: attitude not finite",
        ),
        (
            M.MAVLink_attitude_quaternion_message(10_500, 0.0, 0.0, 0.0, 0.0, 0, 0, 0),
            "ATTITUDE_QUATERNION: quaternion norm N",
        ),
        (
            M.MAVLink_gimbal_device_attitude_status_message(
                0, 0, 10_500, 0, [NAN, 0, 0, 0], NAN, NAN, NAN, 0, NAN, NAN, 1
            ),
            "GIMBAL_DEVICE_ATTITUDE_STATUS: gimbal quaternion not finite",
        ),
        (
            M.MAVLink_home_position_message(0, 2_000_000_000, 0, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0, 0),
            "HOME_POSITION: lon N out of range",
        ),
    ],
)
def test_absurd_fields_are_rejected_and_counted_never_believed(bad, reason):
    buf = TelemetryBuffer()
    last = feed(buf, 50.0, 6)
    before = buf.pose_at(last)
    assert before is not None
    buf.handle_message(wire(bad, source=AUTOPILOT), last)
    assert buf.rejected[reason] == 1, dict(buf.rejected)
    after = buf.pose_at(last)
    assert after == before
    assert buf.home == pytest.approx((HOME_LAT, HOME_LON, 5.0))


def test_a_flood_of_bad_messages_warns_a_few_times_and_counts_each(caplog):
    buf = TelemetryBuffer()
    bad = wire(M.MAVLink_mount_orientation_message(1000, NAN, NAN, NAN, NAN), (77, 1))
    with caplog.at_level(logging.WARNING, logger="sarmission.mavlink.telemetry"):
        for k in range(1000):
            buf.handle_message(bad, 1.0 + k * 1e-3)
    assert buf.rejected["MOUNT_ORIENTATION: mount angles not finite"] == 1000
    assert 1 <= len(caplog.records) <= 2


def test_a_position_jump_faster_than_an_aircraft_is_rejected():
    buf = TelemetryBuffer()
    last = feed(buf, 10.0, 5)
    buf.handle_message(wire(position(10_500, lat=HOME_LAT + 0.05)), last + 0.1)  # 5.6 km in 0.1 s
    assert buf.rejected["GLOBAL_POSITION_INT: position jump of N m in N s"] == 1
    assert buf.pose_at(last + 0.1).lat == pytest.approx(HOME_LAT)


JUMP_LAT = HOME_LAT + 0.05  # 5.6 km north


def positions(buf, t0, seconds, lat, start_ms):
    """Position, attitude and GPS every 0.1 s for ``seconds`` from arrival ``t0`` (boot time
    ``start_ms`` then); returns the last arrival."""
    n = round(seconds * 10)
    for k in range(n):
        arrival, ms = t0 + 0.1 * k, start_ms + 100 * k
        buf.handle_message(wire(gps()), arrival)
        buf.handle_message(wire(position(ms, lat=lat)), arrival)
        buf.handle_message(wire(attitude(ms)), arrival)
    return t0 + 0.1 * (n - 1)


def jumped(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if "position jumped" in r.getMessage()]


def test_a_jump_after_a_gap_is_rejected_until_it_persists_then_believed_once(caplog):
    """A 2.5 s gap in the positions does not let a 5.6 km jump through (the allowance grows
    with the gap: 385 m); held for JUMP_CONFIRM_S it is believed, with one warning, and the
    positions from before it are dropped."""
    buf = TelemetryBuffer()
    last = feed(buf, 10.0, 20)  # boot ms 10_000..11_900
    with caplog.at_level(logging.WARNING, logger="sarmission.mavlink.telemetry"):
        t = positions(buf, last + 2.5, JUMP_CONFIRM_S - 1.0, JUMP_LAT, 11_900 + 2_500)
        assert isinstance(buf.lookup(t), StaleTelemetry)  # no position believed for 9 s
        assert buf.latest_position()[0] == pytest.approx(HOME_LAT)
        assert jumped(caplog) == []
        t = positions(buf, t + 0.1, 2.0, JUMP_LAT, 11_900 + round((t + 0.1 - last) * 1000))
    assert len(jumped(caplog)) == 1
    assert buf.pose_at(t).lat == pytest.approx(JUMP_LAT)
    assert isinstance(buf.lookup(last), StaleTelemetry)  # nothing before the jump is kept


def test_a_held_jump_is_not_believed_as_the_allowance_grows():
    """1.2 km away, held: the time since the last believed position grows past what an
    aircraft could fly in it (after 8 s), but the jump is only believed by its confirmation."""
    buf = TelemetryBuffer()
    last = feed(buf, 10.0, 20)
    lat = HOME_LAT + 0.0108  # 1.2 km north
    t = positions(buf, last + 0.1, JUMP_CONFIRM_S - 0.5, lat, 12_000)
    assert buf.latest_position()[0] == pytest.approx(HOME_LAT)
    positions(buf, t + 0.1, 1.0, lat, 11_900 + round((t + 0.1 - last) * 1000))
    assert buf.latest_position()[0] == pytest.approx(lat)


def test_a_glitch_that_returns_is_never_believed_and_the_track_goes_on(caplog):
    buf = TelemetryBuffer()
    last = feed(buf, 10.0, 20)
    with caplog.at_level(logging.WARNING, logger="sarmission.mavlink.telemetry"):
        t = positions(buf, last + 0.1, 3.0, JUMP_LAT, 12_000)  # 3 s away, then back
        t = positions(buf, t + 0.1, 1.0, HOME_LAT, 12_000 + 3_000)
    assert jumped(caplog) == []
    assert buf.pose_at(t).lat == pytest.approx(HOME_LAT)
    # a small glitch (30 m in 0.1 s) does not hold up the true positions after it
    buf.handle_message(wire(position(16_000, lat=HOME_LAT + 0.00027)), t + 0.1)
    t = positions(buf, t + 0.2, 1.0, HOME_LAT, 16_100)
    assert buf.newest_time("position") == pytest.approx(t)


def test_a_forged_time_jump_forward_is_rejected_and_moves_nothing():
    buf = TelemetryBuffer()
    last = feed(buf, 10.0, 10)
    offset = buf.clock.offset
    # a sample claiming a capture 1000 s after the current one, arriving now
    buf.handle_message(wire(position(10_900 + 1_000_000, lat=HOME_LAT + 1e-4)), last + 0.1)
    assert buf.rejected["GLOBAL_POSITION_INT: time_boot_ms off the sender's timeline"] == 1
    assert buf.clock.offset == offset
    feed(buf, last + 0.1, 3, start_ms=11_000)
    assert buf.clock.reboots == 0 and buf.resets == 0


def test_a_forged_time_jump_back_while_the_autopilot_streams_resets_nothing():
    buf = TelemetryBuffer()
    last = feed(buf, 10.0, 10)
    for k in range(20):  # a forger sends old boot times between real samples for 2 s
        t = last + 0.1 * (k + 1)
        buf.handle_message(wire(position(50 + 100 * k, lat=HOME_LAT + 2e-4)), t)
        feed(buf, t, 1, start_ms=10_900 + 100 * (k + 1))
    assert buf.clock.reboots == 0 and buf.resets == 0
    assert buf.pose_at(last + 2.0).lat == pytest.approx(HOME_LAT)
    assert buf.rejected["GLOBAL_POSITION_INT: time_boot_ms off the sender's timeline"] == 20


def test_an_autopilot_reboot_drops_what_it_said_before():
    buf = TelemetryBuffer()
    last = feed(buf, 10.0, 10, start_ms=600_000)
    assert buf.home is not None
    # silence, then the autopilot boots again: boot time starts near zero, no fix, no home yet
    t = last + 20.0
    for k in range(15):
        buf.handle_message(wire(attitude(500 + 100 * k)), t + 0.1 * k)
    assert buf.clock.reboots == 1 and buf.resets == 1
    assert buf.home is None and buf.newest_time("position") is None
    assert isinstance(buf.lookup(t + 1.4), StaleTelemetry)
    assert buf.newest_time("attitude") == pytest.approx(t + 1.4, abs=0.01)


def test_a_gimbal_component_has_its_own_clock():
    buf = TelemetryBuffer()
    last = feed(buf, 10.0, 10)
    offset = buf.clock.offset
    for k in range(10):  # the gimbal booted later: its time_boot_ms is 9 s behind
        msg = M.MAVLink_gimbal_device_attitude_status_message(
            0,
            0,
            1000 + 100 * k,
            32,
            [math.cos(-math.pi / 4), 0, math.sin(-math.pi / 4), 0],
            NAN,
            NAN,
            NAN,
            0,
            NAN,
            NAN,
            1,
        )
        buf.handle_message(wire(msg, source=(1, 154)), last - 0.9 + 0.1 * k)
    assert buf.clock.offset == offset
    assert not buf.rejected
    pose = buf.pose_at(last)
    assert pose is not None and pose.gimbal_rpy[1] == pytest.approx(-math.pi / 2, abs=1e-6)


def test_no_pose_for_a_time_before_the_autopilot_was_replaced():
    """A frame taken just before another autopilot was adopted is not placed with the new
    one's telemetry, although its first samples are within the staleness limit of it."""
    buf = TelemetryBuffer()
    last = feed(buf, 10.0, 20)
    buf.reset("autopilot 1/1 replaced by 2/1", at=last + 0.5)
    new = feed(buf, last + 0.6, 20, start_ms=50_000, source=(2, 1))
    assert buf.pose_at(new) is not None
    stale = buf.lookup(last + 0.4)  # 0.2 s before the new autopilot's first sample
    assert isinstance(stale, StaleTelemetry) and "before the autopilot was replaced" in stale.reason
