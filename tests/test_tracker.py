"""Tracker and box Kalman filter on hand-made trajectories of tiny boxes."""

from __future__ import annotations

import numpy as np
import pytest

from sarmission.boxes import cxcywh_to_xyxy
from sarmission.perception.types import Detections
from sarmission.tracking.kalman import BoxKalman, MotionNoise, process_noise, transition_matrix
from sarmission.tracking.tracker import Tracker, TrackState, associate

SIZE = 6.0


def dets(
    *targets: tuple[float, float],
    score: float = 0.9,
    classes: list[int] | None = None,
    size: float = SIZE,
) -> Detections:
    """Detections of square boxes centred on ``targets`` (cx, cy)."""
    centres = np.array(targets, dtype=np.float64).reshape(-1, 2)
    cxcywh = np.column_stack([centres, np.full((len(centres), 2), size)])
    n = len(centres)
    return Detections(
        boxes=cxcywh_to_xyxy(cxcywh).astype(np.float32),
        scores=np.full(n, score, np.float32),
        class_ids=np.array(classes if classes is not None else [0] * n, np.int64),
    )


def centre(state: TrackState) -> np.ndarray:
    return np.array([(state.box[0] + state.box[2]) / 2, (state.box[1] + state.box[3]) / 2])


def run(
    tracker: Tracker,
    frames: list[Detections],
    shifts: list[tuple[float, float] | None] | None = None,
) -> list[list[TrackState]]:
    shifts = shifts or [None] * len(frames)
    return [
        tracker.update(d, frame_index=i, timestamp=i / 30.0, camera_shift=s)
        for i, (d, s) in enumerate(zip(frames, shifts, strict=True))
    ]


# Kalman filter --------------------------------------------------------------------------------


def test_kalman_matrices_follow_constant_velocity_model() -> None:
    f = transition_matrix(2.0)
    x = np.array([10.0, 20.0, 5.0, 6.0, 1.5, -0.5])
    assert np.allclose(f @ x, [13.0, 19.0, 5.0, 6.0, 1.5, -0.5])
    q = process_noise(1.0, MotionNoise(acceleration_std=2.0, size_drift_std=0.5))
    assert np.allclose(q[[0, 0, 4], [0, 4, 4]], [1.0, 2.0, 4.0])
    assert q[2, 2] == pytest.approx(0.25) and np.allclose(q, q.T)


def test_kalman_learns_velocity_and_applies_camera_shift() -> None:
    kf = BoxKalman(cxcywh_to_xyxy(np.array([100.0, 100.0, 6.0, 6.0])))
    for i in range(1, 20):
        kf.predict()
        kf.update(cxcywh_to_xyxy(np.array([100.0 + 2 * i, 100.0 - i, 6.0, 6.0])))
    assert np.allclose(kf.velocity, (2.0, -1.0), atol=0.05)
    kf.predict(dt=2.0, camera_shift=(10.0, 5.0))
    assert np.allclose(kf.centre, (138 + 4 + 10, 81 - 2 + 5), atol=0.3)
    assert np.allclose(kf.velocity, (2.0, -1.0), atol=0.05)


# Association ----------------------------------------------------------------------------------


def test_associate_gates_and_solves_globally() -> None:
    tracks = cxcywh_to_xyxy(np.array([[100.0, 100, 6, 6], [108, 100, 6, 6]]))
    # A greedy pass would give detection 0 (at 104) to track 0 and leave track 1 without a
    # match; the optimal assignment pairs both.
    detections = cxcywh_to_xyxy(np.array([[104.0, 100, 6, 6], [99, 100, 6, 6]]))
    matches, lost, new = associate(tracks, detections, match_nwd=0.3, max_centre_distance=8.0)
    assert sorted(matches) == [(0, 1), (1, 0)] and lost == [] and new == []

    far = cxcywh_to_xyxy(np.array([[120.0, 100, 6, 6]]))  # W = 20 px: NWD 0.21, 20 px away
    assert associate(tracks[:1], far, 0.3, 8.0) == ([], [0], [0])
    odd_size = cxcywh_to_xyxy(np.array([[106.0, 100, 40, 40]]))  # NWD 0.14, but 6 px away
    assert associate(tracks[:1], odd_size, 0.3, 8.0) == ([(0, 0)], [], [])
    assert associate(tracks[:1], odd_size, 0.3, 5.0) == ([], [0], [0])


# Tracker --------------------------------------------------------------------------------------


def test_constant_velocity_target_keeps_one_id() -> None:
    rng = np.random.default_rng(0)
    truth = [np.array([200.0 + 1.5 * i, 300.0 - 0.8 * i]) for i in range(60)]
    measured = [t + rng.normal(0.0, 1.0, 2) for t in truth]
    states = run(Tracker(), [dets(tuple(m)) for m in measured])
    assert {s.track_id for frame in states for s in frame} == {1}
    last = states[-1][0]
    assert last.hits == 60 and last.misses == 0 and last.age == 60
    filtered_error = [np.linalg.norm(centre(states[i][0]) - truth[i]) for i in range(30, 60)]
    raw_error = [np.linalg.norm(measured[i] - truth[i]) for i in range(30, 60)]
    assert np.mean(filtered_error) < 0.8 * np.mean(raw_error)
    assert np.allclose(last.velocity, (1.5, -0.8), atol=0.5)


def test_crossing_targets_keep_their_ids() -> None:
    rng = np.random.default_rng(1)
    truth_a = [np.array([100.0 + 2 * i, 100.0 + 1 * i]) for i in range(60)]
    truth_b = [np.array([220.0 - 2 * i, 100.0 + 1 * i]) for i in range(60)]  # meet at frame 30
    frames = [
        dets(tuple(a + rng.normal(0, 1, 2)), tuple(b + rng.normal(0, 1, 2)))
        for a, b in zip(truth_a, truth_b, strict=True)
    ]
    states = run(Tracker(), frames)
    assert {s.track_id for frame in states for s in frame} == {1, 2}
    for i, frame in enumerate(states):
        if np.linalg.norm(truth_a[i] - truth_b[i]) < 8.0:
            continue  # overlapping: either box is right
        by_id = {s.track_id: centre(s) for s in frame}
        assert np.linalg.norm(by_id[1] - truth_a[i]) < 3.0, i
        assert np.linalg.norm(by_id[2] - truth_b[i]) < 3.0, i


@pytest.mark.parametrize("gap, survives", [(4, True), (5, True), (6, False)])
def test_track_survives_up_to_max_age_missed_frames(gap: int, survives: bool) -> None:
    max_age = 5
    position = [(300.0 + 0.5 * i, 200.0) for i in range(40)]
    frames = [dets(position[i]) if not 10 <= i < 10 + gap else Detections() for i in range(40)]
    states = run(Tracker(max_age=max_age), frames)
    ids_after = {s.track_id for s in states[10 + gap]}
    assert ids_after == ({1} if survives else {2})
    coasting = states[10 + gap - 1]
    if survives:
        assert [(s.track_id, s.misses) for s in coasting] == [(1, gap)]
    else:
        assert coasting == []  # gone on its (max_age + 1)-th miss
        assert [s.misses for s in states[10 + max_age - 1]] == [max_age]


def test_spurious_single_detection_never_locks() -> None:
    frames = [dets((100.0, 100.0)) for _ in range(30)]
    frames[5] = dets((100.0, 100.0), (600.0, 400.0))
    states = run(Tracker(max_age=5), frames)
    spurious = [s for frame in states for s in frame if s.track_id == 2]
    assert len(spurious) == 6  # its birth frame plus max_age coasting frames
    assert not any(s.locked or s.just_locked for s in spurious)
    assert all(s.locked for s in states[-1]) and [s.track_id for s in states[-1]] == [1]


def test_three_hits_in_five_frames_lock_at_the_third_hit() -> None:
    pattern = [True, False, True, False, True, False, False, True, True]
    tracker = Tracker(max_age=3, lock_m=3, lock_k=5)
    states = [
        tracker.update(dets((50.0 + i, 80.0)) if hit else Detections(), 100 + i, i / 30)[0]
        for i, hit in enumerate(pattern)
    ]
    assert [s.locked for s in states] == [False] * 4 + [True] * 5
    assert [s.just_locked for s in states] == [False] * 4 + [True] + [False] * 4
    assert {s.lock_frame for s in states[4:]} == {104}
    assert {s.track_id for s in states} == {1}


def test_low_scored_detections_keep_the_track_but_do_not_lock_it() -> None:
    """lock_min_score 0.5: scores 0.9, 0.4, 0.4, 0.9, 0.9 -> the same track all along, locked at
    its third detection scored >= 0.5 (frame 4), not at its third detection (frame 2)."""
    scores = [0.9, 0.4, 0.4, 0.9, 0.9]
    strict = Tracker(lock_m=3, lock_k=5, lock_min_score=0.5)
    loose = Tracker(lock_m=3, lock_k=5)
    for tracker, lock_frame in ((strict, 4), (loose, 2)):
        states = [
            tracker.update(dets((50.0 + i, 80.0), score=sc), i, i / 30)[0]
            for i, sc in enumerate(scores)
        ]
        assert {st.track_id for st in states} == {1} and states[-1].hits == 5
        assert [st.just_locked for st in states].index(True) == lock_frame
    with pytest.raises(ValueError, match="lock_min_score"):
        Tracker(lock_min_score=1.5)


def test_hits_spread_wider_than_k_never_lock() -> None:
    tracker = Tracker(max_age=5, lock_m=3, lock_k=5)
    states = [
        tracker.update(dets((50.0, 80.0)) if i % 3 == 0 else Detections(), i, i / 30)
        for i in range(40)
    ]
    assert {s.track_id for frame in states for s in frame} == {1}
    assert states[-1][0].hits == 14
    assert not any(s.locked for frame in states for s in frame)


def test_camera_shift_input_keeps_ids_under_platform_shake() -> None:
    rng = np.random.default_rng(2)
    offsets = np.cumsum(rng.normal(0.0, 8.0, (50, 2)) + [3.0, 0.0], axis=0)  # pan + shake
    ground = [np.array([400.0 + 0.3 * i, 300.0]) for i in range(50)]
    frames = [
        dets(tuple(g + o + rng.normal(0, 1, 2))) for g, o in zip(ground, offsets, strict=True)
    ]
    shifts = [None] + [tuple(d) for d in np.diff(offsets, axis=0)]

    with_shift = run(Tracker(), frames, shifts)
    assert {s.track_id for frame in with_shift for s in frame} == {1}
    assert with_shift[-1][0].hits == 50
    assert np.allclose(with_shift[-1][0].velocity, (0.3, 0.0), atol=0.6)

    without = run(Tracker(), frames)
    assert len({s.track_id for frame in without for s in frame}) > 1


def test_class_vote_over_flickering_classes() -> None:
    classes = [0, 0, 1, 1, 1, 0]
    tracker = Tracker()
    states = [
        tracker.update(dets((70.0, 70.0), classes=[c]), i, i / 30)[0] for i, c in enumerate(classes)
    ]
    assert {s.track_id for s in states} == {1}  # class flicker does not split the track
    assert [s.class_id for s in states] == [0, 0, 0, 1, 1, 0]  # ties (frames 3, 5): latest wins


def test_reporting_history_and_frame_order() -> None:
    tracker = Tracker(min_hits_to_report=2, history_length=10, lock_m=3, lock_k=5)
    assert tracker.update(dets((10.0, 10.0), score=1.0), 0, 0.0) == []
    state = tracker.update(dets((10.0, 10.0), score=0.0), 1, 0.1)[0]
    assert state.score == pytest.approx(0.7) and state.hits == 2
    for i in range(2, 30):
        state = tracker.update(dets((10.0, 10.0)), i, i / 10)[0]
    assert len(state.history) == 10 and state.history[-1][:2] == (29, 2.9)
    np.testing.assert_allclose(state.raw_box, [7, 7, 13, 13])
    with pytest.raises(ValueError):
        tracker.update(Detections(), 29, 3.0)


def test_dropped_tracks_are_forgotten_and_new_ones_get_new_ids() -> None:
    tracker = Tracker()
    for i in range(4):
        (state,) = tracker.update(dets((100.0, 100.0)), i, i / 30)
    assert state.track_id == 1 and state.locked
    tracker.drop_tracks()
    assert tracker.update(dets(), 10, 10 / 30) == []
    (fresh,) = tracker.update(dets((100.0, 100.0)), 11, 11 / 30)
    assert fresh.track_id == 2 and fresh.hits == 1 and not fresh.locked
