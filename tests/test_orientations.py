"""The head's verdict averaged over orientations of each crop (perception/orientations.py)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from sarmission.perception.mitenet import MiteNet, build_head_runtime
from sarmission.perception.orientations import (
    check_orientations,
    ltrb_from_orientation,
    oriented_crops,
)
from sarmission.training.train import dihedral

CENTRE = 8  # the crop's centre, in pixel edges, of a 16-px crop


def _mask_ltrb(mask: np.ndarray) -> np.ndarray:
    """Distances from the crop's centre to the edges of the pixels set in ``mask`` [S, S]."""
    rows, cols = np.nonzero(mask)
    return np.array(
        [
            CENTRE - cols.min(),
            CENTRE - rows.min(),
            cols.max() + 1 - CENTRE,
            rows.max() + 1 - CENTRE,
        ],
        np.float32,
    )


@pytest.mark.parametrize("op", range(8))
def test_a_box_turned_with_its_crop_maps_back_to_where_it_was(op: int) -> None:
    """An off-centre rectangle drawn in a crop: its edges measured in the crop turned by ``op``,
    mapped back, are its edges in the crop as drawn (every turn and mirror)."""
    crops = np.zeros((1, 4, 16, 16), np.float32)
    crops[0, :, 2:6, 9:15] = 1.0  # above and right of the centre, wider than tall
    turned = oriented_crops(crops, op)
    assert turned.shape == crops.shape and turned.flags.c_contiguous
    seen = _mask_ltrb(turned[0, 0] > 0)[None]
    np.testing.assert_array_equal(
        ltrb_from_orientation(seen, op), _mask_ltrb(crops[0, 0] > 0)[None]
    )
    if op:
        assert not np.array_equal(turned, crops)  # every op but the identity moves it


@pytest.mark.parametrize("op", range(8))
def test_the_training_turns_crops_and_boxes_the_same_way(op: int) -> None:
    """The augmentation the head is trained with and the orientations inference averages over
    are the same symmetry for the same ``op``: crops alike, boxes mapped back alike."""
    rng = np.random.default_rng(op)
    crops = rng.random((3, 4, 16, 16)).astype(np.float32)
    ltrb = rng.random((3, 4)).astype(np.float32) * 8
    ops = torch.full((3,), op)
    trained, trained_ltrb, _ = dihedral(
        torch.from_numpy(crops), torch.from_numpy(ltrb), torch.ones(3, 2), ops
    )
    np.testing.assert_array_equal(trained.numpy(), oriented_crops(crops, op))
    np.testing.assert_allclose(ltrb_from_orientation(trained_ltrb.numpy(), op), ltrb)


@pytest.fixture(scope="module")
def shipped():
    return build_head_runtime(None, "onnx")


def test_eight_orientations_make_the_verdict_independent_of_how_a_crop_lies(shipped) -> None:
    """With 8 orientations the shipped head gives a crop and each of its turned or mirrored
    copies the same probabilities, and the same box once mapped back; with one it does not."""
    crops = np.random.default_rng(0).random((30, 4, 16, 16)).astype(np.float32)
    averaged = MiteNet(shipped, orientations=8, score_threshold=0.0)
    single = MiteNet(shipped, orientations=1, score_threshold=0.0)
    scores, ids, ltrb = averaged._classify(crops)
    single_scores = single._classify(crops)[0]
    for op in range(1, 8):
        op_scores, op_ids, op_ltrb = averaged._classify(oriented_crops(crops, op))
        np.testing.assert_allclose(op_scores, scores, atol=1e-6)
        np.testing.assert_array_equal(op_ids, ids)
        np.testing.assert_allclose(ltrb_from_orientation(op_ltrb, op), ltrb, atol=1e-4)
        assert np.abs(single._classify(oriented_crops(crops, op))[0] - single_scores).max() > 1e-3


def test_four_orientations_average_the_quarter_turns(shipped) -> None:
    """With 4 orientations a crop's score is the mean of the head's probabilities over its
    four quarter turns, its box the mean of their boxes mapped back."""
    crops = np.random.default_rng(1).random((12, 4, 16, 16)).astype(np.float32)
    logits, boxes = zip(
        *(shipped.predict(oriented_crops(crops, op)) for op in range(4)), strict=True
    )
    probs = np.mean([1 / (1 + np.exp(-lg.astype(np.float64))) for lg in logits], axis=0)
    mapped = np.mean([ltrb_from_orientation(b, op) for op, b in enumerate(boxes)], axis=0)
    scores, ids, ltrb = MiteNet(shipped, orientations=4, score_threshold=0.0)._classify(crops)
    np.testing.assert_allclose(scores, probs.max(axis=1), atol=1e-6)
    np.testing.assert_array_equal(ids, probs.argmax(axis=1))
    np.testing.assert_allclose(ltrb, mapped, atol=1e-4)


def test_only_would_be_detections_are_looked_at_again(shipped) -> None:
    """Crops whose single look scores under the detection threshold keep that look (the extra
    orientations cost head passes for would-be detections alone); the others are averaged."""
    crops = np.random.default_rng(2).random((40, 4, 16, 16)).astype(np.float32)
    single = MiteNet(shipped, orientations=1)._classify(crops)[0]
    threshold = float(np.median(single))
    averaged = MiteNet(shipped, orientations=8, score_threshold=threshold)._classify(crops)[0]
    everywhere = MiteNet(shipped, orientations=8, score_threshold=0.0)._classify(crops)[0]
    low = single < threshold
    assert 0 < low.sum() < len(crops)
    np.testing.assert_array_equal(averaged[low], single[low])
    np.testing.assert_allclose(averaged[~low], everywhere[~low], atol=1e-6)
    assert np.abs(averaged[~low] - single[~low]).max() > 1e-3


def test_orientation_counts_other_than_1_4_8_are_refused(shipped) -> None:
    for bad in (0, 2, 3, 5, 16, True, 4.5, "4"):
        with pytest.raises(ValueError, match="orientations must be one of 1, 4, 8"):
            check_orientations(bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="orientations"):
        MiteNet(shipped, orientations=2)
    assert check_orientations(4.0) == 4  # type: ignore[arg-type]


def test_the_head_flops_count_every_orientation(shipped) -> None:
    one, eight = (
        MiteNet(shipped, orientations=n).complexity(2160, 3840)["flops"]["head"] for n in (1, 8)
    )
    assert eight == 8 * one
