"""The camera's view after ROIs: every transition of the table, the timing of hold and settle,
and events from two threads at once."""

from __future__ import annotations

import threading

import pytest

from sarmission.mission.camera_hold import TRANSITIONS, CameraHold, Event, View

HOLD_S = 10.0
SETTLE_S = 2.0


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def camera_in(view: View) -> tuple[CameraHold, Clock]:
    """A camera brought into ``view`` through its public calls only."""
    clock = Clock()
    camera = CameraHold(HOLD_S, SETTLE_S, clock)
    if view is View.SURVEY:
        return camera, clock
    camera.roi_delivered(gimbal=view in (View.ON_TARGET, View.RELEASING_GIMBAL, View.SETTLING))
    if view in (View.ON_TARGET, View.VEHICLE_TURNED):
        return camera, clock
    clock.now += HOLD_S
    assert camera.release_due(lambda: False)
    if view is not View.SETTLING:
        return camera, clock
    camera.release_delivered()
    return camera, clock


def fire(camera: CameraHold, clock: Clock, event: Event) -> None:
    """``event`` as it happens in flight: an answer from the outbox or time passing."""
    if event is Event.ROI_DELIVERED:
        camera.roi_delivered(gimbal=True)
    elif event is Event.ROI_DELIVERED_NO_GIMBAL:
        camera.roi_delivered(gimbal=False)
    elif event is Event.RELEASE_DELIVERED:
        camera.release_delivered()
    elif event is Event.RELEASE_REFUSED:
        camera.release_refused()
    elif event is Event.HOLD_OVER:
        clock.now += HOLD_S
        camera.release_due(lambda: False)
    elif event is Event.SETTLED:
        clock.now += SETTLE_S


@pytest.mark.parametrize(("before", "event"), sorted(TRANSITIONS, key=str), ids=lambda x: x.name)
def test_each_transition_of_the_table(before: View, event: Event) -> None:
    camera, clock = camera_in(before)
    assert camera.view is before
    fire(camera, clock, event)
    assert camera.view is TRANSITIONS[(before, event)]
    assert camera.search_paused() is TRANSITIONS[(before, event)].paused


UNLISTED = [
    (v, e) for v in View for e in Event if (v, e) not in TRANSITIONS and e is not Event.SETTLED
]


@pytest.mark.parametrize(("before", "event"), UNLISTED, ids=lambda x: x.name)
def test_an_event_the_table_does_not_list_leaves_the_view(before: View, event: Event) -> None:
    camera, clock = camera_in(before)
    if event is Event.HOLD_OVER:  # only a hold ends; elsewhere no release becomes due
        clock.now += HOLD_S
        assert not camera.release_due(lambda: False)
    else:
        fire(camera, clock, event)
    expected = View.SURVEY if before is View.SETTLING and event is Event.HOLD_OVER else before
    assert camera.view is expected  # (settling ends by itself within the hold time)


def test_search_pauses_only_while_a_gimbal_points_the_camera_away() -> None:
    assert [v for v in View if v.paused] == [View.ON_TARGET, View.RELEASING_GIMBAL, View.SETTLING]
    camera, _ = camera_in(View.ON_TARGET)
    assert camera.search_paused()
    camera, _ = camera_in(View.VEHICLE_TURNED)
    assert not camera.search_paused()


def test_the_release_is_due_after_the_hold_and_not_while_another_roi_is_on_its_way() -> None:
    camera, clock = camera_in(View.ON_TARGET)
    clock.now += HOLD_S - 0.01
    assert not camera.release_due(lambda: False)
    clock.now += 0.01
    assert not camera.release_due(lambda: True)
    assert camera.view is View.ON_TARGET
    assert camera.release_due(lambda: False)
    assert not camera.release_due(lambda: False)  # once: it is queued now
    assert camera.view is View.RELEASING_GIMBAL


def test_a_new_roi_restarts_the_hold() -> None:
    camera, clock = camera_in(View.ON_TARGET)
    clock.now += HOLD_S - 1.0
    camera.roi_delivered(gimbal=True)
    clock.now += 1.0
    assert not camera.release_due(lambda: False)
    clock.now += HOLD_S - 1.0
    assert camera.release_due(lambda: False)


def test_the_pause_ends_settle_s_after_the_release_is_delivered() -> None:
    camera, clock = camera_in(View.RELEASING_GIMBAL)
    clock.now += 30.0  # a release waiting for a lost link keeps the pause
    assert camera.search_paused()
    camera.release_delivered()
    clock.now += SETTLE_S - 0.01
    assert camera.search_paused()
    clock.now += 0.01
    assert not camera.search_paused()
    assert camera.view is View.SURVEY


def test_a_refused_release_ends_the_pause_at_once() -> None:
    camera, _ = camera_in(View.RELEASING_GIMBAL)
    camera.release_refused()
    assert not camera.search_paused()


def test_one_release_per_hold_when_threads_ask_at_once() -> None:
    """Several threads find the hold over at the same moment: exactly one sends the release."""
    for _ in range(50):
        camera, clock = camera_in(View.ON_TARGET)
        clock.now += HOLD_S
        barrier = threading.Barrier(4)
        due: list[bool] = []

        def ask(camera: CameraHold, barrier: threading.Barrier, due: list[bool]) -> None:
            barrier.wait(timeout=30.0)
            due.append(camera.release_due(lambda: False))

        threads = [threading.Thread(target=ask, args=(camera, barrier, due)) for _ in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=30.0)
        assert sorted(due) == [False, False, False, True]
        assert camera.view is View.RELEASING_GIMBAL


def test_answers_on_the_outbox_thread_interleave_with_frames() -> None:
    """Answers and frames race; afterwards the camera still follows the table."""
    camera = CameraHold(HOLD_S, SETTLE_S, Clock())
    done = threading.Event()
    errors: list[BaseException] = []

    def answers() -> None:
        try:
            for i in range(2000):
                camera.roi_delivered(gimbal=i % 2 == 0)
                camera.release_delivered()
                camera.release_refused()
        except BaseException as exc:  # noqa: BLE001 - reported by the main thread
            errors.append(exc)
        finally:
            done.set()

    worker = threading.Thread(target=answers)
    worker.start()
    while not done.is_set():
        camera.release_due(lambda: False)
        camera.search_paused()
    worker.join(timeout=60.0)
    assert errors == []
    assert camera.view is View.VEHICLE_TURNED  # the last answer: an ROI without gimbal
    camera.release_refused()  # not releasing: ignored
    assert camera.view is View.VEHICLE_TURNED
