"""The MITE-Net cascade on a small synthetic clip."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from motion_scenes import moving_target, to_bgr

from sarmission.perception.crops import motion_enhanced_crops
from sarmission.perception.export import head_onnx_bytes
from sarmission.perception.head import MiteHead, head_flops_per_proposal
from sarmission.perception.mitenet import MiteNet, nms_xyxy
from sarmission.perception.runtime import OnnxHeadRuntime, TorchHeadRuntime

H, W = 120, 160


def _clip(frames: int = 10) -> tuple[list[np.ndarray], np.ndarray]:
    """Textured background and a 6 px bright disc moving at (2, 1) px/frame: BGR frames and the
    target centres (full-resolution pixels)."""
    images, centres = moving_target(H, W, frames, start=(40.0, 50.0), velocity=(2.0, 1.0),
                                    size=6.0, shape="disc", seed=7)
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
        inside = ((boxes[:, 0] <= cx) & (cx <= boxes[:, 2])
                  & (boxes[:, 1] <= cy) & (cy <= boxes[:, 3]))
        assert inside.any(), (result.timestamp, boxes, (cx, cy))
    assert set(net.per_stage_ms) == {"vstmd", "colour", "rpn", "crops", "head"}
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
    nets = [MiteNet(TorchHeadRuntime(head), topn=8, score_threshold=0.0),
            MiteNet(OnnxHeadRuntime(head_onnx_bytes(head), intra_op_threads=1), topn=8,
                    score_threshold=0.0)]
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
    assert flops["head"] == 25 * head_flops_per_proposal(head)
    assert flops["rpn_other"] > net.rpn.flops(1080, 1920)
    assert flops["total"] == flops["vstmd"] + flops["rpn_other"] + flops["head"]
    assert report["parameters"]["head"] < 140_000


def test_nms_drops_overlapping_lower_scores():
    boxes = np.array([[0, 0, 10, 10], [1, 1, 11, 11], [20, 20, 30, 30]], np.float32)
    keep = nms_xyxy(boxes, np.array([0.5, 0.9, 0.3]), 0.5)
    np.testing.assert_array_equal(keep, [1, 2])


def test_colour_proposals_find_a_target_that_does_not_move(head: MiteHead):
    """A still orange patch on tinted water next to the moving disc: only the colour proposals
    reach it; with colour_share 0 (the paper's motion-only RPN) none does."""
    frames, _ = _clip(8)
    still = (110, 35)  # centre (x, y), well away from the disc's path
    tinted = []
    for frame in frames:
        f = (frame.astype(np.float32) * np.array([0.95, 0.75, 0.4], np.float32)).astype(np.uint8)
        f[still[1] - 5:still[1] + 5, still[0] - 5:still[0] + 5] = (20, 110, 240)
        tinted.append(f)

    def reaches(result) -> bool:
        b = result.proposals.boxes
        return bool(np.any((b[:, 0] <= still[0]) & (still[0] <= b[:, 2])
                           & (b[:, 1] <= still[1]) & (still[1] <= b[:, 3])))

    with_colour = _run(MiteNet(TorchHeadRuntime(head), ds=2, topn=5, colour_share=0.4), tinted)
    motion_only = _run(MiteNet(TorchHeadRuntime(head), ds=2, topn=5, colour_share=0.0), tinted)
    assert all(reaches(r) for r in with_colour[4:])
    assert not any(reaches(r) for r in motion_only[4:])
    assert all(r.proposals.from_colour.any() for r in with_colour[4:])
    net = MiteNet(TorchHeadRuntime(head), ds=2, topn=25)
    colour_flops = net.complexity(2160, 3840)["flops"]["rpn_other"]
    no_colour = MiteNet(TorchHeadRuntime(head), ds=2, topn=25, colour_share=0.0)
    assert colour_flops > no_colour.complexity(2160, 3840)["flops"]["rpn_other"]


def test_crop_scales_cut_every_proposal_at_each_scale(head: MiteHead):
    """Scales (1, 2): the head sees each proposal box and its double around the same centre,
    each proposal keeps the detection of its higher-scored crop, and the head's FLOPs double."""
    frames, _ = _clip(8)
    single = MiteNet(TorchHeadRuntime(head), ds=2, topn=5, score_threshold=0.0, nms_iou=None)
    double = MiteNet(TorchHeadRuntime(head), ds=2, topn=5, score_threshold=0.0, nms_iou=None,
                     crop_scales=(1.0, 2.0))
    last_single, last_double = _run(single, frames)[-1], _run(double, frames)[-1]
    n = len(last_double.proposals)
    np.testing.assert_array_equal(last_single.proposals.boxes, last_double.proposals.boxes)
    assert len(last_double.detections) == n
    boxes, _ = double._scaled_boxes(last_double.proposals)
    logits, _ = double.head.predict(motion_enhanced_crops(
        frames[-1], last_double.motion, boxes, np.tile(last_double.proposals.polarity, 2)))
    probs = 1.0 / (1.0 + np.exp(-logits.astype(np.float64)))
    best = probs.max(axis=1).reshape(2, n).max(axis=0)
    np.testing.assert_allclose(last_double.detections.scores, best, atol=1e-5)
    assert np.all(last_double.detections.scores >= last_single.detections.scores - 1e-4)
    boxes, polarity = double._scaled_boxes(last_double.proposals)
    p = last_double.proposals.boxes
    np.testing.assert_allclose((boxes[n:, :2] + boxes[n:, 2:]) / 2, (p[:, :2] + p[:, 2:]) / 2)
    np.testing.assert_allclose(boxes[n:, 2] - boxes[n:, 0], 2 * (p[:, 2] - p[:, 0]))
    np.testing.assert_array_equal(polarity, np.tile(last_double.proposals.polarity, 2))
    one, two = (net.complexity(2160, 3840)["flops"]["head"] for net in (single, double))
    assert two == 2 * one
    with pytest.raises(ValueError, match="crop_scales"):
        MiteNet(TorchHeadRuntime(head), crop_scales=(1.0, 0.0))
    with pytest.raises(ValueError, match="crop_scales"):
        MiteNet(TorchHeadRuntime(head), crop_scales=())
