"""The pilot's mission read back over UDP from the simulated vehicle, and visits inserted into
it without losing an item or breaking its loops."""

import threading

import pytest
from conftest import free_udp_port
from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.mavlink.connection import MavlinkLink, mavlink2_connection
from sarmission.mavlink.mission_transfer import (
    MissionTransferError,
    WireItem,
    download_mission,
    insert_visits,
    loiter_item,
)
from sarmission.mission.config import load_mission
from sim.vehicle import SimVehicle

REL = M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT


def survey() -> list[WireItem]:
    """Home, a speed change, a 4-corner box and a DO_JUMP back to the first corner forever."""
    items = [WireItem(M.MAV_FRAME_GLOBAL, M.MAV_CMD_NAV_WAYPOINT, x=430000000, y=100000000)]
    items.append(WireItem(2, M.MAV_CMD_DO_CHANGE_SPEED, (1.0, 5.0, -1.0, 0.0)))
    for k, (n, e) in enumerate(((300, 0), (300, 300), (0, 300), (0, 0))):
        items.append(
            WireItem(
                REL, M.MAV_CMD_NAV_WAYPOINT, x=430000000 + 27 * n + k, y=100000000 + 37 * e, z=60.0
            )
        )
    items.append(WireItem(2, M.MAV_CMD_DO_JUMP, (2.0, -1.0, 0.0, 0.0)))
    return items


def test_visits_go_before_the_current_item_and_loops_still_close():
    items = survey()
    visits = [loiter_item(43.001, 10.002, 40.0, 30.0), loiter_item(43.002, 10.001, 40.0, 30.0)]
    merged = insert_visits(items, 4, visits)
    assert len(merged) == len(items) + 2
    assert merged[4:6] == visits
    assert merged[:4] == items[:4] and merged[6:-1] == items[4:-1]
    jump = merged[-1]
    assert jump.command == M.MAV_CMD_DO_JUMP and jump.params[0] == 2.0  # before the insertion
    late = insert_visits(items, 2, visits)
    assert late[-1].params[0] == 4.0  # its target moved with the items
    with pytest.raises(ValueError):
        insert_visits(items, 0, visits)


def test_download_reads_the_mission_the_pilot_uploaded():
    mission = load_mission(overrides={"flight.takeoff": False})
    port = free_udp_port()
    with SimVehicle(f"udpin:127.0.0.1:{port}", mission).start() as vehicle:
        with MavlinkLink(f"udpout:127.0.0.1:{port}") as link:
            assert link.wait_autopilot(5.0)
            pilot = survey()
            vehicle.missions[M.MAV_MISSION_TYPE_MISSION] = [
                vehicle_item(seq, it) for seq, it in enumerate(pilot)
            ]
            assert download_mission(link) == pilot


def test_download_from_an_autopilot_that_never_answers_says_so():
    port = free_udp_port()
    with MavlinkLink(f"udpin:127.0.0.1:{port}") as link:
        peer = mavlink2_connection(f"udpout:127.0.0.1:{port}", 1, 1)
        stop = threading.Event()

        def heartbeats() -> None:  # an autopilot that is alive but ignores mission requests
            while not stop.wait(0.2):
                peer.mav.heartbeat_send(
                    M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, M.MAV_STATE_ACTIVE
                )

        thread = threading.Thread(target=heartbeats, daemon=True)
        thread.start()
        try:
            assert link.wait_autopilot(5.0)
            with pytest.raises(MissionTransferError, match="no answer for the mission's item"):
                download_mission(link, timeout_s=0.2, retries=1)
        finally:
            stop.set()
            thread.join()
            peer.close()


def vehicle_item(seq: int, it: WireItem):
    from sim.vehicle import MissionItem

    return MissionItem(
        seq=seq,
        frame=it.frame,
        command=it.command,
        current=0,
        autocontinue=it.autocontinue,
        param1=it.params[0],
        param2=it.params[1],
        param3=it.params[2],
        param4=it.params[3],
        x=it.x,
        y=it.y,
        z=it.z,
    )
