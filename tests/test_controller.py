"""Mission controller: lock -> geolocation -> durable alert -> autopilot, with a scripted detector
(the telemetry buffer, alert store, geolocation and MAVLink are the real ones)."""

import math
import time

import numpy as np
import pytest
from conftest import free_udp_port, wait_until
from scripted_detector import ScriptedDetector

from sarmission.alerts.store import AlertStore
from sarmission.geo.camera import CameraPose, project_points
from sarmission.geo.wgs84 import ned_to_geodetic
from sarmission.mavlink.commands import CommandSender, Outbox
from sarmission.mavlink.connection import M, MavlinkLink
from sarmission.mavlink.telemetry import TelemetryBuffer
from sarmission.mission.actions import ROI_SETTLE_S, ActionPolicy, ascii_statustext
from sarmission.mission.config import ConfirmConfig, load_mission
from sarmission.mission.controller import MissionController
from sarmission.mission.targets import distance_m
from sarmission.mission.visits import MoveGate
from sim.vehicle import SimVehicle

W, H = 960, 540
DRONE_NED = (30.0, 10.0)
ALT = 70.0
YAW = math.radians(35.0)
TARGET_NED = (38.0, 4.0)
FPS = 10.0


@pytest.fixture
def mission():
    return load_mission(
        overrides={
            "camera.width": W,
            "camera.height": H,
            "camera.hfov_deg": 30.0,
            "name": "ctl_test",
        }
    )


def confirm_at_lock(mission) -> None:
    """Confirm a candidate at its lock (one sighting): for the tests about what follows."""
    mission.confirm = ConfirmConfig(min_seen_s=0.0, min_sightings=1, min_score=0.5)


def filled_buffer(mission, t_end: float, t_start: float = 0.0) -> TelemetryBuffer:
    """Exact telemetry of a drone hovering at DRONE_NED, 70 m, yawed, camera at nadir."""
    buf = TelemetryBuffer(stale_after_s=mission.telemetry.stale_after_s)
    home = mission.area.home
    buf.set_home(*home)
    lat, lon, _ = ned_to_geodetic(DRONE_NED[0], DRONE_NED[1], 0.0, *home)
    for t in np.arange(t_start, t_end + 1e-9, 0.05):
        buf.push_position(float(t), float(lat), float(lon), ALT)
        buf.push_attitude(float(t), 0.0, 0.0, YAW)
    return buf


def target_pixel(mission) -> tuple[float, float]:
    cam = CameraPose.from_attitudes(
        np.array([DRONE_NED[0], DRONE_NED[1], -ALT]),
        (0.0, 0.0, YAW),
        (0.0, -math.pi / 2, 0.0),
        "body",
    )
    uv, _ = project_points(
        mission.camera.intrinsics(), cam, np.array([[TARGET_NED[0], TARGET_NED[1], 0.0]])
    )
    return float(uv[0, 0]), float(uv[0, 1])


def script_3_of_5(mission, n_frames: int):
    """The target at frames 0, 1, 3 (locks at frame 3), then every frame; a false blip once."""
    u, v = target_pixel(mission)
    box = (u - 5, v - 5, u + 5, v + 5)
    hits = {0, 1, 3} | set(range(5, n_frames))
    script = [[(box, 0.8, 0)] if i in hits else [] for i in range(n_frames)]
    script[2] = [((100, 100, 110, 110), 0.9, 1)]  # seen once: never locks
    return script


def truth_latlon(mission) -> tuple[float, float]:
    lat, lon, _ = ned_to_geodetic(TARGET_NED[0], TARGET_NED[1], 0.0, *mission.area.home)
    return float(lat), float(lon)


def run_frames(ctl, n_frames: int, t0: float = 0.0, frames=None, start: int = 0) -> list:
    """Frames ``start .. start + n_frames - 1`` at ``t0 + i / FPS``."""
    alerts = []
    for i in range(start, start + n_frames):
        frame = np.full((H, W, 3), 90, np.uint8) if frames is None else frames[i - start]
        alerts += ctl.process(i, t0 + i / FPS, frame)
    return alerts


def run_script(mission, script: list, store: AlertStore) -> MissionController:
    """A controller on ``script`` (a hovering drone, exact telemetry), run over every frame."""
    ctl = MissionController(
        mission,
        ScriptedDetector(script),
        filled_buffer(mission, len(script) / FPS),
        store,
        console=lambda s: None,
    )
    run_frames(ctl, len(script))
    return ctl


def test_target_seen_3_of_5_frames_is_alerted_once_within_1m(tmp_path, mission):
    mission.confirm = ConfirmConfig(min_seen_s=1.0, min_sightings=6, min_score=0.6)
    n = 20
    store = AlertStore(tmp_path / "alerts.db")
    lines = []
    ctl = MissionController(
        mission,
        ScriptedDetector(script_3_of_5(mission, n)),
        filled_buffer(mission, n / FPS),
        store,
        console=lines.append,
        to_posix=lambda t: 1.7e9 + t,
    )
    alerts = run_frames(ctl, n)
    assert len(alerts) == 1 and store.count() == 1
    alert = store.list()[0]
    assert alert.frame_index == 3  # the third hit in five frames
    assert alert.lock_time == pytest.approx(1.7e9 + 0.3)
    assert alert.class_name == "swimmer"
    assert alert.position is not None
    assert distance_m(alert.position, truth_latlon(mission)) < 1.0
    assert 0 < alert.error_m < 10
    assert alert.drone_position[2] == pytest.approx(ALT)
    assert alert.thumbnail and alert.thumbnail[:2] == b"\xff\xd8"
    assert [p[0] for p in alert.pixel_track] == [0, 1, 2, 3]
    assert len(alert.track) == 4 and distance_m(alert.track[-1][1:], alert.position) < 1.0
    # a candidate at the lock, the alert once a second of sightings confirmed it in the world
    assert len(lines) == 2 and lines[0].startswith("CANDIDATE target 1: swimmer")
    assert lines[1].startswith(f"ALERT target 1 ({alert.short_id}): swimmer")
    assert "1.0 s, 10 sightings" in lines[1] and alert.tier == "confirmed"
    assert ctl.stats.confirmed[0][1] == 13  # frame 3 + 1 s at 10 frames/s
    assert ctl.stats.frames == n and ctl.stats.locks == 1
    store.close()


def test_restart_on_the_same_store_does_not_re_announce(tmp_path, mission):
    confirm_at_lock(mission)
    n = 12
    path = tmp_path / "alerts.db"
    with AlertStore(path) as store:
        ctl = MissionController(
            mission,
            ScriptedDetector(script_3_of_5(mission, n)),
            filled_buffer(mission, n / FPS),
            store,
            console=lambda s: None,
        )
        assert len(run_frames(ctl, n)) == 1
    with AlertStore(path) as store:
        ctl = MissionController(
            mission,
            ScriptedDetector(script_3_of_5(mission, n)),
            filled_buffer(mission, n / FPS),
            store,
            console=lambda s: None,
        )
        assert ctl.known_at_start == 1
        assert run_frames(ctl, n) == []
        assert store.count() == 1 and ctl.stats.merged_tracks == 1


def test_a_restart_goes_on_following_an_earlier_run_s_alert(tmp_path, mission):
    """An alert stored by an earlier run 3 m off its target (an older fix) is moved back onto
    it once the restarted controller sees the target again; a dismissed one stays put."""
    confirm_at_lock(mission)
    n = 12
    path = tmp_path / "alerts.db"
    lines: list[str] = []

    def controller(store: AlertStore) -> MissionController:
        return MissionController(
            mission,
            ScriptedDetector(script_3_of_5(mission, n)),
            filled_buffer(mission, n / FPS),
            store,
            console=lines.append,
        )

    truth = truth_latlon(mission)
    older = ned_to_geodetic(TARGET_NED[0] + 3.0, TARGET_NED[1], 0.0, *mission.area.home)[:2]
    for dismissed in (False, True):
        path.unlink(missing_ok=True)
        with AlertStore(path) as store:
            assert len(run_frames(controller(store), n)) == 1
            (alert,) = store.list()
            store.refine_position(alert.alert_id, older, 4.0, "ground plane", "older", 1.0)
            if dismissed:
                store.decide(alert.alert_id, "dismissed", "sam")
        lines.clear()
        with AlertStore(path) as store:
            assert run_frames(controller(store), n) == []
            (after,) = store.list()
        if dismissed:
            assert after.position == pytest.approx(older)
            assert not any(line.startswith("REFINED") for line in lines)
        else:
            assert distance_m(after.position, truth) < 1.0
            assert any(line.startswith(f"REFINED target {alert.target_id}") for line in lines)


@pytest.mark.parametrize(("other_person", "candidates"), [(False, 1), (True, 2)])
def test_a_track_re_born_far_off_in_the_image_joins_only_once_alone(
    tmp_path, mission, other_person, candidates
):
    """From frame 10 a box 40 px (1.6 m) right of the first: the person swept across the
    image (the first box is gone) or a second person beside the first (the first box stays,
    missing frame 12 only, when the new track locks). The new track is pending until the
    registry can tell: one candidate, or two."""
    u, v = target_pixel(mission)
    first, beside = (u - 5, v - 5, u + 5, v + 5), (u + 35, v - 5, u + 45, v + 5)
    n = 20
    script = []
    for i in range(n):
        boxes = [(first, 0.8, 0)] if i < 10 or (other_person and i != 12) else []
        script.append(boxes + ([(beside, 0.8, 0)] if i >= 10 else []))
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl = run_script(mission, script, store)
        assert store.count() == candidates
        assert ctl.stats.locks == 2 and ctl.stats.merged_tracks == 2 - candidates


def test_stale_telemetry_gives_an_alert_without_position_and_the_reason(tmp_path, mission):
    n = 8
    buf = filled_buffer(mission, 1.0)  # telemetry ends at t = 1 s; frames from t = 5 s
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl = MissionController(
            mission, ScriptedDetector(script_3_of_5(mission, n)), buf, store, console=lambda s: None
        )
        # a candidate for the operator; never confirmed: there is nothing to check it against
        assert run_frames(ctl, n, t0=5.0) == []
        (alert,) = ctl.stats.candidates
        assert store.list() == [alert] and alert.tier == "candidate"
        assert alert.position is None and alert.error_m is None
        assert alert.position_note.startswith("no position for")
        assert alert.drone_position is None
        assert "pos unknown" in alert.statustext()


class AnnouncedActions:
    """Stands in for the action policy: remembers what it was asked to announce."""

    delivered = refused = 0

    def __init__(self) -> None:
        self.announced: list = []
        self.refined: list = []

    def announce(self, alert) -> int:
        self.announced.append((alert.alert_id, alert.position))
        return 1

    def refine(self, alert) -> bool:
        self.refined.append((alert.alert_id, alert.position))
        return False

    def pending(self) -> int:
        return 0

    def tick(self) -> bool:
        return False

    def search_paused(self) -> bool:
        return False

    def summary(self) -> str:
        return f"announced: {len(self.announced)}"


@pytest.mark.parametrize("reborn", [False, True], ids=["same track", "track re-born"])
def test_position_found_after_a_blind_alert_goes_to_that_alert(tmp_path, mission, reborn):
    """Telemetry starts at t = 2 s; the target locks at frame 2 (t = 0.2 s) without a position.
    Either its track goes on, or it is lost for 2 s and a new track locks on it (frame 25) with
    telemetry: one candidate either way, which gets the position, and is confirmed (announced
    once, with its position) after a second of placed sightings."""
    mission.confirm = ConfirmConfig(
        min_seen_s=1.0, min_sightings=6, min_score=0.6, min_seen_share=0.0
    )
    n = 41
    u, v = target_pixel(mission)
    box = (u - 5, v - 5, u + 5, v + 5)
    seen = set(range(n)) - (set(range(5, 23)) if reborn else set())
    script = [[(box, 0.8, 0)] if i in seen else [] for i in range(n)]
    lines: list[str] = []
    actions = AnnouncedActions()
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl = MissionController(
            mission,
            ScriptedDetector(script),
            filled_buffer(mission, 4.0, t_start=2.0),
            store,
            actions=actions,
            console=lines.append,
        )
        alerts = run_frames(ctl, n)
        assert len(alerts) == 1 and store.count() == 1
        stored = store.get(alerts[0].alert_id)
        # placed once its telemetry came; at the confirmation given the fit of the fixes that
        # confirmed it, with the drift they show
        assert [e.kind for e in store.events()] == ["new", "position", "position", "confirmed"]
        assert stored.drift_ne is not None
    assert alerts[0].frame_index == 2
    assert distance_m(stored.position, truth_latlon(mission)) < 1.0
    assert 0 < stored.error_m < 10 and "stale" not in stored.position_note
    assert alerts[0].position == stored.position  # the run's own record follows
    assert ctl.stats.located_later == 1 and ctl.stats.merged_tracks == int(reborn)
    assert [p for _, p in actions.announced] == [stored.position]
    assert [line.split(":")[0] for line in lines] == [
        "CANDIDATE target 1",
        "POSITION target 1",
        f"ALERT target 1 ({stored.short_id})",
    ]
    assert "positions found after the alert: 1" in ctl.summary()


def test_taller_frames_than_the_camera_are_placed_as_a_crop_of_its_view(tmp_path, mission, caplog):
    """Frames of 4:3 from a camera configured 16:9 (the same width and horizontal view, 90 more
    rows above and below): the target, 90 rows lower in the frame, is placed where it is, and
    the shape mismatch is said once."""
    confirm_at_lock(mission)
    n = 8
    u, v = target_pixel(mission)
    box = (u - 5, v + 85, u + 5, v + 95)
    script = [[(box, 0.8, 0)] for _ in range(n)]
    tall = [np.full((H + 180, W, 3), 90, np.uint8) for _ in range(n)]
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl = MissionController(
            mission, ScriptedDetector(script), filled_buffer(mission, n / FPS), store,
            console=lambda s: None,
        )  # fmt: skip
        with caplog.at_level("WARNING"):
            alerts = run_frames(ctl, n, frames=tall)
        stored = store.get(alerts[0].alert_id)
    # exact telemetry: the crop puts it within centimetres; stretched rows put it 0.78 m off
    assert distance_m(stored.position, truth_latlon(mission)) < 0.1
    warnings = [r.getMessage() for r in caplog.records if "not the shape" in r.getMessage()]
    assert len(warnings) == 1 and "960x720" in warnings[0] and "960x540" in warnings[0]


def test_corrupt_frames_are_skipped_and_counted(tmp_path, mission):
    confirm_at_lock(mission)
    good = np.full((H, W, 3), 90, np.uint8)
    frames = [
        good,
        good,
        None,
        good,
        np.zeros((H, W), np.uint8),
        good,
        good.astype(np.float32),
        np.zeros((H // 2, W // 2, 3), np.uint8),
        "garbage",
        good,
    ]
    detector = ScriptedDetector(script_3_of_5(mission, len(frames)))
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl = MissionController(
            mission, detector, filled_buffer(mission, 2.0), store, console=lambda s: None
        )
        alerts = run_frames(ctl, len(frames), frames=frames)
        assert ctl.stats.skipped_total == 5 and ctl.stats.frames == 5
        assert detector.calls == 5  # the detector never saw a bad frame
        assert set(ctl.stats.skipped) == {
            "no image",
            "not a BGR uint8 image",
            "size 480x270 differs from the stream's 960x540",
            "not an image",
        }
        assert len(alerts) == 1  # frames 0, 1, 3 of the good ones lock the target
        assert "skipped: 5" in ctl.summary()


def test_alert_reaches_the_autopilot_sent_repeatedly_and_loiter_acknowledged(tmp_path, mission):
    """The STATUSTEXT (no acknowledgement exists) is recorded as sent n times, never as
    delivered; the DO_REPOSITION as acknowledged, without waiting for the text's repeats."""
    confirm_at_lock(mission)
    n = 10
    mission.actions.policy = ["alert", "loiter"]
    mission.actions.statustext_repeats = 3
    mission.actions.statustext_repeat_interval_s = 1.0
    port = free_udp_port()
    vehicle = SimVehicle(f"udpin:127.0.0.1:{port}", mission).start()
    link = MavlinkLink(f"udpout:127.0.0.1:{port}")
    outbox = Outbox(CommandSender(link, retries=2, ack_timeout_s=0.5))
    store = AlertStore(tmp_path / "alerts.db")
    lines: list[str] = []
    try:
        assert link.wait_autopilot(5.0)
        actions = ActionPolicy(
            mission.actions,
            outbox,
            store,
            survey_altitude_m=50.0,
            console=lines.append,
            move_gate=MoveGate.from_mission(mission),
            takeover=lambda: "",
        )
        ctl = MissionController(
            mission,
            ScriptedDetector(script_3_of_5(mission, n)),
            filled_buffer(mission, n / FPS),
            store,
            actions=actions,
            console=lambda s: None,
        )
        (alert,) = run_frames(ctl, n)
        assert wait_until(
            lambda: not actions.pending() and store.get(alert.alert_id).delivered, 10.0
        )
        stored = store.get(alert.alert_id)
        assert stored.delivered.keys() == {"mavlink_loiter"}
        assert stored.sent.keys() == {"mavlink"} and stored.sent["mavlink"].count == 3
        assert wait_until(lambda: len(vehicle.statustexts) == 3, 5.0)
        assert [s.text for s in vehicle.statustexts] == [ascii_statustext(alert)] * 3
        assert vehicle.statustexts[0].text.startswith(f"{alert.short_id} SAR ")
        assert vehicle.statustexts[0].text.endswith("+-2m")
        assert vehicle.statustexts[0].severity == M.MAV_SEVERITY_ALERT
        (cmd,) = [c for c in vehicle.commands if c.command == M.MAV_CMD_DO_REPOSITION]
        assert cmd.is_int and cmd.result == M.MAV_RESULT_ACCEPTED
        lat, lon = cmd.params[4] / 1e7, cmd.params[5] / 1e7
        assert distance_m((lat, lon), alert.position) < 0.1
        assert cmd.params[6] == pytest.approx(50.0)
        assert actions.acknowledged == 1 and actions.sent == 1
        assert store.undelivered("mavlink", repeats=3) == []
        assert [a.alert_id for a in store.undelivered("mavlink", repeats=4)] == [alert.alert_id]
        sent_line = (
            f"  -> target 1 ({alert.short_id}): STATUSTEXT sent 3x (no "
            "acknowledgement exists for STATUSTEXT)"
        )
        ack_line = "  -> target 1: MAV_CMD_DO_REPOSITION acknowledged (1 attempt)"
        assert lines.index(ack_line) < lines.index(sent_line)  # repeats did not hold it up
        assert not any("delivered" in line for line in lines)
    finally:
        outbox.close()
        link.close()
        vehicle.stop()
        store.close()


def nadir_angle_deg(vehicle: SimVehicle) -> float:
    """Angle between the simulated camera's optical axis and straight down."""
    axis = vehicle.camera_pose().optical_axis_ned
    return math.degrees(math.acos(float(np.clip(axis[2] / np.linalg.norm(axis), -1.0, 1.0))))


def test_roi_is_held_then_released_and_the_search_pauses_meanwhile(tmp_path, mission):
    """ROI on the alert, DO_SET_ROI_NONE once ``roi_hold_s`` has passed on the policy's clock
    (not before), the simulated gimbal back at nadir; no frame is searched from the ROI's
    delivery until ROI_SETTLE_S after the release."""
    confirm_at_lock(mission)
    n = 10
    mission.actions.policy = ["roi"]
    mission.actions.roi_hold_s = 10.0
    now = [100.0]
    lines: list[str] = []
    port = free_udp_port()
    vehicle = SimVehicle(f"udpin:127.0.0.1:{port}", mission).start()
    link = MavlinkLink(f"udpout:127.0.0.1:{port}")
    outbox = Outbox(CommandSender(link, retries=2, ack_timeout_s=0.5))
    store = AlertStore(tmp_path / "alerts.db")

    def released() -> list:
        return [c for c in vehicle.commands if c.command == M.MAV_CMD_DO_SET_ROI_NONE]

    def wait_for(condition) -> None:
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and not condition():
            time.sleep(0.05)

    try:
        assert link.wait_autopilot(5.0)
        actions = ActionPolicy(
            mission.actions,
            outbox,
            store,
            survey_altitude_m=50.0,
            console=lines.append,
            clock=lambda: now[0],
            move_gate=MoveGate.from_mission(mission),
            gimbal_present=lambda: True,
            takeover=lambda: "",
        )
        detector = ScriptedDetector(script_3_of_5(mission, n))
        ctl = MissionController(
            mission,
            detector,
            filled_buffer(mission, 4.0),
            store,
            actions=actions,
            console=lambda s: None,
        )
        assert not actions.search_paused()
        (alert,) = run_frames(ctl, n)
        wait_for(lambda: store.get(alert.alert_id).delivered)
        assert set(store.get(alert.alert_id).delivered) == {"mavlink_roi"}
        # the gimbal slews (about 1 s) until it points at the target, off nadir
        assert wait_until(lambda: nadir_angle_deg(vehicle) > 5.0, 15.0)
        assert actions.search_paused()
        # The ROI may already have arrived during the first frames (loopback UDP is fast).
        calls, paused = detector.calls, ctl.stats.paused
        assert run_frames(ctl, 5, start=n) == [] and ctl.stats.paused == paused + 5
        assert detector.calls == calls  # paused frames are not searched

        now[0] += 9.9
        assert not actions.tick()
        time.sleep(0.3)
        assert released() == []
        now[0] += 0.2
        assert actions.tick()
        assert not actions.tick()  # released once
        wait_for(released)
        (cmd,) = released()
        assert cmd.result == M.MAV_RESULT_ACCEPTED and not cmd.is_int
        wait_for(lambda: "  -> camera back to the survey view (DO_SET_ROI_NONE)" in lines)
        assert wait_until(lambda: nadir_angle_deg(vehicle) < 1.0, 15.0)  # back at nadir
        assert actions.search_paused()  # the gimbal settles
        now[0] += ROI_SETTLE_S + 0.1
        assert not actions.search_paused()
        run_frames(ctl, 2, start=n + 5)
        assert detector.calls == calls + 2 and ctl.stats.paused == paused + 5
        assert (
            f"frames not searched while the camera was on a target: {paused + 5}" in ctl.summary()
        )
        assert actions.acknowledged == 1  # the release is no alert delivery
    finally:
        outbox.close()
        link.close()
        vehicle.stop()
        store.close()


def test_a_glint_that_joined_a_person_first_yields_them_to_their_own_track(tmp_path, mission):
    """A person alerted, then out of sight for 4 s; a glint 7 m off (179 px) locks first and
    joins them by the re-find radius, the person's own track locks a frame later 1 m from
    where they were. The person's track takes their target over and the glint becomes a
    candidate of its own, at its own place: not a second alert on the person."""
    confirm_at_lock(mission)
    u, v = target_pixel(mission)
    person, moved, glint = (
        (u - 5, v - 5, u + 5, v + 5),
        (u + 21, v - 5, u + 31, v + 5),
        (u + 174, v - 5, u + 184, v + 5),
    )
    n = 70
    script = []
    for i in range(n):
        boxes = [(person, 0.9, 0)] if i < 10 else []
        boxes += [(glint, 0.8, 0)] if i >= 50 else []
        boxes += [(moved, 0.9, 0)] if i >= 51 else []
        script.append(boxes)
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl = run_script(mission, script, store)
        alerts = sorted(store.list(), key=lambda a: a.target_id)
        assert len(alerts) == 2
        first, second = alerts
        assert distance_m(first.position, truth_latlon(mission)) < 1.5
        assert distance_m(second.position, first.position) > 5.0  # the glint, not the person
        # the glint's sightings left the person's evidence with it
        evidence = ctl.candidates.evidence[first.target_id].sightings
        assert len(evidence) > 10
        assert all(distance_m((s.lat, s.lon), truth_latlon(mission)) < 2.5 for s in evidence)


def test_a_new_frame_size_is_adopted_and_the_search_goes_on(tmp_path, mission, caplog):
    """A sender restarted at another resolution once left the mission blind for the rest of
    the run, with a warning per frame. The new size is adopted after a few frames in a row:
    the lens re-derived, the detector reset and the old tracks dropped, said once."""
    small = np.full((H // 2, W // 2, 3), 90, np.uint8)
    frames = [np.full((H, W, 3), 90, np.uint8)] * 5 + [small] * 10
    u, v = target_pixel(mission)
    detector = ScriptedDetector([[((u - 5, v - 5, u + 5, v + 5), 0.8, 0)]] * 15)
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl = MissionController(
            mission, detector, filled_buffer(mission, 2.0), store, console=lambda s: None
        )
        with caplog.at_level("WARNING"):
            run_frames(ctl, 5, frames=frames)
            assert ctl.tracker._tracks
            run_frames(ctl, 10, frames=frames[5:], start=5)
    assert ctl.stats.frames == 13 and ctl.stats.skipped_total == 2
    assert detector.resets == [5]
    assert ctl._intrinsics.width == W // 2
    # born at frame 7 or later: none of the old size
    assert ctl.tracker._tracks and all(t.age <= 8 for t in ctl.tracker._tracks)
    changed = [r for r in caplog.records if "frame size changed" in r.getMessage()]
    assert len(changed) == 1 and "960x540 to 480x270" in changed[0].getMessage()


def test_skipped_frames_are_all_counted_but_warned_about_at_most_every_few_seconds(
    tmp_path, mission, caplog
):
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl = MissionController(
            mission, ScriptedDetector([]), filled_buffer(mission, 2.0), store,
            console=lambda s: None,
        )  # fmt: skip
        with caplog.at_level("WARNING"):
            run_frames(ctl, 10, frames=[None] * 10)
    assert ctl.stats.skipped == {"no image": 10}
    assert len([r for r in caplog.records if "skipped" in r.getMessage()]) == 1
