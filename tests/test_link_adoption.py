"""One adopted autopilot per link, over real UDP on 127.0.0.1, with hostile senders beside it.

A spoofer (system 77) claiming to be an autopilot, a component of the vehicle's own system that is
not its autopilot, and foreign telemetry (lat 214.7, NaN gimbal angles) must neither take the link
nor reach the autopilot's subscribers; the real vehicle is :class:`sim.vehicle.SimVehicle`.
"""

from __future__ import annotations

import logging
import math
import os
import socket

import pytest
from conftest import free_udp_port, wait_until
from link_peers import RawPeer
from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.mavlink.commands import CommandSender
from sarmission.mavlink.connection import MavlinkLink
from sarmission.mission.config import load_mission
from sim.vehicle import SimVehicle

TELEMETRY = ("GLOBAL_POSITION_INT", "ATTITUDE", "HOME_POSITION", "MOUNT_ORIENTATION")


@pytest.fixture(scope="module")
def mission():
    return load_mission(overrides={"flight.takeoff": False})


def _bogus_position(peer: RawPeer) -> None:
    peer.send(
        peer.conn.mav.global_position_int_encode(1000, 2147000000, 70000000, 0, 0, 0, 0, 0, 0)
    )


def _bogus_mount(peer: RawPeer) -> None:
    peer.send(peer.conn.mav.mount_orientation_encode(1000, math.nan, math.nan, math.nan, math.nan))


def test_spoofer_heard_first_then_silent_hands_the_link_to_the_vehicle(mission, caplog):
    caplog.set_level(logging.INFO, logger="sarmission.mavlink")
    port = free_udp_port()
    # another system is adopted only after the adopted one is gone (a minute by default)
    with MavlinkLink(f"udpin:127.0.0.1:{port}", link_timeout_s=2.0, system_switch_s=3.0) as link:
        adopted: list[tuple] = []
        link.on_adopted(lambda new, old: adopted.append((new, old)))
        attitudes: list[tuple[int, int]] = []
        link.subscribe_autopilot(
            lambda m, t: attitudes.append((m.get_srcSystem(), m.get_srcComponent())), ["ATTITUDE"]
        )
        spoofer = RawPeer(port, 77)
        vehicle = None
        try:
            assert wait_until(lambda: link.autopilot == (77, 1), 10.0)
            # asked of the spoofer: never answered, and the vehicle ignores what targets 77
            assert link.request_streams({M.MAVLINK_MSG_ID_ATTITUDE: 10.0}, timeout_s=0.5) == {
                M.MAVLINK_MSG_ID_ATTITUDE: None
            }
            vehicle = SimVehicle(
                f"udpout:127.0.0.1:{port}", mission, stream_on_request=True
            ).start()
            assert wait_until(lambda: link.other_autopilots() == [(1, 1)], 10.0)
            assert link.autopilot == (77, 1) and link.adoptions == 1  # the adopted one is alive
            assert wait_until(
                lambda: (
                    "two autopilots on the link: 77/1 (adopted) and 1/1; pin one with "
                    "--target-system" in caplog.text
                ),
                10.0,
            )

            spoofer.close()  # the spoofer falls silent; the vehicle keeps beating
            assert wait_until(lambda: link.autopilot == (1, 1), 15.0), link.autopilot
            # the callbacks run on the reader thread right after the switch
            assert wait_until(lambda: len(adopted) == 2, 5.0), adopted
            assert adopted == [((77, 1), None), ((1, 1), (77, 1))]
            assert link.adoptions == 2 and link.target_system == 1
            readoption = [
                r
                for r in caplog.records
                if r.levelno == logging.WARNING and "; adopting autopilot" in r.message
            ]
            assert len(readoption) == 1 and "77/1" in readoption[0].message
            assert "1/1" in readoption[0].message

            # the stream asked of the spoofer is asked of the vehicle now, and arrives
            assert wait_until(lambda: (1, 1) in attitudes, 15.0)
            assert set(attitudes) == {(1, 1)}
            sender = CommandSender(link, retries=2, ack_timeout_s=1.0)
            assert sender.statustext("SWIMMER 54.170412 7.890231 +-4m").accepted
            result = sender.reposition(54.1705, 7.8905, 40.0)
            assert result.accepted, result.error
            assert vehicle.commands[-1].command == M.MAV_CMD_DO_REPOSITION
            assert wait_until(
                lambda: (
                    [s.text for s in vehicle.statustexts] == ["SWIMMER 54.170412 7.890231 +-4m"]
                ),
                5.0,
            )
        finally:
            spoofer.close()
            if vehicle is not None:
                vehicle.stop()


def _drain(sock: socket.socket) -> int:
    """Datagrams waiting at ``sock``."""
    count = 0
    while True:
        try:
            sock.recv(65536)
        except BlockingIOError:
            return count
        count += 1


def test_a_listening_link_answers_the_autopilot_alone(mission):
    # pymavlink's UDP server sends every message to every address that ever sent it a datagram
    port = free_udp_port()
    strangers = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(20)]
    gcs = None
    vehicle = None
    imposter = None
    with MavlinkLink(f"udpin:127.0.0.1:{port}", link_timeout_s=2.0) as link:
        try:
            for stranger in strangers:
                stranger.bind(("127.0.0.1", 0))
                stranger.setblocking(False)
                stranger.sendto(b"\xfd\x09garbage", ("127.0.0.1", port))
            gcs = RawPeer(port, 200, mav_type=M.MAV_TYPE_GCS, autopilot=M.MAV_AUTOPILOT_INVALID)
            assert wait_until(lambda: link.replies.valid_from is not None, 10.0)
            vehicle = SimVehicle(f"udpout:127.0.0.1:{port}", mission).start()
            assert wait_until(lambda: link.autopilot == (1, 1), 10.0)
            # another address sending with the autopilot's ids while the autopilot lives
            imposter = RawPeer(port, 1, 1)
            assert wait_until(lambda: link.replies.contested >= 2, 10.0)
            heard_by_gcs = len(gcs.received)
            heard_by_imposter = len(imposter.received)
            sender = CommandSender(link, retries=2, ack_timeout_s=1.0)
            for k in range(3):  # strangers keep sending while commands go out
                for stranger in strangers:
                    stranger.sendto(os.urandom(40), ("127.0.0.1", port))
                assert sender.reposition(54.1705 + k * 1e-4, 7.8905, 40.0).accepted
            assert sender.statustext("SWIMMER 54.170412 7.890231 +-4m").accepted
            assert wait_until(lambda: len(vehicle.statustexts) == 1, 5.0)
            assert link.replies.target == link.replies.autopilot_at is not None
            gcs_beats = gcs.heartbeats_sent
            assert wait_until(lambda: gcs.heartbeats_sent >= gcs_beats + 3, 5.0)
            assert sum(_drain(stranger) for stranger in strangers) == 0
            assert len(gcs.received) == heard_by_gcs  # a ground station beside it: nothing
            assert len(imposter.received) == heard_by_imposter
            repositions = [c for c in vehicle.commands if c.command == M.MAV_CMD_DO_REPOSITION]
            assert len({c.params[4:6] for c in repositions}) == 3  # a late ACK: sent again
        finally:
            for stranger in strangers:
                stranger.close()
            for peer in (gcs, imposter):
                if peer is not None:
                    peer.close()
            if vehicle is not None:
                vehicle.stop()


def test_pinned_target_system_ignores_a_spoofer_entirely(mission, caplog):
    caplog.set_level(logging.INFO, logger="sarmission.mavlink")
    port = free_udp_port()
    with MavlinkLink(f"udpin:127.0.0.1:{port}", link_timeout_s=2.0, target_system=1) as link:
        adopted: list[tuple] = []
        link.on_adopted(lambda new, old: adopted.append((new, old)))
        got: list[tuple[int, int, str]] = []
        link.subscribe_autopilot(
            lambda m, t: got.append((m.get_srcSystem(), m.get_srcComponent(), m.get_type())),
            TELEMETRY,
        )
        spoofer = RawPeer(port, 77)
        vehicle = None
        try:
            assert wait_until(lambda: link.other_autopilots() == [(77, 1)], 10.0)
            _bogus_position(spoofer)
            assert wait_until(lambda: link.ignored[(77, 1, "GLOBAL_POSITION_INT")] >= 1, 10.0)
            assert link.autopilot is None and not link.wait_autopilot(0.0)
            assert link.target_system == 1
            assert link.diagnosis() == "autopilot 77/1 heard, but the link is pinned to system 1"
            assert "ignoring autopilot 77/1: the link is pinned to system 1" in caplog.text

            vehicle = SimVehicle(f"udpout:127.0.0.1:{port}", mission).start()
            assert wait_until(lambda: link.autopilot == (1, 1), 10.0)
            assert (
                CommandSender(link, retries=2, ack_timeout_s=1.0).set_roi(54.17, 7.89, 0).accepted
            )
            assert vehicle.commands[-1].command == M.MAV_CMD_DO_SET_ROI_LOCATION

            vehicle.stop()  # the vehicle falls silent, the spoofer goes on: still not adopted
            assert wait_until(lambda: not link.link_ok, 10.0)
            beats = spoofer.heartbeats_sent
            assert wait_until(lambda: spoofer.heartbeats_sent >= beats + 15, 10.0)
            _bogus_position(spoofer)
            assert wait_until(lambda: link.ignored[(77, 1, "GLOBAL_POSITION_INT")] >= 2, 10.0)
            assert link.autopilot == (1, 1) and adopted == [((1, 1), None)]
            assert link.adoptions == 1
            assert got and {(s, c) for s, c, _ in got} == {(1, 1)}
        finally:
            spoofer.close()
            if vehicle is not None:
                vehicle.stop()


def test_foreign_telemetry_is_ignored_and_counted(mission, caplog):
    caplog.set_level(logging.INFO, logger="sarmission.mavlink")
    port = free_udp_port()
    got: list[tuple[int, int, str]] = []
    everything: list[tuple[int, int, str]] = []
    with MavlinkLink(f"udpin:127.0.0.1:{port}") as link:
        link.subscribe_autopilot(
            lambda m, t: got.append((m.get_srcSystem(), m.get_srcComponent(), m.get_type())),
            TELEMETRY,
        )
        link.subscribe(
            lambda m, t: everything.append((m.get_srcSystem(), m.get_srcComponent(), m.get_type()))
        )
        # streams by default: positions, attitude, gimbal, home; a gimbal of the vehicle's own
        # system, a ground station, a non-autopilot component of system 1
        vehicle = SimVehicle(f"udpout:127.0.0.1:{port}", mission).start()
        gimbal = RawPeer(
            port,
            1,
            M.MAV_COMP_ID_GIMBAL,
            mav_type=M.MAV_TYPE_GIMBAL,
            autopilot=M.MAV_AUTOPILOT_INVALID,
        )
        hostile = RawPeer(port, 77, mav_type=M.MAV_TYPE_GCS, autopilot=M.MAV_AUTOPILOT_INVALID)
        stranger = RawPeer(port, 1, 99, heartbeat=False)
        try:
            assert link.wait_autopilot(10.0) and link.autopilot == (1, 1)

            def inject() -> bool:
                _bogus_position(hostile)
                _bogus_mount(hostile)
                _bogus_position(stranger)
                _bogus_position(gimbal)  # a gimbal may report its attitude, not a position
                gimbal.send(gimbal.conn.mav.mount_orientation_encode(1000, 0.0, -90.0, 0.0, 0.0))
                return (
                    link.ignored[(77, 1, "GLOBAL_POSITION_INT")] > 0
                    and link.ignored[(77, 1, "MOUNT_ORIENTATION")] > 0
                    and link.ignored[(1, 99, "GLOBAL_POSITION_INT")] > 0
                    and link.ignored[(1, M.MAV_COMP_ID_GIMBAL, "GLOBAL_POSITION_INT")] > 0
                    and (1, M.MAV_COMP_ID_GIMBAL, "MOUNT_ORIENTATION") in got
                    and (1, 1, "HOME_POSITION") in got  # streamed every 2 s
                )

            assert wait_until(inject, 10.0, step=0.2)
            assert link.autopilot == (1, 1) and link.adoptions == 1  # a GCS heartbeat: no rival
            assert (1, 1, "GLOBAL_POSITION_INT") in got and (1, 1, "HOME_POSITION") in got
            assert {(s, c) for s, c, _ in got} == {(1, 1), (1, M.MAV_COMP_ID_GIMBAL)}
            assert (77, 1, "GLOBAL_POSITION_INT") in everything  # subscribe() is unfiltered
            assert "ignoring GLOBAL_POSITION_INT from 77/1: not autopilot 1/1" in caplog.text
            assert not [k for k in dict(link.ignored) if k[:2] == (1, 1)]
        finally:
            for peer in (gimbal, hostile, stranger):
                peer.close()
            vehicle.stop()
