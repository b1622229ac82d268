"""Typed outbox commands: each kind reaches the vehicle over real UDP as the MAVLink command it
names, and outcomes go to the callbacks given through the outbox's explicit API."""

from __future__ import annotations

import pytest
from conftest import free_udp_port, wait_until
from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.mavlink.commands import CommandSender, Outbox
from sarmission.mavlink.connection import MavlinkLink
from sarmission.mavlink.outbox_commands import (
    ClearRoi,
    CommandInt,
    CommandLong,
    Reposition,
    SetRoi,
    StatusText,
)
from sarmission.mission.config import load_mission
from sim.vehicle import SimVehicle


@pytest.fixture
def outbox():
    port = free_udp_port()
    vehicle = SimVehicle(
        f"udpin:127.0.0.1:{port}", load_mission(overrides={"flight.takeoff": False})
    ).start()
    link = MavlinkLink(f"udpout:127.0.0.1:{port}", link_timeout_s=2.0)
    assert link.wait_autopilot(5.0), "no autopilot HEARTBEAT"
    box = Outbox(CommandSender(link, retries=2, ack_timeout_s=1.0), statustext_repeats=1)
    yield vehicle, box
    box.close()
    link.close()
    vehicle.stop()


def test_each_command_kind_arrives_as_its_mavlink_command(outbox) -> None:
    vehicle, box = outbox
    delivered, sent = [], []
    box.set_callbacks(
        on_delivered=lambda action, result: delivered.append(action.key),
        on_sent=lambda action, result: sent.append(action.key),
    )
    commands = [
        ("roi", SetRoi(54.1705, 7.8905, 0.0), M.MAV_CMD_DO_SET_ROI_LOCATION, True),
        ("release", ClearRoi(), M.MAV_CMD_DO_SET_ROI_NONE, False),
        ("move", Reposition(54.1706, 7.8906, 40.0), M.MAV_CMD_DO_REPOSITION, True),
        (
            "int",
            CommandInt(
                M.MAV_CMD_DO_SET_ROI_LOCATION,
                M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                x=541_707_000,
                y=78_907_000,
            ),
            M.MAV_CMD_DO_SET_ROI_LOCATION,
            True,
        ),
        ("long", CommandLong(M.MAV_CMD_DO_SET_ROI_NONE, (0.0,)), M.MAV_CMD_DO_SET_ROI_NONE, False),
    ]
    for key, command, _, _ in commands:
        box.submit(command, key=key)
    box.submit(StatusText("T1-a SAR test"), key="text")
    assert wait_until(lambda: len(delivered) == len(commands) and sent == ["text"], 15.0), (
        delivered,
        sent,
    )
    assert delivered == [key for key, *_ in commands]  # in the order submitted
    received = [(c.command, c.is_int) for c in vehicle.commands]
    assert received == [(mav_cmd, is_int) for _, _, mav_cmd, is_int in commands]
    roi, _, move, by_int, _ = vehicle.commands
    assert (roi.params[4], roi.params[5]) == (541_705_000, 78_905_000)
    assert (move.params[4], move.params[5], move.params[6]) == (541_706_000, 78_906_000, 40.0)
    assert (by_int.params[4], by_int.params[5]) == (541_707_000, 78_907_000)
    assert wait_until(lambda: any(t.text == "T1-a SAR test" for t in vehicle.statustexts), 5.0)


def test_something_else_than_a_command_is_refused_at_once(outbox) -> None:
    _, box = outbox
    with pytest.raises(TypeError, match="not an outbox command"):
        box.submit("set_roi", key="x")  # type: ignore[arg-type]
    assert box.pending() == []


def test_callbacks_given_later_replace_those_of_the_constructor(outbox) -> None:
    _, box = outbox
    first, second = [], []
    box.set_callbacks(on_delivered=lambda action, result: first.append(action.key))
    box.set_callbacks(on_delivered=lambda action, result: second.append(action.key))
    box.submit(ClearRoi(), key="release")
    assert wait_until(lambda: second == ["release"], 10.0)
    assert first == []
