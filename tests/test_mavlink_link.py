"""MavlinkLink, CommandSender and Outbox over real UDP on 127.0.0.1 against SimVehicle."""

import math
import socket
import threading
import time

import numpy as np
import pytest
from conftest import free_udp_port, wait_until
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.geo.wgs84 import geodetic_to_ned, ned_to_geodetic
from sarmission.mavlink.commands import CommandSender, MissionItem, Outbox
from sarmission.mavlink.connection import MavlinkLink, signing_key_from_passphrase
from sarmission.mavlink.outbox_commands import Reposition, StatusText
from sarmission.mavlink.telemetry import MESSAGE_TYPES, TelemetryBuffer
from sarmission.mission.config import load_mission
from sim.vehicle import SimVehicle

STREAMS = {
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 10.0,
    M.MAVLINK_MSG_ID_ATTITUDE: 20.0,
    M.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS: 5.0,
    M.MAVLINK_MSG_ID_HOME_POSITION: 1.0,
    M.MAVLINK_MSG_ID_GPS_RAW_INT: 2.0,  # the fix type: positions are believed only with a fix
}


@pytest.fixture(scope="module")
def mission():
    return load_mission(overrides={"flight.takeoff": False})


@pytest.fixture
def ardupilot(mission):
    """An ArduPilot-like vehicle (streams on request, MISSION_REQUEST) and our link to it."""
    port = free_udp_port()
    vehicle = SimVehicle(
        f"udpin:127.0.0.1:{port}", mission, stream_on_request=True, legacy_mission_request=True
    ).start()
    # link lost after two missed 1 Hz heartbeats (a 1 s timeout flaps on scheduling jitter)
    link = MavlinkLink(f"udpout:127.0.0.1:{port}", link_timeout_s=2.0)
    assert link.wait_autopilot(3.0), "no autopilot HEARTBEAT"
    yield vehicle, link
    link.close()
    vehicle.stop()


def test_detects_autopilot_requests_streams_and_buffers_pose(ardupilot):
    vehicle, link = ardupilot
    assert link.autopilot == (1, 1) and link.link_ok
    buf = TelemetryBuffer(stale_after_s=0.5)
    link.subscribe(buf.handle_message, MESSAGE_TYPES)
    heartbeats = []
    link.subscribe(lambda msg, arrival: heartbeats.append(msg), {"HEARTBEAT"})
    # ArduPilot: nothing until asked, however many heartbeats (1 Hz) have come meanwhile
    assert wait_until(lambda: len(heartbeats) >= 2, 10.0)
    assert buf.newest_time("position") is None
    assert vehicle.sent_counts.get("GLOBAL_POSITION_INT", 0) == 0
    assert link.request_streams(STREAMS) == {k: M.MAV_RESULT_ACCEPTED for k in STREAMS}
    # a pose 0.2 s back needs samples on both sides of it, the gimbal's (5 Hz) among them
    assert wait_until(
        lambda: (
            buf.pose_at(time.monotonic() - 0.2) is not None
            and buf.newest_time("gimbal") is not None
        ),
        10.0,
    )
    now = time.monotonic()
    sim_now = vehicle.sim_time()
    pose = buf.pose_at(now - 0.2)
    assert buf.home == pytest.approx(vehicle.home)
    assert pose.gimbal_frame == "earth"  # vehicle-frame q with delta_yaw, turned to earth
    truth = vehicle.truth_state(sim_now - 0.2)
    n, e, _ = geodetic_to_ned(pose.lat, pose.lon, 0.0, *vehicle.home)
    assert math.hypot(n - truth.position_ned[0], e - truth.position_ned[1]) < 5.0
    assert pose.rel_alt_m == pytest.approx(-truth.position_ned[2], abs=5.0)
    yaw_err = (pose.yaw - truth.yaw + math.pi) % (2 * math.pi) - math.pi
    assert abs(yaw_err) < math.radians(5)


def test_statustext_command_and_mission_upload(ardupilot):
    vehicle, link = ardupilot
    sender = CommandSender(link, retries=2, ack_timeout_s=1.0)
    assert sender.statustext("SWIMMER 54.170412 7.890231 +-4m").accepted
    long_text = "PERSON IN WATER " + "x" * 70  # 86 chars: two chunks with one id
    assert sender.statustext(long_text, M.MAV_SEVERITY_CRITICAL).attempts == 2
    assert wait_until(lambda: len(vehicle.statustexts) == 2, 2.0)
    first, second = vehicle.statustexts
    assert (
        first.text == "SWIMMER 54.170412 7.890231 +-4m" and first.severity == M.MAV_SEVERITY_ALERT
    )
    assert second.text == long_text and (second.src_system, second.src_component) == (1, 191)

    start = vehicle.truth_state().position_ned.copy()
    home = vehicle.home
    target = np.array([start[0] + 150.0, start[1] - 80.0])
    lat, lon, _ = (float(v) for v in ned_to_geodetic(target[0], target[1], 0.0, *home))
    result = sender.reposition(lat, lon, 50.0)
    assert result.accepted and result.attempts == 1 and result.result == M.MAV_RESULT_ACCEPTED
    cmd = vehicle.commands[-1]
    assert cmd.command == M.MAV_CMD_DO_REPOSITION and cmd.is_int
    assert cmd.params[1] == 1 and math.isnan(cmd.params[3]) and cmd.params[0] == -1
    d0 = np.linalg.norm(start[:2] - target)
    assert wait_until(  # flying towards the target
        lambda: np.linalg.norm(vehicle.truth_state().position_ned[:2] - target) < d0 - 8.0, 20.0
    )

    assert sender.set_roi(lat, lon, 0.0).accepted
    items = [
        MissionItem(M.MAV_CMD_NAV_WAYPOINT, lat, lon, 40.0),
        MissionItem(M.MAV_CMD_NAV_LOITER_TIME, lat, lon, 40.0, params=(30.0, 0, 0, 0)),
    ]
    up = sender.upload_mission(items)
    assert up.accepted, up.error
    stored = vehicle.missions[0]
    assert len(stored) == 3 and stored[1].x == round(lat * 1e7) and stored[2].param1 == 30.0
    assert vehicle.sent_counts.get("MISSION_REQUEST", 0) >= 3  # asked the ArduPilot way

    refused = sender.command_long(42424)
    assert not refused.accepted and refused.result == M.MAV_RESULT_UNSUPPORTED
    assert "UNSUPPORTED" in refused.error


class SilentAutopilot:
    """A raw pymavlink peer that sends HEARTBEATs (as an autopilot) and never answers."""

    def __init__(self, port: int, key: bytes | None = None):
        self.conn = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{port}", source_system=1, source_component=1
        )
        self.conn.mav = M.MAVLink(self.conn, srcSystem=1, srcComponent=1)
        self.conn.mav.robust_parsing = True
        if key is not None:
            self.conn.setup_signing(key, sign_outgoing=True)
        self.received = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self):
        next_hb = 0.0
        while not self._stop.is_set():
            if time.monotonic() >= next_hb:
                next_hb = time.monotonic() + 0.2
                self.conn.mav.heartbeat_send(
                    M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, M.MAV_STATE_ACTIVE
                )
            msg = self.conn.recv_match(blocking=True, timeout=0.05)
            if msg is not None:
                self.received.append(msg)

    def close(self):
        self._stop.set()
        self._thread.join(2.0)
        self.conn.close()


def test_command_without_ack_retries_then_fails():
    port = free_udp_port()
    with MavlinkLink(f"udpin:127.0.0.1:{port}") as link:
        peer = SilentAutopilot(port)
        try:
            assert link.wait_autopilot(2.0)
            sender = CommandSender(link, retries=2, ack_timeout_s=0.3)
            result = sender.command_long(M.MAV_CMD_DO_SET_ROI_NONE)
            assert not result.accepted and result.result is None and result.no_answer
            assert result.attempts == 3 and "no COMMAND_ACK after 3 tries" in result.error

            def confirmations() -> list[int]:
                return [
                    m.confirmation for m in list(peer.received) if m.get_type() == "COMMAND_LONG"
                ]

            assert wait_until(lambda: len(confirmations()) >= 3, 10.0)
            assert confirmations() == [0, 1, 2]  # one send per try, counting the re-sends
            up = sender.upload_mission([MissionItem(M.MAV_CMD_NAV_WAYPOINT, 54.0, 7.0, 30.0)])
            assert not up.accepted and "silent" in up.error and up.attempts == 3
        finally:
            peer.close()
    # no autopilot at all: a clear answer at once
    with MavlinkLink(f"udpout:127.0.0.1:{free_udp_port()}") as lonely:
        res = CommandSender(lonely, retries=1, ack_timeout_s=0.2).reposition(54.0, 7.0, 30.0)
        assert not res.accepted and res.attempts == 0 and "no autopilot" in res.error


class _WatchedLink:
    """The link, counting how often the outbox's workers ask whether it is up."""

    def __init__(self, link) -> None:
        self._link = link
        self.checks = 0

    @property
    def link_ok(self) -> bool:
        self.checks += 1
        return self._link.link_ok

    def __getattr__(self, name):
        return getattr(self._link, name)


def test_outbox_delivers_after_link_loss(ardupilot):
    """Commands are acknowledged, STATUSTEXTs only sent (``repeats`` times, never called
    delivered); both wait out a silent autopilot and go once it is back."""
    vehicle, link = ardupilot
    watched = _WatchedLink(link)
    delivered, sent = [], []
    outbox = Outbox(
        CommandSender(watched, retries=1, ack_timeout_s=0.5),
        on_delivered=lambda action, result: delivered.append((action.key, result)),
        on_sent=lambda action, result: sent.append((action.key, action.attempts)),
        statustext_repeats=2,
        repeat_interval_s=0.3,
    )
    try:
        outbox.submit(StatusText("before loss"), key="a1")
        assert wait_until(lambda: len(sent) == 2, 3.0)
        assert wait_until(lambda: len(vehicle.statustexts) == 2, 3.0)
        vehicle.stop()  # the autopilot goes silent
        assert wait_until(lambda: not link.link_ok, 3.0)
        outbox.submit(StatusText("ALERT during loss"), key="a2")
        outbox.submit(Reposition(54.1705, 7.8905, 40.0), key="r1")
        # both workers find the link down again and again (each asks only with work to do)
        checks = watched.checks
        assert wait_until(lambda: watched.checks >= checks + 10, 10.0)
        assert [(a.key, a.attempts) for a in outbox.pending()] == [("a2", 0), ("r1", 0)]
        n_before = len(vehicle.statustexts)
        vehicle.start()  # back on the same port
        assert wait_until(lambda: not outbox.pending(), 8.0), outbox.pending()
        assert [k for k, _ in delivered] == ["r1"]  # only the command is acknowledged
        assert sent == [("a1", 1), ("a1", 2), ("a2", 1), ("a2", 2)]
        assert wait_until(lambda: len(vehicle.statustexts) == n_before + 2, 3.0)
        assert [s.text for s in vehicle.statustexts[n_before:]] == ["ALERT during loss"] * 2
        assert delivered[0][1].accepted and vehicle.commands[-1].command == M.MAV_CMD_DO_REPOSITION
    finally:
        outbox.close()


def test_malformed_bytes_are_counted_and_skipped(mission):
    port = free_udp_port()
    link = MavlinkLink(f"udpin:127.0.0.1:{port}")
    vehicle = SimVehicle(f"udpout:127.0.0.1:{port}", mission).start()  # streams by default
    try:
        assert link.wait_autopilot(3.0)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as junk:
            junk.sendto(b"\x00garbage that is not mavlink\xff" * 3, ("127.0.0.1", port))
            frame = bytearray(
                link.mav.heartbeat_encode(6, 8, 0, 0, 4).pack(link.mav)
            )  # valid frame, then a broken CRC
            frame[-1] ^= 0xFF
            junk.sendto(bytes(frame), ("127.0.0.1", port))
        assert wait_until(lambda: link.bad_packets >= 2, 2.0), link.bad_packets
        before = link.received
        assert wait_until(lambda: link.received > before + 10, 2.0)
        assert link.link_ok
        assert CommandSender(link, retries=1, ack_timeout_s=1.0).set_roi(54.17, 7.89, 0).accepted
    finally:
        link.close()
        vehicle.stop()


@pytest.mark.parametrize(
    ("peer_key", "ok"), [("sar-secret", True), ("wrong", False), (None, False)]
)
def test_signing(peer_key, ok):
    key = signing_key_from_passphrase("sar-secret")
    port = free_udp_port()
    with MavlinkLink(f"udpin:127.0.0.1:{port}", signing_key=key) as link:
        peer = SilentAutopilot(
            port, None if peer_key is None else signing_key_from_passphrase(peer_key)
        )
        try:
            assert link.wait_autopilot(1.0) == ok
            if ok:
                assert link.signing_stats["goodsig"] > 0
                assert wait_until(
                    lambda: any(m.get_type() == "HEARTBEAT" and m._signed for m in peer.received),
                    2.0,
                )
            else:
                assert link.rejected_signatures > 0 and link.autopilot is None
        finally:
            peer.close()
