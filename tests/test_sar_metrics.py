"""SSR, search time and false alarm rates on hand-made sequences."""

import json

import pytest
from conftest import FIXTURES_DIR

from sarmission.data import read_coco_video
from sarmission.evaluation.matching import FrameBoxes
from sarmission.evaluation.sar_metrics import (
    DEFINITIONS,
    SequenceFrame,
    evaluate_sar,
    sequences_from_dataset,
)

FIXTURE = FIXTURES_DIR / "seadronessee_sample.json"
X1, X2 = 50.0, 200.0  # track 1 and track 2 positions


def box(cx, cy=50.0, side=8.0):
    return [cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2]


def frame(index, gt, dets):
    """gt: [(track_id, cx)], dets: [(cx, score)]."""
    return SequenceFrame(
        index,
        FrameBoxes.of([box(x) for _, x in gt], ids=[t for t, _ in gt]),
        FrameBoxes.of([box(x) for x, _ in dets], scores=[s for _, s in dets]),
    )


def sequences():
    # Video "v", frames 0..8. Track 1 annotated 0..7, hit at 0, 2, 3, 7 -> locked at frame 3
    # (hits 0, 2, 3 inside window 0..4), search time 3. Track 2 annotated 2..7, hit at 2 and 5
    # only -> never 3 hits in 5 frames, not locked. False alarms: 1 at frame 1, 2 at frame 4,
    # 1 at frame 8 (a frame without GT); the 0.3-score box at frame 6 is below threshold.
    hits1, hits2 = {0, 2, 3, 7}, {2, 5}
    fps = {1: [(400.0, 0.9)], 4: [(400.0, 0.9), (600.0, 0.7)], 6: [(700.0, 0.3)]}
    v = []
    for i in range(8):
        gt = [(1, X1)] + ([(2, X2)] if i >= 2 else [])
        dets = [(X1 + 1, 0.9)] * (i in hits1) + [(X2 - 1, 0.8)] * (i in hits2) + fps.get(i, [])
        v.append(frame(i, gt, dets))
    v.append(frame(8, [], [(900.0, 0.95)]))
    # Video "w": track 1 (a different trajectory from v's track 1) annotated at frames 10, 11
    # and 15 only, hit in all three: its own annotated frames are consecutive, so it locks at
    # frame 15 and the search time is 15 - 10 = 5. Frames given out of order on purpose.
    w = [
        frame(15, [(1, X1)], [(X1, 0.9)]),
        frame(10, [(1, X1)], [(X1, 0.9)]),
        frame(11, [(1, X1)], [(X1, 0.9)]),
    ]
    return {"v": v, "w": w}


def test_hand_made_sequences():
    r = evaluate_sar(sequences(), m=3, k=5)
    assert r.n_trajectories == 3 and r.n_locked == 2 and r.n_lockable == 3
    assert r.search_success_rate == pytest.approx(200 / 3)
    by_key = {(t.sequence, t.track_id): t for t in r.trajectories}
    assert by_key["v", 1].lock_frame == 3 and by_key["v", 1].search_time == 3
    assert by_key["v", 2].lock_frame is None and by_key["v", 2].n_hits == 2
    assert by_key["v", 2].n_frames == 6 and by_key["v", 2].first_frame == 2
    assert by_key["w", 1].lock_frame == 15 and by_key["w", 1].search_time == 5
    assert r.avg_search_time_frames == pytest.approx(4.0)
    assert r.max_search_time_frames == 5
    # 12 frames; candidates: 6 TP in v + 3 in w + 4 FP = 13
    assert (r.n_frames, r.n_matched, r.n_false_alarms, r.n_detections) == (12, 9, 4, 13)
    assert r.false_alarm_rate_per_frame == pytest.approx(100 * 4 / 12)
    assert r.false_alarm_rate_detections == pytest.approx(100 * 4 / 13)


def test_stricter_lock_changes_ssr():
    r = evaluate_sar(sequences(), m=4, k=5)
    assert r.n_locked == 0 and r.search_success_rate == 0.0
    assert r.n_lockable == 2  # w's track is annotated in 3 frames only: never 4 hits
    assert r.avg_search_time_frames is None and r.max_search_time_frames is None


def test_to_dict_is_json_and_has_definitions():
    d = evaluate_sar(sequences()).to_dict()
    json.dumps(d)
    assert d["definitions"] == DEFINITIONS
    assert {"false_alarm_rate_per_frame", "false_alarm_rate_detections"} <= set(d["definitions"])
    assert len(d["trajectories"]) == 3


def test_empty_input():
    r = evaluate_sar({})
    assert r.search_success_rate is None and r.false_alarm_rate_per_frame is None
    assert r.false_alarm_rate_detections == 0.0


def test_sequences_from_dataset():
    ds = read_coco_video(FIXTURE)
    seqs = sequences_from_dataset(ds, {11: FrameBoxes.of([[102, 201, 114, 211]], scores=[0.9])})
    assert sorted(seqs) == ["DJI_0001", "DJI_0002"]
    assert [f.frame_index for f in seqs["DJI_0001"]] == [0, 1]
    r = evaluate_sar(seqs, m=1, k=1)
    # trajectories: (DJI_0001, 1), (DJI_0001, 2), (DJI_0002, 7); only track 1 hit at frame 1
    assert r.n_trajectories == 3 and r.n_locked == 1
    assert r.trajectories[0].search_time == 1
