"""Evaluation thresholds probed exactly at their boundaries, and the SSR denominator for
trajectories too short to lock.

A threshold checked a little on either side cannot tell ``>`` from ``>=``; here the pair sits
exactly on it: identical boxes have NWD exp(0) = 1.0 exactly, and a score of 0.5 is exact in
float32.
"""

import numpy as np

from sarmission.evaluation.matching import FrameBoxes, match_frame
from sarmission.evaluation.sar_metrics import SequenceFrame, evaluate_sar

BOX = [40.0, 40.0, 48.0, 48.0]


def test_nwd_equal_to_the_threshold_is_no_match():
    gt = FrameBoxes.of([BOX])
    det = FrameBoxes.of([BOX], scores=[0.9])
    on_threshold = match_frame(det, gt, nwd_thr=1.0)
    assert on_threshold.det_indices.size == 0
    assert on_threshold.unmatched_detections.tolist() == [0]
    assert on_threshold.unmatched_gt.tolist() == [0]
    just_below = match_frame(det, gt, nwd_thr=float(np.nextafter(1.0, 0.0)))
    assert just_below.det_indices.tolist() == [0] and just_below.gt_indices.tolist() == [0]


def test_score_equal_to_the_threshold_is_no_candidate():
    gt = FrameBoxes.of([BOX])
    at = match_frame(FrameBoxes.of([BOX], scores=[0.5]), gt, score_thr=0.5)
    assert at.n_candidates == 0 and at.det_indices.size == 0
    above = match_frame(
        FrameBoxes.of([BOX], scores=[0.5]),
        gt,
        score_thr=float(np.nextafter(np.float32(0.5), np.float32(0.0))),
    )
    assert above.n_candidates == 1 and above.det_indices.tolist() == [0]


def frame(index: int, gt_ids: list[int], hits: list[bool]) -> SequenceFrame:
    """GT boxes for ``gt_ids`` side by side; a detection on each one marked as hit."""
    gt_boxes = [[100.0 * i, 0.0, 100.0 * i + 8.0, 8.0] for i in range(len(gt_ids))]
    det_boxes = [b for b, hit in zip(gt_boxes, hits, strict=True) if hit]
    return SequenceFrame(
        index,
        FrameBoxes.of(gt_boxes, ids=gt_ids),
        FrameBoxes.of(det_boxes, scores=[0.9] * len(det_boxes)),
    )


def test_short_trajectories_count_in_the_success_rate_denominator():
    """Track 1 is hit in all 5 frames (locked at its third); track 2 appears in the last two
    frames only, hit in both, and can never reach m = 3: SSR = 1 / 2 = 50 %, not 100 %."""
    frames = [frame(i, [1], [True]) for i in range(3)]
    frames += [frame(i, [1, 2], [True, True]) for i in (3, 4)]
    r = evaluate_sar({"seq": frames}, m=3, k=5)
    assert r.n_trajectories == 2 and r.n_locked == 1 and r.n_lockable == 1
    assert r.search_success_rate == 50.0
    assert r.avg_search_time_frames == 2.0 and r.max_search_time_frames == 2
    short = next(t for t in r.trajectories if t.track_id == 2)
    assert (short.n_frames, short.n_hits, short.lock_frame) == (2, 2, None)


def test_a_trajectory_hit_exactly_m_times_in_k_frames_locks_on_its_mth_hit():
    """Hits at frames 0, 2, 4 of a 5-frame trajectory: 3 of 5, locked at frame 4; hits at
    0, 2, 5 span 6 frames: no window of 5 holds 3, not locked."""
    locked = [frame(i, [7], [i in (0, 2, 4)]) for i in range(6)]
    unlocked = [frame(i, [8], [i in (0, 2, 5)]) for i in range(6)]
    r = evaluate_sar({"a": locked, "b": unlocked}, m=3, k=5)
    by_seq = {t.sequence: t for t in r.trajectories}
    assert by_seq["a"].lock_frame == 4 and by_seq["a"].search_time == 4
    assert by_seq["b"].lock_frame is None
    assert r.search_success_rate == 50.0
