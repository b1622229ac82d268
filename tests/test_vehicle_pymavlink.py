"""The MAVLink vehicle over real UDP on 127.0.0.1, driven by a pymavlink client."""

import collections
import math
import socket
import time

import pytest
from conftest import free_udp_port, wait_until
from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.geo.wgs84 import geodetic_to_ned, ned_to_geodetic
from sarmission.mavlink.connection import mavlink2_connection
from sarmission.mission.config import load_mission
from sim.vehicle import ARM_NO_HOME, SimVehicle


@pytest.fixture(scope="module")
def mission():
    return load_mission(overrides={"flight.takeoff": False})


class Link:
    """A vehicle plus a connected pymavlink client (system 255, component 190)."""

    def __init__(self, mission, **kwargs):
        self.port = free_udp_port()
        self.vehicle = SimVehicle(f"udpin:127.0.0.1:{self.port}", mission, **kwargs).start()
        self.conn = mavlink2_connection(f"udpout:127.0.0.1:{self.port}", 255, 190)
        self.conn.mav.heartbeat_send(
            M.MAV_TYPE_ONBOARD_CONTROLLER, M.MAV_AUTOPILOT_INVALID, 0, 0, M.MAV_STATE_ACTIVE
        )

    def recv(self, mtype, timeout=3.0, cond=None):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            msg = self.conn.recv_match(type=mtype, blocking=True, timeout=0.05)
            if msg is not None and (cond is None or cond(msg)):
                return msg
        raise AssertionError(f"no {mtype} within {timeout} s")

    def command_long(self, command, *params):
        p = list(params) + [0.0] * (7 - len(params))
        self.conn.mav.command_long_send(1, 1, command, 0, *p)
        return self.recv("COMMAND_ACK", cond=lambda m: m.command == command).result

    def close(self):
        self.conn.close()
        self.vehicle.stop()


@pytest.fixture
def link(mission):
    lk = Link(mission)
    yield lk
    lk.close()


def collect_messages(conn, needed: dict[str, int], timeout: float = 60.0):
    """Messages by type until each type in ``needed`` has arrived that many times (the
    deadline only bounds a hang); counts and ``time_boot_ms`` stamps by type."""
    counts = collections.Counter()
    stamps = collections.defaultdict(list)
    deadline = time.monotonic() + timeout
    while any(counts[t] < n for t, n in needed.items()):
        assert time.monotonic() < deadline, (needed, counts)
        msg = conn.recv_match(blocking=True, timeout=0.05)
        if msg is None:
            continue
        counts[msg.get_type()] += 1
        if hasattr(msg, "time_boot_ms"):
            stamps[msg.get_type()].append(msg.time_boot_ms)
    return counts, stamps


def test_telemetry_rates(link):
    """Each stream's rate, read from the vehicle's own ``time_boot_ms`` stamps (how often the
    receiver happens to be scheduled says nothing about the sender)."""
    link.recv("HEARTBEAT")
    rates = {
        "GLOBAL_POSITION_INT": 10,
        "ATTITUDE": 20,
        "GIMBAL_DEVICE_ATTITUDE_STATUS": 5,
        "SYSTEM_TIME": 1,
    }
    counts, stamps = collect_messages(
        link.conn, {**{t: r * 3 for t, r in rates.items()}, "HEARTBEAT": 2, "HOME_POSITION": 1}
    )
    for mtype, rate in rates.items():
        dt = (stamps[mtype][-1] - stamps[mtype][0]) / 1000 / (len(stamps[mtype]) - 1)
        assert 1 / dt == pytest.approx(rate, rel=0.05), mtype
    hb = link.recv("HEARTBEAT")
    assert (hb.type, hb.autopilot) == (M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_ARDUPILOTMEGA)
    g = link.recv("GIMBAL_DEVICE_ATTITUDE_STATUS")
    assert g.flags & M.GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME
    w, x, y, z = g.q
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x)))))
    assert pitch == pytest.approx(-90.0, abs=3.0)
    pos = link.recv("GLOBAL_POSITION_INT")
    assert pos.relative_alt == pytest.approx(70_000, abs=5_000)
    assert pos.lat != 0 and pos.lon != 0


def test_commands_are_acknowledged(link):
    assert link.command_long(31999) == M.MAV_RESULT_UNSUPPORTED
    assert (
        link.command_long(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_ATTITUDE, 100_000)
        == M.MAV_RESULT_ACCEPTED
    )
    assert link.command_long(M.MAV_CMD_SET_MESSAGE_INTERVAL, 31, 100_000) == M.MAV_RESULT_DENIED
    link.conn.mav.command_long_send(
        1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION, 0, 0, 0, 0, 0, 0
    )
    seen = {}
    deadline = time.monotonic() + 3.0
    while len(seen) < 2 and time.monotonic() < deadline:
        m = link.conn.recv_match(
            type=["AUTOPILOT_VERSION", "COMMAND_ACK"], blocking=True, timeout=0.05
        )
        if m is not None:
            seen[m.get_type()] = m
    assert seen["COMMAND_ACK"].result == M.MAV_RESULT_ACCEPTED
    assert seen["AUTOPILOT_VERSION"].capabilities & M.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    link.conn.mav.command_int_send(
        1, 1, M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 31998, 0, 0, 0, 0, 0, 0, 0, 0, 0.0
    )
    assert link.recv("COMMAND_ACK", cond=lambda m: m.command == 31998).result == (
        M.MAV_RESULT_UNSUPPORTED
    )


def upload(link, items, request_type):
    link.conn.mav.mission_count_send(1, 1, len(items), 0)
    for _ in items:
        req = link.recv(request_type)
        it = items[req.seq]
        link.conn.mav.mission_item_int_send(1, 1, req.seq, *it, 0)
    return link.recv("MISSION_ACK")


def download(link):
    link.conn.mav.mission_request_list_send(1, 1, 0)
    count = link.recv("MISSION_COUNT").count
    got = []
    for seq in range(count):
        link.conn.mav.mission_request_int_send(1, 1, seq, 0)
        got.append(link.recv("MISSION_ITEM_INT", cond=lambda m, s=seq: m.seq == s))
    link.conn.mav.mission_ack_send(1, 1, M.MAV_MISSION_ACCEPTED, 0)
    return got


def three_items(mission):
    home = mission.area.home
    items = []
    for i in range(3):
        lat, lon, _ = ned_to_geodetic(50.0 * i, 20.0, 0.0, *home)
        items.append(
            (
                M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                M.MAV_CMD_NAV_WAYPOINT,
                0,
                1,
                0.0,
                2.0,
                0.0,
                float("nan"),
                int(round(float(lat) * 1e7)),
                int(round(float(lon) * 1e7)),
                40.0 + i,
            )
        )
    return items


@pytest.mark.parametrize("legacy", [False, True])
def test_mission_upload_and_read_back(mission, legacy):
    link = Link(mission, legacy_mission_request=legacy)
    try:
        items = three_items(mission)
        ack = upload(link, items, "MISSION_REQUEST" if legacy else "MISSION_REQUEST_INT")
        assert ack.type == M.MAV_MISSION_ACCEPTED
        got = download(link)
        assert [(m.seq, m.command, m.x, m.y, m.z) for m in got] == [
            (i, it[1], it[8], it[9], it[10]) for i, it in enumerate(items)
        ]
        assert len(link.vehicle.missions[0]) == 3
    finally:
        link.close()


def test_mission_upload_rerequests_lost_items(link, mission):
    items = three_items(mission)
    link.conn.mav.mission_count_send(1, 1, 3, 0)
    first = link.recv("MISSION_REQUEST_INT")
    assert first.seq == 0
    again = link.recv("MISSION_REQUEST_INT", timeout=2.0)  # we stayed silent: asked again
    assert again.seq == 0
    for seq in range(3):
        link.conn.mav.mission_item_int_send(1, 1, seq, *items[seq], 0)
        if seq < 2:
            link.recv("MISSION_REQUEST_INT", cond=lambda m, s=seq: m.seq == s + 1)
    assert link.recv("MISSION_ACK").type == M.MAV_MISSION_ACCEPTED


def test_reposition_flies_to_target_and_roi_points_gimbal(mission):
    link = Link(mission, speedup=10.0)
    try:
        v = link.vehicle
        home = mission.area.home
        target_ne = (0.0, 0.0)
        lat, lon, _ = ned_to_geodetic(*target_ne, 0.0, *home)

        def dist():
            now_ms = (v.sim_time() - 0.3) * 1000  # skip messages queued earlier
            p = link.recv("GLOBAL_POSITION_INT", cond=lambda m: m.time_boot_ms >= now_ms)
            n, e, _ = geodetic_to_ned(p.lat / 1e7, p.lon / 1e7, p.alt / 1000, *home)
            return math.hypot(float(n) - target_ne[0], float(e) - target_ne[1])

        d0 = dist()
        link.conn.mav.command_int_send(
            1,
            1,
            M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            M.MAV_CMD_DO_REPOSITION,
            0,
            0,
            -1.0,
            1.0,
            0.0,
            float("nan"),
            int(round(float(lat) * 1e7)),
            int(round(float(lon) * 1e7)),
            50.0,
        )
        ack = link.recv("COMMAND_ACK", cond=lambda m: m.command == M.MAV_CMD_DO_REPOSITION)
        assert ack.result == M.MAV_RESULT_ACCEPTED
        # flying towards the target: 50 m closer (5 s of flight at 10 m/s)
        assert wait_until(lambda: dist() < d0 - 50.0, 20.0), (d0, dist())
        hb = link.recv("HEARTBEAT")
        assert hb.custom_mode == 4  # GUIDED
        # ROI at a point on the ground: the gimbal pitch moves off nadir.
        rlat, rlon, _ = ned_to_geodetic(60.0, 0.0, 0.0, *home)
        link.conn.mav.command_int_send(
            1,
            1,
            M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            M.MAV_CMD_DO_SET_ROI_LOCATION,
            0,
            0,
            0,
            0,
            0,
            0,
            int(round(float(rlat) * 1e7)),
            int(round(float(rlon) * 1e7)),
            0.0,
        )
        assert link.recv("COMMAND_ACK", cond=lambda m: m.command == 195).result == 0
        assert wait_until(
            lambda: -80.0 < math.degrees(v.truth_state().gimbal_pitch) < -20.0, 10.0
        ), math.degrees(v.truth_state().gimbal_pitch)
        assert [c.command for c in v.commands][-2:] == [192, 195]
    finally:
        link.close()


def test_malformed_bytes_do_not_stop_the_vehicle(link):
    link.recv("HEARTBEAT")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as raw:
        raw.sendto(
            b"\xfd\xff\x00\x00\x00\x01\x01\x4c\x00\x00" + b"\x00" * 20, ("127.0.0.1", link.port)
        )
        raw.sendto(bytes(range(256)) * 4, ("127.0.0.1", link.port))
        raw.sendto(b"\xfe\x05garbage", ("127.0.0.1", link.port))
        raw.sendto(b"", ("127.0.0.1", link.port))
    # A valid packet with a corrupted CRC.
    good = link.conn.mav.command_long_encode(1, 1, 31999, 0, 0, 0, 0, 0, 0, 0, 0).pack(
        link.conn.mav
    )
    link.conn.write(good[:-2] + b"\x00\x00")
    assert wait_until(lambda: link.vehicle.bad_packets > 0, 10.0)
    assert link.vehicle.is_alive
    assert link.command_long(31997) == M.MAV_RESULT_UNSUPPORTED
    assert link.vehicle.bad_packets > 0


def test_statustext_is_logged_and_kept(link, caplog):
    caplog.set_level("WARNING", logger="sim.vehicle")
    link.conn.mav.statustext_send(M.MAV_SEVERITY_ALERT, b"SAR: person at 54.17,7.89")
    long_text = "SAR target 1 confirmed at lat 54.1712345 lon 7.8912345, score 0.93, track 17"
    link.conn.mav.statustext_send(M.MAV_SEVERITY_CRITICAL, long_text[:50].encode(), 7, 0)
    link.conn.mav.statustext_send(M.MAV_SEVERITY_CRITICAL, long_text[50:].encode(), 7, 1)
    deadline = time.monotonic() + 2.0
    while len(link.vehicle.statustexts) < 2 and time.monotonic() < deadline:
        time.sleep(0.02)
    texts = [(s.severity, s.text) for s in link.vehicle.statustexts]
    assert texts == [
        (M.MAV_SEVERITY_ALERT, "SAR: person at 54.17,7.89"),
        (M.MAV_SEVERITY_CRITICAL, long_text),
    ]
    assert link.vehicle.statustexts[0].src_system == 255
    assert "SAR: person" in caplog.text


def test_stream_on_request_sends_only_heartbeat_until_asked(mission):
    link = Link(mission, stream_on_request=True)
    try:
        counts, _ = collect_messages(link.conn, {"HEARTBEAT": 2})
        assert set(counts) == {"HEARTBEAT"}
        assert (
            link.command_long(
                M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 250_000
            )
            == 0
        )
        counts, stamps = collect_messages(link.conn, {"GLOBAL_POSITION_INT": 8})
        position = stamps["GLOBAL_POSITION_INT"]
        assert (position[-1] - position[0]) / (len(position) - 1) == pytest.approx(250, rel=0.05)
        assert counts["ATTITUDE"] == 0 and counts["GIMBAL_DEVICE_ATTITUDE_STATUS"] == 0
        assert (
            link.command_long(
                M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, -1
            )
            == 0
        )
        collect_messages(link.conn, {"HEARTBEAT": 1})  # what was on its way has arrived
        counts, _ = collect_messages(link.conn, {"HEARTBEAT": 2})
        assert counts["GLOBAL_POSITION_INT"] == 0
    finally:
        link.close()


def test_gps_raw_int_reports_a_3d_fix_and_its_accuracy(link, mission):
    gps = link.recv("GPS_RAW_INT")
    pos = link.recv("GLOBAL_POSITION_INT")
    assert gps.fix_type >= M.GPS_FIX_TYPE_3D_FIX and gps.satellites_visible >= 6
    assert gps.h_acc == round(mission.telemetry.gnss_noise_m * 1000)
    n, e, _ = geodetic_to_ned(gps.lat / 1e7, gps.lon / 1e7, 0.0, pos.lat / 1e7, pos.lon / 1e7, 0.0)
    assert math.hypot(float(n), float(e)) < 50.0  # the same aircraft (0.2 s apart at most)


def test_arducopter_like_start_no_fix_then_fix_then_home(mission):
    """Until ``gps_fix_after_s`` no fix and position 0,0; until ``home_after_s`` no home, and
    arming is refused with the reason in a STATUSTEXT after the ACK (ArduPilot's order)."""
    link = Link(mission, gps_fix_after_s=1.5, home_after_s=3.0)
    try:
        v = link.vehicle
        gps = link.recv("GPS_RAW_INT")
        pos = link.recv("GLOBAL_POSITION_INT")
        assert v.sim_time() < 1.5, "too slow to see the start"
        assert (gps.fix_type, gps.lat, gps.lon, gps.satellites_visible) == (0, 0, 0, 0)
        assert (pos.lat, pos.lon) == (0, 0)
        assert link.command_long(M.MAV_CMD_GET_HOME_POSITION) == M.MAV_RESULT_FAILED
        link.conn.mav.command_long_send(
            1, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0
        )
        first = link.recv(
            ["COMMAND_ACK", "STATUSTEXT"],
            cond=lambda m: (
                m.get_type() == "STATUSTEXT" or m.command == M.MAV_CMD_COMPONENT_ARM_DISARM
            ),
        )
        assert first.get_type() == "COMMAND_ACK" and first.result == M.MAV_RESULT_FAILED
        text = link.recv("STATUSTEXT")
        assert (text.severity, text.text) == (M.MAV_SEVERITY_CRITICAL, ARM_NO_HOME)
        homes_before = v.sent_counts.get("HOME_POSITION", 0)
        gps = link.recv("GPS_RAW_INT", timeout=10.0, cond=lambda m: m.fix_type >= 3)
        assert gps.lat != 0 and link.recv("GLOBAL_POSITION_INT").lat != 0
        home = link.recv("HOME_POSITION", timeout=10.0)
        assert homes_before == 0 and v.sim_time() >= 3.0
        assert home.latitude == round(mission.area.home_lat * 1e7)
        assert link.command_long(M.MAV_CMD_GET_HOME_POSITION) == M.MAV_RESULT_ACCEPTED
        assert link.command_long(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    finally:
        link.close()


def test_duplicate_packets_are_dropped_by_sequence_number(link):
    link.recv("HEARTBEAT")
    mav = link.conn.mav

    def packet(mav, seq: int, text: bytes) -> bytes:
        mav.seq = seq
        return mav.statustext_encode(M.MAV_SEVERITY_ALERT, text).pack(mav)

    first, again = packet(mav, 100, b"T1-ab SAR swimmer"), packet(mav, 101, b"T1-ab SAR swimmer")
    other = mavlink2_connection(f"udpout:127.0.0.1:{link.port}", 255, 191)  # another source
    try:
        foreign = packet(other.mav, 100, b"T2-cd SAR diver")
        assert (first[4], again[4], foreign[4]) == (100, 101, 100)  # sequence numbers
        for packet in (first, first, again, again, again):  # a radio repeating packets
            link.conn.write(packet)
        other.write(foreign)  # same sequence number, other component: not a duplicate
        assert wait_until(lambda: len(link.vehicle.statustexts) >= 3, 3.0)
        time.sleep(0.2)  # let any duplicate that slipped through arrive
        texts = sorted(s.text for s in link.vehicle.statustexts)
        assert texts == ["T1-ab SAR swimmer", "T1-ab SAR swimmer", "T2-cd SAR diver"]
        assert link.vehicle.duplicates_dropped == 3
    finally:
        other.close()
