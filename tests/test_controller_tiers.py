"""Candidates and confirmed alerts through the controller: a person still in the world frame is
confirmed after a second of sightings; sun glint that keeps its place in the image while the
aircraft flies on, and a boat, are discarded and never told to the autopilot; an operator's
confirmation announces at once, a dismissal silences the place, also after a restart."""

import math

import cv2
import numpy as np
import pymap3d
import pytest
from scripted_detector import ScriptedDetector

from sarmission.alerts.store import AlertStore
from sarmission.mavlink.telemetry import TelemetryBuffer
from sarmission.mission.config import ConfirmConfig, load_mission
from sarmission.mission.controller import MissionController

W, H, HFOV_DEG, FPS = 960, 540, 30.0, 10.0
DRONE = (43.0, 10.0)
F = (W / 2) / math.tan(math.radians(HFOV_DEG) / 2)


@pytest.fixture
def mission():
    mission = load_mission(
        overrides={
            "camera.width": W,
            "camera.height": H,
            "camera.hfov_deg": HFOV_DEG,
            "name": "tiers",
        }
    )
    # the rule's shape, not its tuned defaults: a second of at least six sightings
    mission.confirm = ConfirmConfig(
        min_seen_s=1.0, min_sightings=6, min_seen_share=0.4, min_score=0.6
    )
    return mission


class Announced:
    """Stands in for the action policy: what it was asked to announce."""

    def __init__(self) -> None:
        self.alerts: list = []

    def announce(self, alert) -> int:
        self.alerts.append(alert)
        return 1

    def tick(self) -> bool:
        return False

    def search_paused(self) -> bool:
        return False

    def pending(self) -> int:
        return 0

    def summary(self) -> str:
        return ""


def flight(seconds: float, speed_north: float = 0.0, height: float = 60.0) -> TelemetryBuffer:
    """Level flight northwards at ``speed_north`` m/s, camera at nadir, yaw 0."""
    buf = TelemetryBuffer()
    buf.set_home(*DRONE, 2.0)
    for t in np.arange(0.0, seconds + 1e-9, 0.05):
        lat, lon, _ = pymap3d.ned2geodetic(speed_north * t, 0.0, 0.0, *DRONE, 0.0)
        buf.push_position(
            float(t), float(lat), float(lon), height, velocity_ned=(speed_north, 0.0, 0.0)
        )
        buf.push_attitude(float(t), 0.0, 0.0, 0.0)
    return buf


def controller(mission, detector, telemetry, store, actions=None, **options) -> MissionController:
    """The controller under test, its console silent (``actions``: an :class:`Announced`)."""
    return MissionController(
        mission,
        detector,
        telemetry,
        store,
        actions=Announced() if actions is None else actions,
        console=lambda s: None,
        **options,
    )


def box_at(north: float, east: float, height: float, side_px: float = 8.0):
    """The box of a point ``north``/``east`` metres from the point below the camera."""
    u = (W - 1) / 2 + F * east / height
    v = (H - 1) / 2 - F * north / height
    return (u - side_px / 2, v - side_px / 2, u + side_px / 2, v + side_px / 2)


def run(ctl, n: int, start: int = 0) -> list:
    alerts = []
    for i in range(start, start + n):
        alerts += ctl.process(i, i / FPS, np.full((H, W, 3), 90, np.uint8))
    return alerts


def test_a_still_person_is_a_candidate_then_confirmed_after_a_second(tmp_path, mission):
    script = [[(box_at(10.0, -5.0, 60.0), 0.9, 0)]] * 20
    actions = Announced()
    with AlertStore(tmp_path / "a.db") as store:
        ctl = controller(mission, ScriptedDetector(script), flight(3.0), store, actions=actions)
        alerts = run(ctl, 20)
        (alert,) = alerts
        assert store.get(alert.alert_id).tier == "confirmed"
        assert actions.alerts == alerts
        (_, frame_index, _) = ctl.stats.confirmed[0]
        assert frame_index == 12  # locked at frame 2, 1.0 s of sightings later
        assert "drift 0.0 m/s" in store.get(alert.alert_id).evidence


def test_confirmation_and_discard_times_are_on_the_controllers_clock(tmp_path, mission):
    """A replay maps footage time to POSIX seconds: the confirmation is stamped with its
    frame's time on that clock, like the lock, not with the wall clock of the replay."""
    epoch = 1.6e9  # a flight long ago
    person = (box_at(10.0, -5.0, 60.0), 0.9, 0)
    boat = (box_at(-5.0, 5.0, 60.0, side_px=130.0), 0.9, 0)
    script = [[person, boat]] * 20
    with AlertStore(tmp_path / "a.db") as store:
        ctl = controller(
            mission, ScriptedDetector(script), flight(3.0), store, to_posix=lambda t: epoch + t
        )
        run(ctl, 20)
        (confirmed,) = [store.get(a.alert_id) for a, _, _ in ctl.stats.confirmed]
        assert confirmed.lock_time == pytest.approx(epoch + 0.2)
        assert confirmed.confirmed_at == pytest.approx(epoch + 1.2)  # frame 12
        others = [a.alert_id for a in ctl.stats.candidates if a.alert_id != confirmed.alert_id]
        (discarded,) = [store.get(i) for i in others]
        assert discarded.discarded and epoch <= discarded.discarded_at <= epoch + 2.0


def test_glint_that_keeps_its_place_in_the_image_is_discarded(tmp_path, mission):
    script = [[(box_at(0.0, 8.0, 60.0), 0.95, 0)]] * 30  # fixed pixel, aircraft at 10 m/s
    actions = Announced()
    with AlertStore(tmp_path / "a.db") as store:
        ctl = controller(
            mission, ScriptedDetector(script), flight(4.0, 10.0), store, actions=actions
        )
        assert run(ctl, 30) == [] and actions.alerts == []
        (candidate,) = ctl.stats.candidates
        stored = store.get(candidate.alert_id)
        assert stored.tier == "candidate" and "moves 10" in stored.discarded
        assert "1 (moves)" in ctl.summary()


def test_a_boat_is_too_large_to_be_a_person(tmp_path, mission):
    script = [[(box_at(5.0, 5.0, 60.0, side_px=130.0), 0.9, 0)]] * 20  # 6 m across
    with AlertStore(tmp_path / "a.db") as store:
        ctl = controller(mission, ScriptedDetector(script), flight(3.0), store)
        assert run(ctl, 20) == []
        (candidate,) = ctl.stats.candidates
        assert "m across is no person" in store.get(candidate.alert_id).discarded


def test_the_operator_confirms_a_candidate_before_the_evidence_does(tmp_path, mission):
    script = [[(box_at(10.0, -5.0, 60.0), 0.9, 0)]] * 6
    actions = Announced()
    with AlertStore(tmp_path / "a.db") as store:
        ctl = controller(mission, ScriptedDetector(script), flight(3.0), store, actions=actions)
        assert run(ctl, 4) == []
        (candidate,) = ctl.stats.candidates
        store.decide(candidate.alert_id, "confirmed", by="jo")
        assert (
            ctl.process(4, 0.4, np.full((H, W, 3), 90, np.uint8))[0].alert_id == candidate.alert_id
        )
        assert [a.alert_id for a in actions.alerts] == [candidate.alert_id]


def test_a_dismissed_place_stays_silent_also_after_a_restart(tmp_path, mission):
    script = [[(box_at(10.0, -5.0, 60.0), 0.9, 0)]] * 20
    path = tmp_path / "a.db"
    with AlertStore(path) as store:
        ctl = controller(mission, ScriptedDetector(script[:4]), flight(3.0), store)
        run(ctl, 4)
        (candidate,) = ctl.stats.candidates
        store.decide(candidate.alert_id, "dismissed", by="jo")  # foam, says the operator
        actions = Announced()
        ctl.actions = actions
        ctl.detector = ScriptedDetector(script[:16])
        assert run(ctl, 16, start=4) == [] and actions.alerts == []  # evidence cannot overrule
    with AlertStore(path) as store:  # a restart: a new track on the same spot, another id
        ctl = controller(mission, ScriptedDetector(script), flight(3.0), store, mission_id="tiers")
        ctl.registry.targets.clear()  # forget the known target: only the zone may silence it
        assert run(ctl, 20) == []
        assert ctl.stats.suppressed == 1 and ctl.stats.candidates == []
        assert store.count() == 1


class ObjectsDetector(ScriptedDetector):
    """The scripted detector with the maritime head's classes (boats, buoys, life rings)."""

    classes = (
        "swimmer",
        "swimmer_with_life_jacket",
        "boat",
        "jetski",
        "buoy",
        "life_saving_appliances",
    )


def test_a_target_the_head_calls_a_boat_is_never_alerted(tmp_path, mission):
    script = [[(box_at(10.0, -5.0, 60.0), 0.9, 2)]] * 20
    actions = Announced()
    with AlertStore(tmp_path / "a.db") as store:
        ctl = controller(mission, ObjectsDetector(script), flight(3.0), store, actions=actions)
        assert run(ctl, 20) == [] and actions.alerts == []
        assert ctl.stats.candidates == [] and ctl.stats.objects == 1
        assert "calls an object (never alerted): 1" in ctl.summary()


def test_a_target_first_called_a_boat_becomes_a_candidate_once_it_is_a_person(tmp_path, mission):
    box = box_at(10.0, -5.0, 60.0)
    script = [[(box, 0.9, 2)]] * 3 + [[(box, 0.9, 0)]] * 27
    with AlertStore(tmp_path / "a.db") as store:
        ctl = controller(mission, ObjectsDetector(script), flight(4.0), store)
        (alert,) = run(ctl, 30)
        assert alert.class_name == "swimmer"
        (candidate,) = ctl.stats.candidates
        assert candidate.frame_index > 3


def test_a_life_ring_is_its_own_kind_of_alert(tmp_path, mission):
    script = [[(box_at(10.0, -5.0, 60.0), 0.9, 5)]] * 20
    with AlertStore(tmp_path / "a.db") as store:
        ctl = controller(mission, ObjectsDetector(script), flight(3.0), store)
        (alert,) = run(ctl, 20)
        assert alert.class_name == "life_saving_appliances"
        assert "life_saving_appliances" in store.get(alert.alert_id).class_name


def test_a_boat_the_head_boxes_as_a_person_is_too_large_against_its_surroundings(tmp_path, mission):
    """The head's box never grows past its crop: a 16 px box on a 6 m boat is person-sized.
    The object under it, measured in the frame, is not."""
    box = box_at(5.0, 5.0, 60.0, side_px=16.0)  # 0.5 m: a person, by the box
    cx, cy = int((box[0] + box[2]) / 2), int((box[1] + box[3]) / 2)
    frame = np.full((H, W, 3), 90, np.uint8)
    cv2.rectangle(frame, (cx - 90, cy - 30), (cx + 90, cy + 30), (235, 235, 240), -1)  # 6 m
    script = [[(box, 0.9, 0)]] * 20
    for max_extent_m, confirmed in ((3.0, False), (0.0, True)):
        mission.confirm.max_extent_m = max_extent_m
        with AlertStore(tmp_path / f"a{max_extent_m}.db") as store:
            ctl = controller(mission, ScriptedDetector(script), flight(3.0), store)
            alerts = [a for i in range(20) for a in ctl.process(i, i / FPS, frame)]
            assert bool(alerts) == confirmed
            (candidate,) = ctl.stats.candidates
            if not confirmed:
                reason = store.get(candidate.alert_id).discarded
                assert "6.0 m across against its surroundings is no person" in reason


def test_the_extent_is_ready_before_the_first_candidate_when_it_is_measured(
    tmp_path, mission, monkeypatch
):
    """OpenCV builds its Lab tables on first use (about 0.17 s): the controller has them built
    when it starts, not at its first candidate's measurement, and only if it measures."""
    from sarmission.perception import extent

    prepared = []
    monkeypatch.setattr(extent, "prepare", lambda: prepared.append(True))
    for max_extent_m, expected in ((4.0, [True]), (0.0, [])):
        prepared.clear()
        mission.confirm.max_extent_m = max_extent_m
        with AlertStore(tmp_path / f"p{max_extent_m}.db") as store:
            controller(mission, ScriptedDetector([]), flight(1.0), store)
        assert prepared == expected


LOOK_BOX = box_at(5.0, 5.0, 60.0, side_px=10.0)


def look_frame(k: int, swinging: bool) -> np.ndarray:
    """A body with an arm: swinging once in 4.5 s, or held still."""
    cx, cy = int((LOOK_BOX[0] + LOOK_BOX[2]) / 2), int((LOOK_BOX[1] + LOOK_BOX[3]) / 2)
    image = np.full((H, W, 3), 90, np.uint8)
    cv2.circle(image, (cx, cy), 3, (40, 120, 230), -1)
    angle = 2 * np.pi * k / 45 if swinging else 0.0
    tip = (int(cx + 6 * np.cos(angle)), int(cy + 6 * np.sin(angle)))
    cv2.line(image, (cx, cy), tip, (200, 200, 210), 2)
    return image


def test_a_steady_object_waits_when_the_rule_asks_for_a_changing_look(tmp_path, mission):
    """A floating object's look stays the same from frame to frame; a swimmer's arm swings.
    Only with ``min_look_change`` does the steady one wait (and stay a candidate for the
    operator) instead of being confirmed."""
    box, frame = LOOK_BOX, look_frame

    script = [[(box, 0.9, 0)]] * 90
    for swinging, rule, confirmed in ((False, 0.15, False), (True, 0.15, True), (False, 0.0, True)):
        mission.confirm.min_look_change = rule
        with AlertStore(tmp_path / f"l{swinging}{rule}.db") as store:
            ctl = controller(mission, ScriptedDetector(script), flight(6.0), store)
            alerts = [a for i in range(90) for a in ctl.process(i, i / FPS, frame(i, swinging))]
            assert bool(alerts) == confirmed, (swinging, rule)
            (candidate,) = ctl.stats.candidates
            looks = [
                s.look_change
                for s in ctl.candidates.evidence[candidate.target_id].sightings
                if s.look_change is not None
            ]
            if rule:  # without the rule this mission confirms within a second: no look yet
                assert (np.median(looks) > 0.15) == swinging, np.median(looks)


def test_the_look_follows_the_target_across_its_broken_tracks(tmp_path, mission):
    """A faint swimmer's tracks break and re-form within a second: its look is compared with
    its own patch a second earlier whatever track took it, so it is measured and confirmed."""
    from sarmission.tracking.tracker import Tracker

    mission.confirm.min_look_change = 0.15
    script = [[(LOOK_BOX, 0.9, 0)] if k % 8 != 7 else [] for k in range(120)]
    with AlertStore(tmp_path / "broken.db") as store:
        ctl = controller(mission, ScriptedDetector(script), flight(13.0), store)
        ctl.tracker = Tracker(max_age=0)  # one missed frame ends a track
        alerts = [a for i in range(120) for a in ctl.process(i, i / FPS, look_frame(i, True))]
        (candidate,) = ctl.stats.candidates
        tracks = {s.track_id for s in ctl.candidates.evidence[candidate.target_id].sightings}
        assert len(tracks) > 3, tracks  # several tracks, each under a second
        assert alerts, store.get(candidate.alert_id).discarded
