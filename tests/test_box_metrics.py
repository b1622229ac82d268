"""AP / AR / F2 by size band and recall at NWD thresholds, on hand-computed cases."""

import json

import numpy as np
import pytest

from sarmission.boxes import centres_inside
from sarmission.evaluation.box_metrics import (
    evaluate_boxes,
    f_beta,
    interpolated_ap,
    recall_at_nwd,
)
from sarmission.evaluation.matching import FrameBoxes


def box(cx, cy, side):
    return [cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2]


def test_perfect_detections_score_one_in_every_band():
    gt = {
        1: FrameBoxes.of([box(50, 50, 6), box(200, 50, 12), box(400, 50, 24)], class_ids=[1, 1, 2]),
        2: FrameBoxes.of([box(80, 80, 10)], class_ids=[1]),
    }
    det = {
        k: FrameBoxes.of(v.boxes, scores=np.full(len(v), 0.9), class_ids=v.class_ids)
        for k, v in gt.items()
    }
    r = evaluate_boxes(gt, det)
    for name, band in r.bands.items():
        assert band.ap == pytest.approx(1.0), name
        assert band.ar == pytest.approx(1.0) and band.f2 == pytest.approx(1.0)
    assert (
        r.bands["extremely_tiny"].n_gt,
        r.bands["tiny"].n_gt,
        r.bands["small"].n_gt,
        r.bands["all"].n_gt,
    ) == (1, 2, 1, 4)
    json.dumps(r.to_dict())


def test_known_precision_recall_curve():
    # 2 GT, ranked detections TP (0.9), FP (0.8), TP (0.7):
    # recall 0.5, 0.5, 1.0; precision 1, 0.5, 2/3; interpolated precision 1 for r <= 0.5
    # (51 of the 101 recall levels) and 2/3 above (50 levels).
    gt = {0: FrameBoxes.of([box(20, 20, 8), box(100, 20, 8)])}
    det = {
        0: FrameBoxes.of(
            [box(20, 20, 8), box(300, 300, 8), box(100, 20, 8)], scores=[0.9, 0.8, 0.7]
        )
    }
    expected_ap = (51 * 1.0 + 50 * 2 / 3) / 101
    r = evaluate_boxes(gt, det, nwd_thresholds=[0.5], score_thr=0.5)
    band = r.bands["extremely_tiny"]  # 8x8 = 64 px^2, the upper edge of the band
    assert band.ap == pytest.approx(expected_ap)
    assert band.ar == pytest.approx(1.0)
    assert band.precision == pytest.approx(2 / 3) and band.recall == pytest.approx(1.0)
    assert band.f2 == pytest.approx(10 / 11)
    assert r.bands["tiny"].ap is None and r.bands["tiny"].n_gt == 0
    assert r.bands["all"].ap == pytest.approx(expected_ap)
    high = evaluate_boxes(gt, det, nwd_thresholds=[0.5], score_thr=0.75).bands["all"]
    assert high.precision == pytest.approx(0.5) and high.recall == pytest.approx(0.5)
    assert high.f2 == pytest.approx(0.5)


def test_interpolated_ap_direct():
    ap, ar = interpolated_ap(np.array([0.9, 0.8, 0.7]), np.array([True, False, True]), 4)
    # recall .25, .25, .5; precision 1, .5, 2/3 -> levels 0..0.25 (26) at 1, 0.26..0.5 (25)
    # at 2/3, the rest 0
    assert ap == pytest.approx((26 + 25 * 2 / 3) / 101)
    assert ar == pytest.approx(0.5)


def test_bands_populated_by_gt_area_and_detection_area():
    gt = {0: FrameBoxes.of([box(50, 50, 6), box(200, 50, 12), box(400, 50, 24)])}  # 36,144,576
    det = {
        0: FrameBoxes.of(
            [box(50, 50, 6), box(400, 50, 24), box(800, 800, 10), box(900, 900, 5)],
            scores=[0.9, 0.9, 0.8, 0.7],
        )
    }  # TP(ET), TP(small), FP area 100 (tiny), FP area 25 (ET)
    b = evaluate_boxes(gt, det, nwd_thresholds=[0.5]).bands
    assert [b[n].n_gt for n in ("extremely_tiny", "tiny", "small", "all")] == [1, 1, 1, 3]
    assert [b[n].n_detections for n in ("extremely_tiny", "tiny", "small", "all")] == [2, 1, 1, 4]
    assert b["extremely_tiny"].precision == pytest.approx(0.5)
    assert b["extremely_tiny"].recall == pytest.approx(1.0)
    assert b["tiny"].recall == 0.0 and b["tiny"].ap == 0.0
    assert b["small"].ap == pytest.approx(1.0) and b["small"].precision == pytest.approx(1.0)
    assert b["all"].precision == pytest.approx(0.5) and b["all"].recall == pytest.approx(2 / 3)


def test_detection_matched_to_other_band_is_ignored():
    # ET GT (7x7 = 49) found by a 9x9 box (81, tiny-sized; NWD = exp(-sqrt(2)/12.8) = 0.895);
    # tiny GT (12x12) found exactly. For the tiny band the 9x9 box is ignored, not a FP.
    gt = {0: FrameBoxes.of([box(50, 50, 7), box(300, 50, 12)])}
    det = {0: FrameBoxes.of([box(50, 50, 9), box(300, 50, 12)], scores=[0.95, 0.6])}
    b = evaluate_boxes(gt, det, nwd_thresholds=[0.5]).bands
    assert b["tiny"].ap == pytest.approx(1.0) and b["tiny"].precision == pytest.approx(1.0)
    assert b["extremely_tiny"].ap == pytest.approx(1.0)
    # at NWD 0.9 the 9x9 box no longer matches: FP in the tiny band (its own area), ranked first
    b = evaluate_boxes(gt, det, nwd_thresholds=[0.9]).bands
    assert b["extremely_tiny"].ar == 0.0
    assert b["tiny"].precision == pytest.approx(0.5)


def test_class_must_match_unless_agnostic():
    gt = {0: FrameBoxes.of([box(50, 50, 8)], class_ids=[1])}
    det = {0: FrameBoxes.of([box(50, 50, 8)], scores=[0.9], class_ids=[2])}
    assert evaluate_boxes(gt, det).bands["all"].ap == 0.0
    assert evaluate_boxes(gt, det, class_agnostic=True).bands["all"].ap == pytest.approx(1.0)


def test_f2_formula():
    assert f_beta(0.5, 1.0) == pytest.approx(5 * 0.5 / (4 * 0.5 + 1))
    assert f_beta(1.0, 0.5) == pytest.approx(5 * 0.5 / (4 + 0.5))
    assert f_beta(0.5, 1.0) > f_beta(1.0, 0.5)  # recall weighs more
    assert f_beta(0.0, 0.0) == 0.0
    assert f_beta(0.3, 0.6, beta=1.0) == pytest.approx(2 * 0.18 / 0.9)


def test_recall_at_nwd_thresholds():
    gt = {0: FrameBoxes.of([box(50, 50, 8), box(300, 50, 8)]), 1: FrameBoxes.of([box(9, 9, 8)])}
    # exact on the first; 20 px from the second (NWD exp(-20/12.8) = 0.21); none for image 1
    proposals = {0: FrameBoxes.of([box(50, 50, 8), box(320, 50, 8)], scores=[0.1, 0.2])}
    r = recall_at_nwd(gt, proposals, thresholds=(0.1, 0.5))
    assert r == {0.1: pytest.approx(2 / 3), 0.5: pytest.approx(1 / 3)}
    assert recall_at_nwd(gt, proposals, score_thr=0.15)[0.5] == 0.0
    # one proposal cannot recall two GT boxes
    one = {0: FrameBoxes.of([box(50, 50, 8)]), 1: FrameBoxes.of([box(50, 51, 8)])}
    gt_pair = {0: FrameBoxes.of([box(50, 50, 8), box(52, 50, 8)])}
    assert recall_at_nwd(gt_pair, one)[0.5] == pytest.approx(0.5)


def test_centres_inside_matches_a_small_box_on_part_of_a_large_one():
    small = np.array([box(10, 10, 4), box(50, 50, 4), box(20, 5, 2)])
    large = np.array([[0.0, 0.0, 20.0, 20.0], [45.0, 45.0, 46.0, 46.0]])
    inside = centres_inside(small, large)
    assert inside.shape == (3, 2)
    # the third's centre (20, 5) lies on the first box's edge: inside
    assert inside.tolist() == [[True, False], [False, False], [True, False]]
