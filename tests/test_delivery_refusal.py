"""Refused commands carry the autopilot's reason, over real UDP on 127.0.0.1.

ArduPilot Copter 4.7 SITL (observed): a refused arming is answered with MAV_RESULT_FAILED and,
right after the ACK, STATUSTEXTs of severity CRITICAL ("Arm: AHRS: waiting for home"); a
DO_REPOSITION before its EKF has an origin gets MAV_RESULT_FAILED and no text. The simulated
vehicle does the same with ``home_after_s``; a scripted peer checks which texts count.
"""

import threading
import time

from alert_samples import make_alert
from conftest import free_udp_port, wait_until
from pymavlink import mavutil

from sarmission.alerts.model import CHANNEL_MAVLINK, Refusal
from sarmission.alerts.store import AlertStore
from sarmission.mavlink.commands import REASON_WINDOW_S, CommandSender, Outbox
from sarmission.mavlink.connection import M, MavlinkLink
from sarmission.mission.actions import ActionPolicy
from sarmission.mission.config import load_mission
from sarmission.mission.visits import MoveGate
from sim.vehicle import ARM_NO_HOME, SimVehicle

NO_ORIGIN = "MAV_CMD_DO_REPOSITION refused: MAV_RESULT_FAILED (no reason given)"


def test_refusals_from_the_simulated_autopilot_carry_its_reason_to_the_store(tmp_path):
    # the mission area around the sample alerts (near Canberra): the reposition may go there
    mission = load_mission(
        overrides={
            "flight.takeoff": False,
            "area.home_lat": -35.3640,
            "area.home_lon": 149.1652,
            "actions.policy": ["alert", "loiter"],
            "actions.statustext_repeats": 1,
        }
    )
    port = free_udp_port()
    vehicle = SimVehicle(f"udpin:127.0.0.1:{port}", mission, home_after_s=3600.0).start()
    link = MavlinkLink(f"udpout:127.0.0.1:{port}")
    sender = CommandSender(link, retries=1, ack_timeout_s=1.0)
    outbox = Outbox(sender)
    store = AlertStore(tmp_path / "alerts.db")
    lines: list[str] = []
    try:
        assert link.wait_autopilot(5.0)
        arm = sender.command_long(M.MAV_CMD_COMPONENT_ARM_DISARM, 1.0)
        assert (arm.accepted, arm.result, arm.attempts) == (False, M.MAV_RESULT_FAILED, 1)
        assert arm.reason == f"'{ARM_NO_HOME}'"
        assert arm.error == (
            f"MAV_CMD_COMPONENT_ARM_DISARM refused: MAV_RESULT_FAILED (autopilot: '{ARM_NO_HOME}')"
        )

        actions = ActionPolicy(
            mission.actions,
            outbox,
            store,
            survey_altitude_m=50.0,
            console=lines.append,
            move_gate=MoveGate.from_mission(mission),
            takeover=lambda: "",
        )
        alert = make_alert(1)
        store.add(alert)
        actions.announce(alert)
        # the controller ticks the policy every frame: the visit plan sends the reposition
        # the outcome is handled just after the action leaves the outbox: wait for the store
        assert wait_until(
            lambda: (
                actions.tick()
                or (
                    not actions.pending()
                    and not actions.planner.pending
                    and bool(store.get(alert.alert_id).refused)
                )
            ),
            10.0,
        )
        stored = store.get(alert.alert_id)
    finally:
        outbox.close()
        link.close()
        vehicle.stop()
        store.close()
    (refusal,) = stored.refused.values()
    assert stored.refused.keys() == {"mavlink_loiter"} and stored.delivered == {}
    assert (refusal.result, refusal.reason) == (M.MAV_RESULT_FAILED, NO_ORIGIN)
    assert stored.to_json_dict()["refused"]["mavlink_loiter"]["reason"] == NO_ORIGIN
    assert stored.sent[CHANNEL_MAVLINK].count == 1
    assert f"  -> target 1: {NO_ORIGIN}" in lines
    assert actions.refused == 1 and actions.acknowledged == 0
    with AlertStore(tmp_path / "alerts.db") as reopened:  # a refusal is final: not sent again
        assert reopened.undelivered("mavlink_loiter") == []
        assert isinstance(reopened.get(alert.alert_id).refused["mavlink_loiter"], Refusal)
    assert [c.command for c in vehicle.commands] == [
        M.MAV_CMD_COMPONENT_ARM_DISARM,
        M.MAV_CMD_DO_REPOSITION,
    ]


class ScriptedAutopilot:
    """A raw pymavlink autopilot (1/1) that answers every command with ``script``: a list of
    ``("text", severity, bytes)``, ``("other", severity, bytes)`` (a STATUSTEXT from another
    component of the vehicle, 1/154), ``("sleep", seconds)`` and ``("ack", result)`` steps."""

    def __init__(self, port: int) -> None:
        self.conn = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{port}", source_system=1, source_component=1
        )
        self.conn.mav = M.MAVLink(self.conn, srcSystem=1, srcComponent=1)
        self.camera = M.MAVLink(self.conn, srcSystem=1, srcComponent=154)
        self.script: list[tuple] = []
        self.answered = 0  # commands whose script has run to its end
        self.texts = 0  # STATUSTEXTs sent
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        next_hb = 0.0
        while not self._stop.is_set():
            if time.monotonic() >= next_hb:
                next_hb = time.monotonic() + 0.2
                self.conn.mav.heartbeat_send(
                    M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4
                )
            msg = self.conn.recv_match(
                type=["COMMAND_LONG", "COMMAND_INT"], blocking=True, timeout=0.05
            )
            if msg is None:
                continue
            for step in self.script:
                if step[0] == "sleep":
                    time.sleep(step[1])
                elif step[0] == "ack":
                    self.conn.mav.command_ack_send(msg.command, step[1], 0, 0, 1, 191)
                else:
                    mav = self.conn.mav if step[0] == "text" else self.camera
                    mav.send(M.MAVLink_statustext_message(step[1], step[2]))
                    self.texts += 1
            self.answered += 1

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self.conn.close()


def test_reason_is_what_the_autopilot_said_around_the_refusal():
    crit, warn, info = M.MAV_SEVERITY_CRITICAL, M.MAV_SEVERITY_WARNING, M.MAV_SEVERITY_INFO
    port = free_udp_port()
    with MavlinkLink(f"udpin:127.0.0.1:{port}") as link:
        peer = ScriptedAutopilot(port)
        try:
            assert link.wait_autopilot(3.0)
            sender = CommandSender(link, retries=0, ack_timeout_s=2.0)
            heard: list[object] = []
            link.subscribe(lambda msg, arrival: heard.append(msg), ["STATUSTEXT"])

            def refuse(*script: tuple) -> str:
                peer.script = list(script)
                answered = peer.answered
                result = sender.command_long(M.MAV_CMD_DO_SET_MODE, 1.0, 4.0)
                assert result.result == M.MAV_RESULT_FAILED
                # the script played out and its last text arrived: none is left for the next
                assert wait_until(
                    lambda: peer.answered > answered and len(heard) == peer.texts, 5.0
                )
                return result.error

            # texts before and after the ACK count; chatter (INFO) and other components do not
            assert refuse(
                ("text", warn, b"Mode change to GUIDED failed: requires position"),
                ("text", info, b"EKF3 IMU0 origin set"),
                ("other", crit, b"Camera: storage full"),
                ("ack", M.MAV_RESULT_FAILED),
                ("sleep", 0.05),
                ("text", crit, b"Arm: Need Position Estimate"),
            ) == (
                "MAV_CMD_DO_SET_MODE refused: MAV_RESULT_FAILED (autopilot: "
                "'Mode change to GUIDED failed: requires position', "
                "'Arm: Need Position Estimate')"
            )
            # nothing of weight said: no reason; a text long after the ACK is not one either
            assert refuse(
                ("text", info, b"GPS 1: detected u-blox"),
                ("ack", M.MAV_RESULT_FAILED),
                ("sleep", REASON_WINDOW_S + 0.5),
                ("text", crit, b"PreArm: Need Position Estimate"),
            ) == ("MAV_CMD_DO_SET_MODE refused: MAV_RESULT_FAILED (no reason given)")
            # hostile text: printable ASCII only, cut at a NUL, at most three texts quoted
            error = refuse(
                ("ack", M.MAV_RESULT_FAILED),
                ("text", crit, b"Bad\xff\x1b[2Jtext\x00hidden"),
                ("text", crit, b"two"),
                ("text", crit, b"two"),
                ("text", crit, b"three"),
                ("text", crit, b"four"),
            )
            assert error == (
                "MAV_CMD_DO_SET_MODE refused: MAV_RESULT_FAILED (autopilot: "
                "'Bad??[2Jtext', 'two', 'three')"
            ), error
        finally:
            peer.close()
