"""After the search pauses (the camera pointed at a target), motion and tracks start afresh:
the detector is reset and the old tracks dropped, so a target seen again must lock again.

Once through a stand-in for the pause, once end to end: the real action policy points the
camera (DO_SET_ROI_LOCATION accepted over UDP), and the autopilot refuses the release
(DO_SET_ROI_NONE denied), which ends the pause as well: where the camera looks is unknown.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from conftest import free_udp_port, wait_until
from link_peers import RawPeer
from pymavlink.dialects.v20 import ardupilotmega as M
from scripted_detector import ScriptedDetector

from sarmission.alerts.store import AlertStore
from sarmission.mavlink.commands import CommandSender, Outbox
from sarmission.mavlink.connection import MavlinkLink
from sarmission.mavlink.telemetry import TelemetryBuffer
from sarmission.mission.actions import ActionPolicy
from sarmission.mission.config import ConfirmConfig, load_mission
from sarmission.mission.controller import MissionController
from sarmission.mission.visits import MoveGate

W, H = 640, 360
FPS = 10.0
BOX = (W / 2 - 5, H / 2 - 5, W / 2 + 5, H / 2 + 5)  # straight below the drone
FRAME = np.full((H, W, 3), 90, np.uint8)


@pytest.fixture
def mission():
    m = load_mission(
        overrides={
            "camera.width": W,
            "camera.height": H,
            "camera.hfov_deg": 40.0,
            "name": "pause_test",
            "actions.policy": ["roi"],
            "actions.roi_hold_s": 5.0,
        }
    )
    m.confirm = ConfirmConfig(min_seen_s=0.0, min_sightings=1, min_score=0.5)
    return m


def hovering(mission, seconds: float) -> TelemetryBuffer:
    """The drone level over home at 60 m, camera at nadir (the default mount)."""
    buf = TelemetryBuffer(stale_after_s=mission.telemetry.stale_after_s)
    lat, lon, alt = mission.area.home
    buf.set_home(lat, lon, alt)
    for t in np.arange(0.0, seconds + 1e-9, 0.05):
        buf.push_position(float(t), lat, lon, 60.0)
        buf.push_attitude(float(t), 0.0, 0.0, 0.0)
    return buf


def target_everywhere(n: int) -> ScriptedDetector:
    return ScriptedDetector([[(BOX, 0.8, 0)]] * n)


class PauseSwitch:
    """Stands in for the action policy: the search is paused while ``paused`` is set."""

    delivered = refused = 0

    def __init__(self) -> None:
        self.paused = False

    def announce(self, alert: Any) -> int:
        return 0

    def pending(self) -> int:
        return 0

    def tick(self) -> bool:
        return False

    def search_paused(self) -> bool:
        return self.paused

    def summary(self) -> str:
        return ""


def test_after_a_pause_the_detector_is_reset_and_the_target_locks_again(tmp_path, mission):
    detector = target_everywhere(40)
    pause = PauseSwitch()
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl = MissionController(
            mission, detector, hovering(mission, 5.0), store, actions=pause, console=lambda s: None
        )
        frame = 0

        def run(n: int) -> None:
            nonlocal frame
            for _ in range(n):
                ctl.process(frame, frame / FPS, FRAME)
                frame += 1

        run(6)
        assert ctl.stats.locks == 1 and detector.resets == []
        pause.paused = True
        run(3)
        assert ctl.stats.paused == 3 and detector.calls == 6
        pause.paused = False
        run(1)
        assert detector.resets == [6]  # before the first searched frame after the pause
        assert ctl.stats.locks == 1  # a new track: not locked on its first frame
        run(5)
        assert ctl.stats.locks == 2 and ctl.stats.merged_tracks == 1  # same target again
        assert detector.resets == [6] and store.count() == 1


class RefusesRelease(RawPeer):
    """An autopilot that accepts DO_SET_ROI_LOCATION and denies DO_SET_ROI_NONE."""

    def _on_command(self, msg: Any) -> None:
        answers = {
            M.MAV_CMD_DO_SET_ROI_LOCATION: M.MAV_RESULT_ACCEPTED,
            M.MAV_CMD_DO_SET_ROI_NONE: M.MAV_RESULT_DENIED,
        }
        if msg.command in answers:
            self.send(
                self.conn.mav.command_ack_encode(
                    msg.command,
                    answers[msg.command],
                    0,
                    0,
                    msg.get_srcSystem(),
                    msg.get_srcComponent(),
                )
            )


def test_a_refused_camera_release_ends_the_pause_and_resets(tmp_path, mission):
    now = [100.0]
    lines: list[str] = []
    port = free_udp_port()
    link = MavlinkLink(f"udpin:127.0.0.1:{port}")
    peer = RefusesRelease(port, system=1)
    outbox = Outbox(CommandSender(link, retries=1, ack_timeout_s=2.0))
    store = AlertStore(tmp_path / "alerts.db")
    try:
        assert link.wait_autopilot(10.0)
        policy = ActionPolicy(
            mission.actions,
            outbox,
            store,
            survey_altitude_m=60.0,
            console=lines.append,
            clock=lambda: now[0],
            move_gate=MoveGate.from_mission(mission),
            gimbal_present=lambda: True,
            takeover=lambda: "",
        )
        detector = target_everywhere(200)
        ctl = MissionController(
            mission,
            detector,
            hovering(mission, 20.0),
            store,
            actions=policy,
            console=lambda s: None,
        )
        frame = 0

        def step() -> None:
            nonlocal frame
            ctl.process(frame, frame / FPS, FRAME)
            frame += 1

        for _ in range(6):
            step()
        assert ctl.stats.locks == 1 and store.count() == 1
        assert wait_until(policy.search_paused, 15.0), lines  # the ROI was delivered
        searched = detector.calls
        for _ in range(3):
            step()
        assert detector.calls == searched and ctl.stats.paused >= 3
        now[0] += mission.actions.roi_hold_s + 0.1
        step()  # ticks the policy: the release is queued
        assert wait_until(lambda: not policy.search_paused(), 15.0), lines
        assert any("camera release" in line and "DENIED" in line for line in lines), lines
        assert detector.resets == []
        step()
        assert detector.resets == [searched]
        for _ in range(5):
            step()
        assert ctl.stats.locks == 2 and ctl.stats.merged_tracks == 1
        assert detector.calls == searched + 6
    finally:
        outbox.close()
        link.close()
        peer.close()
        store.close()
