"""The MITE-Net cascade on a small synthetic clip."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import torch
from conftest import render_narrow_sea
from motion_scenes import moving_target, to_bgr

from sarmission.perception.crops import motion_enhanced_crops
from sarmission.perception.export import head_onnx_bytes
from sarmission.perception.extent import fit_boxes
from sarmission.perception.head import MiteHead, head_flops_per_proposal, ltrb_to_boxes
from sarmission.perception.mitenet import (
    FIT_MAX_PER_FRAME,
    FIT_MAX_SIDE_S,
    FIT_MIN_SCORE,
    RECENTRE_MIN_SCORE,
    RECENTRE_MIN_SHIFT_PX,
    MiteNet,
    build_head_runtime,
    nms_xyxy,
    scaled_boxes,
)
from sarmission.perception.runtime import OnnxHeadRuntime, TorchHeadRuntime

H, W = 120, 160


def _clip(frames: int = 10) -> tuple[list[np.ndarray], np.ndarray]:
    """Textured background and a 6 px bright disc moving at (2, 1) px/frame: BGR frames and the
    target centres (full-resolution pixels)."""
    images, centres = moving_target(
        H, W, frames, start=(40.0, 50.0), velocity=(2.0, 1.0), size=6.0, shape="disc", seed=7
    )
    return [to_bgr(im) for im in images], centres


@pytest.fixture(scope="module")
def head() -> MiteHead:
    torch.manual_seed(0)
    return MiteHead().eval()


def _run(net: MiteNet, frames: list[np.ndarray]):
    return [net.process(f, i / 30.0) for i, f in enumerate(frames)]


def test_proposals_find_the_moving_target(head: MiteHead):
    frames, centres = _clip()
    net = MiteNet(TorchHeadRuntime(head), ds=2, topn=5)
    results = _run(net, frames)
    for result, (cx, cy) in zip(results[4:], centres[4:], strict=True):
        boxes = result.proposals.boxes
        inside = (
            (boxes[:, 0] <= cx) & (cx <= boxes[:, 2]) & (boxes[:, 1] <= cy) & (cy <= boxes[:, 3])
        )
        assert inside.any(), (result.timestamp, boxes, (cx, cy))
    assert set(net.per_stage_ms) == {"vstmd", "colour", "rpn", "crops", "head", "fit"}
    assert all(v >= 0 for v in net.per_stage_ms.values())
    assert results[0].motion.response.shape == (H // 2, W // 2)


def test_replay_after_reset_is_identical(head: MiteHead):
    frames, _ = _clip()
    net = MiteNet(TorchHeadRuntime(head), ds=2, topn=8, score_threshold=0.0)
    first = [(r.proposals.boxes.copy(), r.detections) for r in _run(net, frames)]
    net.reset()
    second = [(r.proposals.boxes.copy(), r.detections) for r in _run(net, frames)]
    assert sum(len(d) for _, d in first) > 0
    for (pa, da), (pb, db) in zip(first, second, strict=True):
        np.testing.assert_array_equal(pa, pb)
        np.testing.assert_array_equal(da.boxes, db.boxes)
        np.testing.assert_array_equal(da.scores, db.scores)
        np.testing.assert_array_equal(da.class_ids, db.class_ids)


def test_torch_and_onnx_give_the_same_detections(head: MiteHead):
    frames, _ = _clip(8)
    nets = [
        MiteNet(TorchHeadRuntime(head), topn=8, score_threshold=0.0),
        MiteNet(
            OnnxHeadRuntime(head_onnx_bytes(head), intra_op_threads=1), topn=8, score_threshold=0.0
        ),
    ]
    a, b = (_run(n, frames) for n in nets)
    assert sum(len(r.detections) for r in a) > 0
    for ra, rb in zip(a, b, strict=True):
        assert len(ra.detections) == len(rb.detections)
        np.testing.assert_allclose(ra.detections.boxes, rb.detections.boxes, atol=1e-3)
        np.testing.assert_allclose(ra.detections.scores, rb.detections.scores, atol=1e-4)
        np.testing.assert_array_equal(ra.detections.class_ids, rb.detections.class_ids)


def test_score_threshold_and_detection_format(head: MiteHead):
    frames, _ = _clip(6)
    net = MiteNet(TorchHeadRuntime(head), topn=8, score_threshold=1.0)
    assert all(len(r.detections) == 0 for r in _run(net, frames))
    net = MiteNet(TorchHeadRuntime(head), topn=8, score_threshold=0.0, nms_iou=None)
    last = _run(net, frames)[-1]
    assert len(last.detections) == len(last.proposals)
    d = last.detections
    assert d.boxes.dtype == np.float32 and d.class_ids.dtype == np.int64
    assert np.all(d.boxes[:, 2] > d.boxes[:, 0]) and np.all(d.boxes[:, 3] > d.boxes[:, 1])
    assert np.all((d.scores >= 0) & (d.scores <= 1))


def test_frame_validation(head: MiteHead):
    net = MiteNet(TorchHeadRuntime(head))
    good = np.zeros((32, 48, 3), np.uint8)
    with pytest.raises(ValueError, match="uint8"):
        net.process(good.astype(np.float32), 0.0)
    with pytest.raises(ValueError, match=r"\[H, W, 3\]"):
        net.process(np.zeros((32, 48), np.uint8), 0.0)
    with pytest.raises(ValueError, match=r"\[H, W, 3\]"):
        net.process(np.zeros((32, 48, 4), np.uint8), 0.0)
    net.process(good, 0.0)
    with pytest.raises(ValueError, match="changed mid-stream"):
        net.process(np.zeros((40, 48, 3), np.uint8), 0.1)
    net.reset()
    net.process(np.zeros((40, 48, 3), np.uint8), 0.2)
    with pytest.raises(ValueError, match="classes"):
        MiteNet(TorchHeadRuntime(head), classes=("person",))


def test_complexity(head: MiteHead):
    net = MiteNet(TorchHeadRuntime(head), ds=2, topn=25)
    report = net.complexity(2160, 3840)
    flops = report["flops"]
    assert flops["vstmd"] == net.vstmd.flops(2160, 3840)
    assert flops["head"] == 25 * head_flops_per_proposal(head)  # the default single crop
    # A second crop scale may refine every proposal: the head's FLOPs are that bound.
    two = MiteNet(TorchHeadRuntime(head), ds=2, topn=25, crop_scales=(1.0, 2.0))
    assert two.complexity(2160, 3840)["flops"]["head"] == 2 * 25 * head_flops_per_proposal(head)
    assert flops["rpn_other"] > net.rpn.flops(1080, 1920)
    assert flops["total"] == flops["vstmd"] + flops["rpn_other"] + flops["head"]
    assert report["parameters"]["head"] < 140_000


def test_nms_drops_overlapping_lower_scores():
    boxes = np.array([[0, 0, 10, 10], [1, 1, 11, 11], [20, 20, 30, 30]], np.float32)
    keep = nms_xyxy(boxes, np.array([0.5, 0.9, 0.3]), 0.5)
    np.testing.assert_array_equal(keep, [1, 2])


def _greedy_nms_reference(boxes: np.ndarray, scores: np.ndarray, threshold: float) -> list[int]:
    """Textbook greedy NMS, one box at a time in pure Python."""

    def iou(a, b):
        iw = max(min(a[2], b[2]) - max(a[0], b[0]), 0.0)
        ih = max(min(a[3], b[3]) - max(a[1], b[1]), 0.0)
        union = (
            max(a[2] - a[0], 0.0) * max(a[3] - a[1], 0.0)
            + max(b[2] - b[0], 0.0) * max(b[3] - b[1], 0.0)
            - iw * ih
        )
        return iw * ih / max(union, 1e-9)

    remaining = sorted(range(len(scores)), key=lambda i: (-scores[i], i))
    keep = []
    while remaining:
        best = remaining.pop(0)
        keep.append(best)
        remaining = [i for i in remaining if iou(boxes[best], boxes[i]) <= threshold]
    return keep


def test_nms_matches_textbook_greedy_suppression_with_ties_and_empty_boxes():
    rng = np.random.default_rng(7)
    assert nms_xyxy(np.zeros((0, 4)), np.zeros(0), 0.5).size == 0
    for trial in range(200):
        n = int(rng.integers(1, 40))
        corner = rng.uniform(0, 60, (n, 2))
        boxes = np.concatenate([corner, corner + rng.uniform(-2, 25, (n, 2))], axis=1)
        scores = rng.choice([0.2, 0.5, 0.9], n) if trial % 2 else rng.random(n)
        threshold = float(rng.choice([0.0, 0.3, 0.5, 0.7]))
        assert nms_xyxy(boxes, scores, threshold).tolist() == _greedy_nms_reference(
            boxes.tolist(), scores.tolist(), threshold
        )


def test_colour_proposals_find_a_target_that_does_not_move(head: MiteHead):
    """A still orange patch on tinted water next to the moving disc: only the colour proposals
    reach it; with colour_share 0 (the paper's motion-only RPN) none does."""
    frames, _ = _clip(8)
    still = (110, 35)  # centre (x, y), well away from the disc's path
    tinted = []
    for frame in frames:
        f = (frame.astype(np.float32) * np.array([0.95, 0.75, 0.4], np.float32)).astype(np.uint8)
        f[still[1] - 5 : still[1] + 5, still[0] - 5 : still[0] + 5] = (20, 110, 240)
        tinted.append(f)

    def reaches(result) -> bool:
        b = result.proposals.boxes
        return bool(
            np.any(
                (b[:, 0] <= still[0])
                & (still[0] <= b[:, 2])
                & (b[:, 1] <= still[1])
                & (still[1] <= b[:, 3])
            )
        )

    with_colour = _run(MiteNet(TorchHeadRuntime(head), ds=2, topn=5, colour_share=0.4), tinted)
    motion_only = _run(MiteNet(TorchHeadRuntime(head), ds=2, topn=5, colour_share=0.0), tinted)
    assert all(reaches(r) for r in with_colour[4:])
    assert not any(reaches(r) for r in motion_only[4:])
    assert all(r.proposals.from_colour.any() for r in with_colour[4:])
    net = MiteNet(TorchHeadRuntime(head), ds=2, topn=25)
    colour_flops = net.complexity(2160, 3840)["flops"]["rpn_other"]
    no_colour = MiteNet(TorchHeadRuntime(head), ds=2, topn=25, colour_share=0.0)
    assert colour_flops > no_colour.complexity(2160, 3840)["flops"]["rpn_other"]


def _crop_scores(net: MiteNet, frame: np.ndarray, result, scale: float):
    """Best-class probability and decoded box of every proposal's crop at ``scale``."""
    boxes = scaled_boxes(result.proposals.boxes, scale)
    return _box_scores(net, frame, result, boxes, result.proposals.polarity)


def _box_scores(net: MiteNet, frame: np.ndarray, result, boxes: np.ndarray, polarity):
    """Best-class probability and decoded box of the crops of ``boxes`` (one bilinear sample
    per bin, as MiteNet cuts them)."""
    logits, ltrb = net.head.predict(
        motion_enhanced_crops(frame, result.motion, boxes, polarity, sampling_ratio=1)
    )
    probs = 1.0 / (1.0 + np.exp(-logits.astype(np.float64)))
    return probs.max(axis=1), ltrb_to_boxes(ltrb, boxes, 16)


@pytest.fixture(scope="module")
def sea_frames(tmp_path_factory: pytest.TempPathFactory) -> list[np.ndarray]:
    """Twelve 960x540 frames of the simulator's narrow-view maritime scene (swimmers of 8-30
    px, boats, foam)."""
    folder = render_narrow_sea(tmp_path_factory.mktemp("sea"), frames=12)
    return [cv2.imread(str(path)) for path in sorted(folder.glob("*.jpg"))]


def test_second_crop_scale_refines_the_proposals_that_score_enough(sea_frames):
    """Scales (1, 2), shipped head, sea frames: every proposal is scored on its box; those at or
    above refine_threshold are scored again on the box doubled about its centre, and the wide
    crop replaces the first when it scores higher and boxes the target at least as large as the
    first crop (S); the others keep their first crop's score and box."""
    shipped = build_head_runtime(None, "onnx")
    options = {"ds": 2, "topn": 25, "score_threshold": 0.0, "nms_iou": None, "fit_boxes": False}
    threshold = 0.5
    single = MiteNet(shipped, crop_scales=(1.0,), **options)
    firsts, wides = [], []
    for i, frame in enumerate(sea_frames):
        result = single.process(frame, i / 30.0)  # its motion maps live two calls only
        if i < 3:
            continue
        firsts.append(_crop_scores(single, frame, result, 1.0))
        wides.append(_crop_scores(single, frame, result, 2.0))
        np.testing.assert_allclose(result.detections.scores, firsts[-1][0], atol=1e-5)
    net = MiteNet(shipped, crop_scales=(1.0, 2.0), refine_threshold=threshold, **options)
    every = MiteNet(shipped, crop_scales=(1.0, 2.0), refine_threshold=0.0, **options)
    outcomes = set()
    for result, best, (first_scores, first_boxes), (wide_scores, wide_boxes) in zip(
        _run(net, sea_frames)[3:], _run(every, sea_frames)[3:], firsts, wides, strict=True
    ):
        side = np.maximum(wide_boxes[:, 2] - wide_boxes[:, 0], wide_boxes[:, 3] - wide_boxes[:, 1])
        higher, larger = wide_scores > first_scores, side >= net.box_size
        refined = first_scores >= threshold
        wide_wins = refined & higher & larger
        outcomes |= set(zip(refined.tolist(), higher.tolist(), larger.tolist(), strict=True))
        np.testing.assert_allclose(
            result.detections.scores, np.where(wide_wins, wide_scores, first_scores), atol=1e-5
        )
        np.testing.assert_allclose(
            result.detections.boxes,
            np.where(wide_wins[:, None], wide_boxes, first_boxes),
            atol=1e-3,
        )
        np.testing.assert_allclose(
            best.detections.scores, np.where(higher & larger, wide_scores, first_scores), atol=1e-5
        )
    # (refined, wide crop scored higher, wide box >= S): the cases the rule tells apart occurred.
    assert {
        (True, True, True),
        (True, True, False),
        (True, False, True),
        (False, True, True),
    } <= outcomes, outcomes
    head = MiteHead()
    one, two = (
        MiteNet(TorchHeadRuntime(head), crop_scales=scales).complexity(2160, 3840)["flops"]["head"]
        for scales in ((1.0,), (1.0, 2.0))
    )
    assert two == 2 * one  # the most the refinement can cost: every proposal refined
    for bad in ({"crop_scales": (1.0, 0.0)}, {"crop_scales": ()}):
        with pytest.raises(ValueError, match="crop_scales"):
            MiteNet(TorchHeadRuntime(head), **bad)
    with pytest.raises(ValueError, match="refine_threshold"):
        MiteNet(TorchHeadRuntime(head), refine_threshold=1.5)


def test_fitted_boxes_are_the_heads_fitted_to_the_object(sea_frames):
    """fit_boxes=True changes boxes alone: each of the FIT_MAX_PER_FRAME best scored at least
    FIT_MIN_SCORE is the head's box passed through fit_boxes with the 4 S cap, the others are
    the head's, and scores and classes are the head's."""
    shipped = build_head_runtime(None, "onnx")
    options = {"ds": 2, "topn": 25, "score_threshold": 0.0}
    heads = _run(MiteNet(shipped, fit_boxes=False, **options), sea_frames)
    fitted = _run(MiteNet(shipped, **options), sea_frames)
    replaced = unsure = 0
    for frame, plain, fit in zip(sea_frames, heads, fitted, strict=True):
        np.testing.assert_array_equal(fit.detections.scores, plain.detections.scores)
        np.testing.assert_array_equal(fit.detections.class_ids, plain.detections.class_ids)
        sure = plain.detections.scores >= FIT_MIN_SCORE
        order = np.argsort(-plain.detections.scores, kind="stable")
        sure[order[FIT_MAX_PER_FRAME:]] = False  # only the best-scored are fitted
        expected, count = fit_boxes(frame, plain.detections.boxes[sure], FIT_MAX_SIDE_S * 16.0)
        np.testing.assert_array_equal(fit.detections.boxes[sure], expected)
        np.testing.assert_array_equal(fit.detections.boxes[~sure], plain.detections.boxes[~sure])
        replaced += count
        unsure += int((~sure).sum())
    assert replaced > 0 and unsure > 0


def test_recentring_classifies_again_where_the_head_put_the_target(sea_frames):
    """recentre=True, shipped head, sea frames: a proposal whose first crop scores at least
    RECENTRE_MIN_SCORE and whose decoded box centre lies RECENTRE_MIN_SHIFT_PX or more from the
    crop's centre is cropped again (S x S) around that centre, and that crop's score and box
    replace the first's; every other proposal keeps its first crop's."""
    shipped = build_head_runtime(None, "onnx")
    options = {"ds": 2, "topn": 25, "score_threshold": 0.0, "nms_iou": None, "fit_boxes": False}
    single = MiteNet(shipped, **options)
    expected = []
    cases = set()
    for i, frame in enumerate(sea_frames):
        result = single.process(frame, i / 30.0)
        if i < 3:
            continue
        scores, boxes = _crop_scores(single, frame, result, 1.0)
        shift = (boxes[:, :2] + boxes[:, 2:]) / 2 - (
            result.proposals.boxes[:, :2] + result.proposals.boxes[:, 2:]
        ) / 2
        far = np.hypot(shift[:, 0], shift[:, 1]) >= RECENTRE_MIN_SHIFT_PX
        sure = scores >= RECENTRE_MIN_SCORE
        moved = np.flatnonzero(far & sure)
        again = result.proposals.boxes[moved] + np.tile(shift[moved], 2)
        polarity = result.proposals.polarity[moved]
        again_scores, again_boxes = _box_scores(single, frame, result, again, polarity)
        scores[moved], boxes[moved] = again_scores, again_boxes
        expected.append((scores, boxes))
        cases |= set(zip(far.tolist(), sure.tolist(), strict=True))
    net = MiteNet(shipped, recentre=True, **options)
    for result, (scores, boxes) in zip(_run(net, sea_frames)[3:], expected, strict=True):
        np.testing.assert_allclose(result.detections.scores, scores, atol=1e-5)
        np.testing.assert_allclose(result.detections.boxes, boxes, atol=1e-3)
    # (centre off by the shift or more, first score high enough): every case occurred.
    assert cases == {(True, True), (True, False), (False, True), (False, False)}, cases
    head = MiteHead()
    plain, again = (
        MiteNet(TorchHeadRuntime(head), recentre=flag).complexity(2160, 3840)["flops"]["head"]
        for flag in (False, True)
    )
    assert again == 2 * plain  # the most it can cost: every proposal cropped again


def test_scaled_boxes_keep_the_centre():
    boxes = np.array([[10.0, 20.0, 26.0, 36.0], [0.0, 0.0, 4.0, 8.0]], np.float32)
    np.testing.assert_allclose(
        scaled_boxes(boxes, 2.0), [[2.0, 12.0, 34.0, 44.0], [-2.0, -4.0, 6.0, 12.0]]
    )


def test_frame_result_carries_the_camera_shift(head: MiteHead):
    """The shift the motion front-end compensated comes with each frame's result: none on the
    first frame, the given one when the caller knows it, the scene's own motion otherwise."""
    frames, _ = _clip(4)
    net = MiteNet(TorchHeadRuntime(head), ds=2, topn=5)
    assert net.process(frames[0], 0.0).camera_shift == (0.0, 0.0)
    assert net.process(frames[1], 1 / 30, shift_px=(3.0, -1.5)).camera_shift == (3.0, -1.5)
    panned = np.roll(frames[1], (2, 6), axis=(0, 1))  # the whole scene 6 px right, 2 px down
    shift = net.process(panned, 2 / 30).camera_shift
    np.testing.assert_allclose(shift, (6.0, 2.0), atol=0.5)


def test_a_detector_that_fits_boxes_builds_the_extents_tables_when_it_is_made(monkeypatch):
    from sarmission.perception import extent

    prepared = []
    monkeypatch.setattr(extent, "prepare", lambda: prepared.append(True))
    head = build_head_runtime(None, "onnx")
    MiteNet(head, fit_boxes=False)
    assert prepared == []
    MiteNet(head, fit_boxes=True)
    assert prepared == [True]


def test_preparing_the_extent_changes_no_measurement():
    from sarmission.perception import extent

    rng = np.random.default_rng(4)
    image = rng.integers(60, 70, (200, 200, 3), dtype=np.uint8)
    image[90:110, 80:130] = (20, 120, 240)
    before = extent.object_extent(image, (95, 92, 111, 108))
    extent.prepare()
    np.testing.assert_array_equal(extent.object_extent(image, (95, 92, 111, 108)), before)
    assert before is not None and before[2] - before[0] == pytest.approx(50, abs=2)
