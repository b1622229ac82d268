"""A placed alert follows its target's better position: at its confirmation, then at most every
few seconds, durably, told on the console and to a queued visit; never for a dismissed alert."""

import math
from dataclasses import dataclass

import numpy as np
import pytest
from scripted_detector import ScriptedDetector
from test_controller import (
    ALT,
    DRONE_NED,
    FPS,
    TARGET_NED,
    YAW,
    AnnouncedActions,
    run_frames,
    target_pixel,
    truth_latlon,
)

from sarmission.alerts.model import Alert, drift_course_speed
from sarmission.alerts.store import AlertStore
from sarmission.geo.camera import CameraPose, project_points
from sarmission.geo.wgs84 import ned_to_geodetic
from sarmission.mavlink.telemetry import TelemetryBuffer
from sarmission.mission.config import ConfirmConfig, load_mission
from sarmission.mission.controller import MissionController
from sarmission.mission.refinement import REFINE_PERIOD_S, PositionRefiner
from sarmission.mission.targets import distance_m

W, H = 960, 540
BIAS_E_M = 10.0
BIAS_UNTIL_S = 2.0


@pytest.fixture
def mission():
    m = load_mission(
        overrides={
            "camera.width": W,
            "camera.height": H,
            "camera.hfov_deg": 30.0,
            "name": "refine_test",
        }
    )
    m.confirm = ConfirmConfig(min_seen_s=1.0, min_sightings=6, min_score=0.6)
    return m


def biased_buffer(
    mission, t_end: float, bias_m: float = BIAS_E_M, until_s: float = BIAS_UNTIL_S
) -> TelemetryBuffer:
    """The hovering drone of the controller tests, its GNSS position reported ``bias_m`` east
    of the truth for the first ``until_s`` (a bias that wanders off), exact after that."""
    buf = TelemetryBuffer(stale_after_s=mission.telemetry.stale_after_s)
    home = mission.area.home
    buf.set_home(*home)
    for t in np.arange(0.0, t_end + 1e-9, 0.05):
        east = DRONE_NED[1] + (bias_m if t < until_s else 0.0)
        lat, lon, _ = ned_to_geodetic(DRONE_NED[0], east, 0.0, *home)
        buf.push_position(float(t), float(lat), float(lon), ALT)
        buf.push_attitude(float(t), 0.0, 0.0, YAW)
    return buf


class RefinedActions(AnnouncedActions):
    """Also keeps each refined position with its error."""

    def __init__(self) -> None:
        super().__init__()
        self.refined_errors: list = []

    def refine(self, alert) -> bool:
        self.refined_errors.append((alert.position, alert.error_m))
        return super().refine(alert)


def fly(mission, store, seconds: float, actions=None, lines=None, first_s=None):
    """The target in every frame for ``seconds``; only the first ``first_s`` are run (default
    all): the caller runs the rest."""
    n = int(seconds * FPS)
    u, v = target_pixel(mission)
    script = [[((u - 5, v - 5, u + 5, v + 5), 0.8, 0)] for _ in range(n)]
    ctl = MissionController(
        mission,
        ScriptedDetector(script),
        biased_buffer(mission, n / FPS),
        store,
        actions=actions,
        console=(lines.append if lines is not None else lambda s: None),
    )
    return ctl, run_frames(ctl, n if first_s is None else int(first_s * FPS))


def test_a_biased_start_is_refined_towards_the_truth_and_its_error_stays_honest(tmp_path, mission):
    lines: list[str] = []
    actions = RefinedActions()
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl, alerts = fly(mission, store, 30.0, actions, lines)
        assert len(alerts) == 1
        stored = store.get(alerts[0].alert_id)
        events = store.events()
    truth = truth_latlon(mission)
    candidate = ctl.stats.candidates[0]
    # the lock's one fix carried the bias; the confirmation (at 1.2 s) the mean of its fixes,
    # every one of them still biased
    first_error = distance_m(actions.announced[0][1], truth)
    assert first_error == pytest.approx(BIAS_E_M, abs=1.0)
    assert candidate.alert_id == stored.alert_id
    # refined on the latest 20 s of fixes: the biased ones have left the window (the last
    # refinement may come while one or two remain: a move under REFINE_MIN_MOVE_M after it is
    # not worth telling), and its error is the fixes' own again
    final_error = distance_m(stored.position, truth)
    assert final_error < 0.5
    fix_error = ctl.candidates.evidence[1].sightings[-1].error_m
    assert stored.error_m == pytest.approx(fix_error, rel=0.05)
    # on the way, while the window held both, the error grew with the fixes' disagreement, and
    # every position told was within twice its error of the truth
    assert max(error for _, error in actions.refined_errors) > 1.5 * fix_error
    for position, error in actions.refined_errors:
        assert distance_m(position, truth) <= 2.0 * error
    refined = [e for e in events if e.kind == "position"]
    assert refined and all(e.detail.startswith("refined: moved ") for e in refined)
    # at most one refinement every REFINE_PERIOD_S after the confirmation's
    assert len(refined) <= 1 + math.ceil(30.0 / REFINE_PERIOD_S)
    # every fix of the first 2 s was biased alike: the confirmation found the mean where the
    # lock's fix was and only gave the alert its drift (still), which the ALERT line tells;
    # each move came later and was told on the console
    told = [line for line in lines if line.startswith("REFINED target 1")]
    assert refined[0].detail.startswith("refined: moved 0.0 m")
    assert len(told) == len(refined) - 1
    assert actions.refined and actions.refined[-1][1] == stored.position
    assert ctl.stats.refined == len(refined)
    assert f"positions refined: {len(refined)}" in ctl.summary()


def exact_controller(mission, script: list, store, console) -> MissionController:
    """A controller on ``script`` with the hovering drone's exact telemetry."""
    return MissionController(
        mission,
        ScriptedDetector(script),
        biased_buffer(mission, len(script) / FPS, bias_m=0.0),
        store,
        console=console,
    )


def pixel_of(mission, north: float, east: float) -> tuple[float, float]:
    """Where the hovering drone's nadir camera sees ground point ``(north, east)``."""
    cam = CameraPose.from_attitudes(
        np.array([DRONE_NED[0], DRONE_NED[1], -ALT]), (0.0, 0.0, YAW), (0.0, -math.pi / 2, 0.0)
    )
    uv, _ = project_points(mission.camera.intrinsics(), cam, np.array([[north, east, 0.0]]))
    return float(uv[0, 0]), float(uv[0, 1])


def scripted(mission, n: int, where) -> list:
    """``n`` frames of a 10 px box on each ground point ``where(i)`` lists for frame ``i``."""
    script = []
    for i in range(n):
        boxes = []
        for north, east in where(i):
            u, v = pixel_of(mission, north, east)
            boxes.append(((u - 5, v - 5, u + 5, v + 5), 0.8, 0))
        script.append(boxes)
    return script


def fly_exact(tmp_path, mission, script: list, console=lambda s: None):
    """``script`` through a controller with exact telemetry: the controller and the one
    alert, as stored."""
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl = exact_controller(mission, script, store, console)
        (alert,) = run_frames(ctl, len(script))
        return ctl, store.get(alert.alert_id)


def test_a_drifting_swimmer_is_placed_where_they_are_not_where_they_were(tmp_path, mission):
    """A swimmer drifting south-east at 0.5 m/s for 28 s (staying in view; the buffer keeps
    30 s of telemetry), exact telemetry: the alert follows to within a metre of where they are
    at its last refinement; the mean of every fix (the registry's) lies about 7 m behind."""
    n = int(28.0 * FPS)
    drift = 0.5 * np.array([-math.sqrt(0.5), math.sqrt(0.5)])  # m/s north, east

    def place(i: int) -> np.ndarray:
        return np.array(TARGET_NED) + drift * i / FPS

    script = []
    for i in range(n):
        u, v = pixel_of(mission, *place(i))
        script.append([((u - 5, v - 5, u + 5, v + 5), 0.8, 0)])
    lines: list[str] = []
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl = exact_controller(mission, script, store, lines.append)
        (alert,) = run_frames(ctl, n)
        stored = store.get(alert.alert_id)
    frame = ctl.stats.position_frames[stored.alert_id]
    assert frame >= n - REFINE_PERIOD_S * FPS
    # the store says how old the position is: as of its frame's fix
    ahead = stored.position_time - stored.lock_time
    assert ahead == pytest.approx((frame - stored.frame_index) / FPS, abs=1e-6)
    lat, lon, _ = ned_to_geodetic(*place(frame), 0.0, *mission.area.home)
    assert distance_m(stored.position, (lat, lon)) < 1.0
    assert distance_m(ctl.registry.targets[1].position, (lat, lon)) > 5.0
    assert sum(line.startswith("REFINED target 1") for line in lines) >= 4
    # and says where they are heading: 0.5 m/s to the south-east, for the team's TAK
    course, speed = drift_course_speed(stored.drift_ne)
    assert speed == pytest.approx(0.5, abs=0.05) and course == pytest.approx(135.0, abs=5.0)
    assert "drifting 0.5 m/s to 135°" in [x for x in lines if x.startswith("REFINED")][-1]


def test_a_still_swimmer_is_told_still(tmp_path, mission):
    """Exact telemetry, a swimmer who does not move: the confirmed alert's drift is zero (still),
    not unknown, and its console line says so."""
    u, v = pixel_of(mission, *TARGET_NED[:2])
    script = [[((u - 5, v - 5, u + 5, v + 5), 0.8, 0)] for _ in range(int(6.0 * FPS))]
    lines: list[str] = []
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl = exact_controller(mission, script, store, lines.append)
        (alert,) = run_frames(ctl, len(script))
        assert store.get(alert.alert_id).drift_ne == (0.0, 0.0)
    assert any(x.startswith("ALERT target 1") and x.endswith("; still)") for x in lines), lines


def test_a_dismissed_alert_keeps_the_position_the_operator_dismissed(tmp_path, mission):
    """The operator dismisses the alert at 1.5 s: its zone stays where they saw it, and the
    controller stops refining it."""
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl, alerts = fly(mission, store, 12.0, first_s=1.5)
        assert len(alerts) == 1
        alert_id = alerts[0].alert_id
        seen = store.get(alert_id).position
        refined_before = ctl.stats.refined  # the confirmation's (its drift is known now)
        store.record_decision(alert_id, "dismissed", "op")
        run_frames(ctl, 105, start=15)
        assert store.get(alert_id).position == seen
        # it was due (the bias gone at 2 s), the store refused, and it is forgotten
        assert alert_id not in ctl.refiner._last and ctl.stats.refined == refined_before


def _alert(position=(0.0, 0.0), error_m=4.0, tier="confirmed") -> Alert:
    return Alert(
        tier=tier,
        mission_id="m",
        target_id=1,
        class_name="swimmer",
        score=0.9,
        lock_time=1.7e9,
        frame_index=0,
        position=position,
        error_m=error_m,
    )


def north_of(position, metres):
    lat, lon, _ = ned_to_geodetic(metres, 0.0, 0.0, position[0], position[1], 0.0)
    return float(lat), float(lon)


def test_the_refiner_waits_its_period_and_ignores_small_changes():
    r = PositionRefiner(period_s=5.0, min_move_m=1.0, move_share=0.5, error_share=0.25)
    alert = _alert()
    r.done(alert.alert_id, 10.0)
    far = north_of(alert.position, 10.0)
    assert r.due(alert, far, 4.0, 14.9) is None  # too soon
    due = r.due(alert, far, 4.0, 15.0)
    assert due is not None and due.moved_m == pytest.approx(10.0, abs=0.01)
    assert "moved 10.0 m, +- 4.0 m" in due.detail()
    # a move within half the error (2 m), the error within a quarter: not worth telling
    assert r.due(alert, north_of(alert.position, 1.9), 4.9, 15.0) is None
    assert r.due(alert, north_of(alert.position, 2.1), 4.0, 15.0) is not None
    assert r.due(alert, alert.position, 5.1, 15.0) is not None  # the error grew by > 25 %
    assert r.due(alert, alert.position, 2.9, 15.0) is not None  # or shrank
    # the confirmation takes any change beyond a decimetre, however soon
    assert r.due(alert, north_of(alert.position, 0.5), 4.0, 10.1, force=True) is not None
    assert r.due(alert, north_of(alert.position, 0.05), 4.0, 10.1, force=True) is None
    # nothing to refine without positions on both sides
    assert r.due(_alert(position=None), far, 4.0, 99.0) is None
    assert r.due(alert, None, None, 99.0) is None


def test_an_alert_due_is_looked_at_once_a_second_not_every_frame():
    """Due but not moved enough: the next fit of its window waits a second, not a frame."""
    r = PositionRefiner(period_s=5.0, check_period_s=1.0)
    r.done("a", 0.0)
    assert not r.worth_a_look("a", 4.9)  # not due yet
    assert r.worth_a_look("a", 5.0)
    assert not r.worth_a_look("a", 5.5)
    assert r.worth_a_look("a", 6.0)
    r.done("a", 6.0)  # refined: the period starts again
    assert not r.worth_a_look("a", 10.9) and r.worth_a_look("a", 11.0)


def test_the_store_refines_only_placed_alerts_nobody_dismissed_or_discarded(tmp_path):
    with AlertStore(tmp_path / "alerts.db") as store:
        placed, blind, dismissed, discarded = (
            _alert(),
            _alert(position=None, error_m=None),
            _alert(),
            _alert(tier="candidate"),
        )
        for a in (placed, blind, dismissed, discarded):
            store.add(a)
        store.record_decision(dismissed.alert_id, "dismissed", "op")
        store.discard(discarded.alert_id, "score 0.4 below 0.7")
        better = north_of((0.0, 0.0), 3.0)
        assert store.refine_position(placed.alert_id, better, 2.0, "ground plane", "refined: x")
        now = store.get(placed.alert_id)
        assert now.position == pytest.approx(better) and now.error_m == 2.0
        assert store.events()[-1].kind == "position"
        assert store.events()[-1].detail == "refined: x"
        for a in (blind, dismissed, discarded):
            assert not store.refine_position(a.alert_id, better, 2.0, "ground plane")
            assert store.get(a.alert_id).position == a.position
        with pytest.raises(KeyError):
            store.refine_position("nope", better, 2.0, "")
        with pytest.raises(ValueError):
            store.refine_position(placed.alert_id, (91.0, 0.0), 2.0, "")


def test_a_track_that_joined_only_by_the_re_find_radius_does_not_move_the_alert(tmp_path, mission):
    """The swimmer's track confirms them and is lost at 3 s; at 6 s another track locks 6 m
    away and is seen for 10 s. The registry joins it to the target by the re-find radius
    (a person can swim 6 m in 3 s), unsure whether it is them: the alert stays where the
    swimmer was seen."""
    other = (TARGET_NED[0] - 6.0, TARGET_NED[1])
    script = scripted(
        mission,
        int(16.0 * FPS),
        lambda i: [TARGET_NED[:2]] if i < 3 * FPS else [other] if i >= 6 * FPS else [],
    )
    ctl, stored = fly_exact(tmp_path, mission, script)
    (target,) = ctl.registry.targets.values()
    assert [s.loose for s in target.shares.values()].count(True) == 1
    assert distance_m(stored.position, truth_latlon(mission)) < 0.5


def test_a_window_with_too_little_evidence_gives_no_estimate():
    from sarmission.mission.position_estimate import latest_position

    few = [_Fix(t / 10, 54.17, 7.89, 1.5) for t in range(10)]  # 10 fixes over 0.9 s
    assert latest_position(few) is not None
    assert latest_position(few, min_fixes=11) is None
    assert latest_position(few, min_span_s=1.0) is None
    assert latest_position(few, min_fixes=10, min_span_s=0.9) is not None


@dataclass(frozen=True)
class _Fix:
    t: float
    lat: float
    lon: float
    error_m: float


def test_a_glint_taken_back_out_of_the_target_never_moves_its_alert(tmp_path, mission):
    """A person alerted, then out of sight; a glint 7 m off locks and joins their target by the
    re-find radius and is seen for 2 s; the person's own track takes the target back over and
    the glint is gone for good. Its sightings stay in the target's evidence (a track's are
    dropped at its next sighting, and it has none), yet the alert never moves towards it."""
    from test_controller import confirm_at_lock, run_script

    confirm_at_lock(mission)
    u, v = pixel_of(mission, *TARGET_NED)
    person, moved, glint = (
        (u - 5, v - 5, u + 5, v + 5),
        (u + 21, v - 5, u + 31, v + 5),
        (u + 174, v - 5, u + 184, v + 5),
    )
    script = []
    for i in range(130):
        boxes = [(person, 0.9, 0)] if i < 10 else []
        boxes += [(glint, 0.8, 0)] if 50 <= i <= 70 else []
        boxes += [(moved, 0.9, 0)] if i >= 68 else []
        script.append(boxes)
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl = run_script(mission, script, store)
        first = min(store.list(), key=lambda a: a.target_id)
        moves = [
            float(e.detail.split("moved ")[1].split(" m")[0])
            for e in store.events()
            if e.kind == "position" and e.alert.alert_id == first.alert_id
        ]
    evidence = ctl.candidates.evidence[first.target_id].sightings
    glint_fixes = [s for s in evidence if distance_m((s.lat, s.lon), truth_latlon(mission)) > 5]
    assert len(glint_fixes) >= 10  # the glint's sightings are still there
    assert all(m < 2.0 for m in moves), moves
    assert distance_m(store_position(tmp_path, first.alert_id), truth_latlon(mission)) < 1.5


def store_position(tmp_path, alert_id):
    with AlertStore(tmp_path / "alerts.db") as store:
        return store.get(alert_id).position


def test_the_confirmation_goes_out_at_its_fixes_not_at_the_locks_one(tmp_path, mission):
    """The lock's fix (0.2 s) is 10 m off, every later one exact: the alert confirmed at 1.2 s
    is announced where the fixes that confirmed it put it, not at the lock's."""
    n = int(3.0 * FPS)
    u, v = target_pixel(mission)
    script = [[((u - 5, v - 5, u + 5, v + 5), 0.8, 0)] for _ in range(n)]
    actions = AnnouncedActions()
    lines: list[str] = []
    with AlertStore(tmp_path / "alerts.db") as store:
        ctl = MissionController(
            mission,
            ScriptedDetector(script),
            biased_buffer(mission, n / FPS, until_s=0.25),
            store,
            actions=actions,
            console=lines.append,
        )
        run_frames(ctl, n)
    # the candidate's line says where the lock put it
    (said,) = [line for line in lines if line.startswith("CANDIDATE target 1")]
    lat, lon = said.split(" at ")[1].split(" ")[0].split(",")
    lock = (float(lat), float(lon))
    truth = truth_latlon(mission)
    assert distance_m(lock, truth) > 9.0
    ((_, announced),) = actions.announced
    assert distance_m(announced, truth) < 2.0


def test_glints_where_the_person_was_never_move_the_alert(tmp_path, mission):
    """A person alerted and then out of sight for 15 s; four sun glints 3 m off lock one after
    the other, each for under a second, and join the target within the ground gate (not by
    the re-find radius). Together they fill the refinement window with enough fixes, yet
    none has a confirmation's evidence of its own: the alert stays where the person was."""
    glint = (TARGET_NED[0], TARGET_NED[1] + 3.0)
    glint_frames = [range(int(s * FPS), int((s + 0.8) * FPS)) for s in (18.0, 21.0, 24.0, 27.0)]

    def where(i: int) -> list:
        if i < 3 * FPS:
            return [TARGET_NED[:2]]
        return [glint] if any(i in frames for frames in glint_frames) else []

    ctl, stored = fly_exact(tmp_path, mission, scripted(mission, int(30.0 * FPS), where))
    (target,) = ctl.registry.targets.values()
    glints = [s for s in target.shares.values() if s.joined > 15.0]
    assert len(glints) == 4 and not any(s.loose for s in glints)
    assert sum(s.fixes for s in glints) >= mission.confirm.min_sightings
    assert distance_m(stored.position, truth_latlon(mission)) < 0.5


def test_a_second_person_where_the_first_was_widens_the_alerts_error(tmp_path, mission):
    """A swimmer drifting north at 1 m/s is alerted and lost at 10 s; 10 s later another,
    still, swimmer is seen for 10 s where the first was last seen. The registry joins them to
    the first's target (within its gate of the latest fix). The alert moves to them, but its
    error grows to cover where the first would be by then had they drifted on, and the
    console says why."""
    drift = np.array([1.0, 0.0])
    n = int(30.0 * FPS)
    lost, found = int(10.0 * FPS), int(20.0 * FPS)
    start = np.array([DRONE_NED[0] - 8.0, DRONE_NED[1]])

    def place(i: int) -> np.ndarray:
        return start + drift * min(i, lost) / FPS

    script = scripted(mission, n, lambda i: [place(i)] if i < lost or i >= found else [])
    lines: list[str] = []
    ctl, stored = fly_exact(tmp_path, mission, script, lines.append)
    (target,) = ctl.registry.targets.values()
    (second,) = [s for s in target.shares.values() if s.joined > 15.0]
    assert not second.loose and second.jump_m is not None and second.jump_m > 5.0
    # compared once the track had a confirmation's evidence (1 s): the first would be 21 m
    # from the start by then
    second_at = ned_to_geodetic(*place(lost), 0.0, *mission.area.home)[:2]
    first_at = ned_to_geodetic(*(start + drift * 21.0), 0.0, *mission.area.home)[:2]
    assert distance_m(second_at, first_at) > 10.0
    # the window's oldest fixes are the first's last ones: the position lies near the second
    assert distance_m(stored.position, second_at) < 2.0
    assert distance_m(stored.position, first_at) <= 2.0 * stored.error_m
    assert stored.error_m >= second.jump_m
    assert any("m apart: one person moved, or two" in line for line in lines), lines


def test_a_refinement_is_of_the_frame_of_its_latest_fix(tmp_path, mission):
    """A swimmer drifting east at 0.5 m/s is seen for 14 s, then a glint locks beside where
    they were lost: its sighting brings a refinement that was due, to the swimmer's position
    as of their last fix. The position is of that frame (what the scorer compares with the
    truth), not of the glint's."""
    drift = np.array([0.0, 0.5])
    n = int(18.0 * FPS)
    lost = int(14.0 * FPS)
    start = np.array([DRONE_NED[0], DRONE_NED[1] - 4.0])
    glint = start + drift * 14.0 + np.array([2.0, 0.0])

    def where(i: int) -> list:
        if i < lost:
            return [start + drift * i / FPS]
        return [glint] if i >= int(17.0 * FPS) else []

    ctl, stored = fly_exact(tmp_path, mission, scripted(mission, n, where))
    (target,) = ctl.registry.targets.values()
    (glint,) = [s for s in target.shares.values() if s.joined > 15.0]
    assert not glint.loose and not glint.jump_m
    frame = ctl.stats.position_frames[stored.alert_id]
    assert frame == lost - 1
    assert stored.position_time - stored.lock_time == pytest.approx(
        (frame - stored.frame_index) / FPS, abs=1e-6
    )
