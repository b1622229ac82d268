"""Per-frame Hungarian NWD matching.

Boxes are 8x8 squares so only centre distance d matters: NWD = exp(-d / 12.8), and
NWD > 0.5 exactly when d < 12.8 * ln 2 = 8.87 px.
"""

import numpy as np
from conftest import FIXTURES_DIR

from sarmission.data import read_coco_video
from sarmission.evaluation.matching import FrameBoxes, ground_truth_by_image, match_frame

FIXTURE = FIXTURES_DIR / "seadronessee_sample.json"


def square(cx, cy=50.0, side=8.0):
    return [cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2]


def test_two_detections_near_one_gt_give_one_match():
    gt = FrameBoxes.of([square(50)])
    det = FrameBoxes.of([square(51), square(52)], scores=[0.9, 0.8])
    m = match_frame(det, gt)
    assert m.det_indices.tolist() == [0] and m.gt_indices.tolist() == [0]
    assert m.unmatched_detections.tolist() == [1]
    assert m.unmatched_gt.tolist() == []
    np.testing.assert_allclose(m.nwd, [np.exp(-1 / 12.8)])


def test_hungarian_beats_greedy():
    # GT A at x=0, B at x=8. det0 (score .9) is 3.5 from A, 4.5 from B; det1 is 5 from A, 13
    # from B (invalid). Greedy by score gives det0->A and leaves det1 unmatched; the optimal
    # one-to-one assignment is det0->B, det1->A.
    gt = FrameBoxes.of([square(0), square(8)])
    det = FrameBoxes.of([square(3.5), square(-5)], scores=[0.9, 0.8])
    m = match_frame(det, gt)
    pairs = sorted(zip(m.det_indices.tolist(), m.gt_indices.tolist(), strict=True))
    assert pairs == [(0, 1), (1, 0)]
    assert m.unmatched_detections.size == 0 and m.unmatched_gt.size == 0


def test_score_threshold_is_strict_and_low_scores_are_not_false_alarms():
    gt = FrameBoxes.of([square(50)])
    det = FrameBoxes.of([square(50), square(200)], scores=[0.5, 0.4])
    m = match_frame(det, gt)
    assert m.det_indices.size == 0 and m.n_candidates == 0
    assert m.unmatched_detections.size == 0
    assert m.unmatched_gt.tolist() == [0]


def test_nwd_threshold_respected():
    gt = FrameBoxes.of([square(50)])
    near = match_frame(FrameBoxes.of([square(50 + 8.8)], scores=[0.9]), gt)  # NWD 0.5027
    far = match_frame(FrameBoxes.of([square(50 + 8.9)], scores=[0.9]), gt)  # NWD 0.4989
    assert near.det_indices.tolist() == [0]
    assert far.det_indices.size == 0 and far.unmatched_detections.tolist() == [0]
    custom = match_frame(FrameBoxes.of([square(55)], scores=[0.9]), gt, nwd_thr=0.7)
    assert custom.det_indices.size == 0  # NWD exp(-5/12.8) = 0.677


def test_empty_inputs():
    gt = FrameBoxes.of([square(50)])
    m = match_frame(FrameBoxes.empty(), gt)
    assert m.unmatched_gt.tolist() == [0] and m.unmatched_detections.size == 0
    m = match_frame(FrameBoxes.of([square(5)], scores=[0.9]), FrameBoxes.empty())
    assert m.unmatched_detections.tolist() == [0]


def test_frameboxes_validates_shapes():
    import pytest

    with pytest.raises(ValueError):
        FrameBoxes.of([square(1), square(2)], scores=[0.5])


def test_ground_truth_from_dataset():
    gt = ground_truth_by_image(read_coco_video(FIXTURE))
    assert set(gt) == {10, 11, 20, 21}
    assert len(gt[20]) == 0
    np.testing.assert_allclose(gt[11].boxes, [[102, 201, 114, 211], [500.5, 600.25, 506.5, 605.25]])
    assert gt[11].ids.tolist() == [1, 2] and gt[11].class_ids.tolist() == [1, 2]
    only_swimmers = ground_truth_by_image(read_coco_video(FIXTURE), category_ids=[1])
    assert len(only_swimmers[11]) == 1


def test_ground_truth_is_clipped_to_its_image_and_empty_boxes_are_not_scored(caplog):
    """A raw file's box over the image edge turned the detection of what is visible into a
    false one; a box outside the image (or of no width) counted as a missed target."""
    from sarmission.data.coco_video import Annotation, Category, ImageRecord, VideoDataset

    dataset = VideoDataset(
        videos=[],
        images=[ImageRecord(id=1, file_name="a.jpg", height=50, width=100)],
        annotations=[
            Annotation(id=1, image_id=1, category_id=1, bbox=(94.0, 10.0, 12.0, 8.0)),  # over
            Annotation(id=2, image_id=1, category_id=1, bbox=(120.0, 10.0, 5.0, 5.0)),  # out
            Annotation(id=3, image_id=1, category_id=1, bbox=(20.0, 10.0, 0.0, 5.0)),  # empty
            Annotation(id=4, image_id=1, category_id=1, bbox=(40.0, 20.0, 8.0, 8.0)),
        ],
        categories=[Category(1, "swimmer")],
    )
    gt = ground_truth_by_image(dataset)[1]
    assert gt.boxes.tolist() == [[94.0, 10.0, 100.0, 18.0], [40.0, 20.0, 48.0, 28.0]]
    assert "2 ground-truth boxes lie outside their image" in caplog.text
    visible = FrameBoxes.of(np.array([[94.0, 10.0, 100.0, 18.0]]), scores=[0.9])
    assert match_frame(visible, gt, 0.5).det_indices.tolist() == [0]
