"""MITE-Net head: size, shapes, DFL decoding, FLOP count, box conversion."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from sarmission.perception.head import (
    HeadConfig,
    MiteHead,
    count_parameters,
    dfl_decode,
    head_flops_per_proposal,
    ltrb_to_boxes,
    normalise_crop_colour,
)


@pytest.fixture(scope="module")
def head() -> MiteHead:
    torch.manual_seed(0)
    return MiteHead().eval()


def test_parameter_budget(head: MiteHead):
    assert 0 < count_parameters(head) < 140_000


@pytest.mark.parametrize("n", [0, 1, 7])
def test_output_shapes(head: MiteHead, n: int):
    with torch.no_grad():
        logits, bins, ltrb = head.forward_with_bins(torch.rand(n, 4, 16, 16))
        logits2, ltrb2 = head(torch.rand(n, 4, 16, 16))
    assert logits.shape == logits2.shape == (n, 2)
    assert bins.shape == (n, 4, 17)
    assert ltrb.shape == ltrb2.shape == (n, 4)
    assert torch.all((ltrb >= 0) & (ltrb <= 16))


def test_class_list_is_configuration():
    cfg = HeadConfig(classes=("person", "boat", "buoy"))
    with torch.no_grad():
        logits, _ = MiteHead(cfg).eval()(torch.rand(2, 4, 16, 16))
    assert logits.shape == (2, 3)
    assert HeadConfig.from_dict(cfg.to_dict()) == cfg
    with pytest.raises(ValueError):
        HeadConfig(classes=()).validate()


@pytest.mark.parametrize("k", [0, 5, 16])
def test_dfl_decode_one_hot_gives_the_bin(k: int):
    logits = torch.full((3, 4, 17), -1e4)
    logits[..., k] = 1e4
    assert torch.equal(dfl_decode(logits), torch.full((3, 4), float(k)))
    # Two equal bins decode to their midpoint.
    two = torch.full((1, 17), -1e4)
    two[0, [3, 4]] = 0.0
    assert dfl_decode(two).item() == pytest.approx(3.5)


def test_flops_per_proposal_matches_hand_count(head: MiteHead):
    hw, c = 16 * 16, 2
    macs = (
        hw * 16 * 6 * 9  # stem
        + hw * 24 * 16 * 9
        + hw * 24 * 24 * 9
        + hw * 24 * 16  # block d=2 with 1x1 skip
        + 2 * hw * 24 * 24 * 9  # block d=4
        + hw * 24 * 9
        + 2 * (24 * 6 + 6 * 24)
        + 48 * 32
        + 32 * c  # classification
        + hw * 4 * 24
        + 4 * hw * 68
    )  # regression
    assert head_flops_per_proposal(head) == 2 * macs


def test_ltrb_to_boxes_scales_with_the_crop():
    boxes = np.array([[100, 200, 116, 216], [0, 0, 32, 32]], np.float32)
    ltrb = np.array([[8, 8, 8, 8], [2, 3, 4, 5]], np.float32)
    out = ltrb_to_boxes(ltrb, boxes)
    np.testing.assert_allclose(out[0], boxes[0])
    np.testing.assert_allclose(out[1], [16 - 4, 16 - 6, 16 + 8, 16 + 10])  # 2 full-res px per bin
    assert ltrb_to_boxes(np.zeros((0, 4)), np.zeros((0, 4))).shape == (0, 4)


def test_crop_norm_sees_colour_relative_to_the_crop():
    """A crop-normalised head scores a crop the same under another brightness, contrast and
    colour cast (a common gain, an offset per colour channel), which a raw-colour head with the
    same weights does not; the motion channel is kept as it is."""
    torch.manual_seed(0)
    crops = torch.rand(6, 4, 16, 16) * 0.5 + 0.2
    recast = crops.clone()
    offset = torch.tensor([0.1, -0.05, 0.2])[None, :, None, None]
    recast[:, :3] = crops[:, :3] * 1.7 + offset
    normed = MiteHead(HeadConfig(crop_norm=0.05)).eval()
    raw = MiteHead(HeadConfig()).eval()
    raw.load_state_dict(normed.state_dict())
    with torch.no_grad():
        assert torch.allclose(normed(crops)[0], normed(recast)[0], atol=1e-4)
        assert not torch.allclose(raw(crops)[0], raw(recast)[0], atol=1e-2)
    x = normalise_crop_colour(crops, 0.05)
    assert torch.equal(x[:, 3], crops[:, 3])
    assert torch.allclose(x[:, :3].mean(dim=(2, 3)), torch.zeros(6, 3), atol=1e-5)
    assert torch.allclose(x[:, :3].pow(2).mean(dim=(1, 2, 3)), torch.ones(6), atol=1e-4)


def test_crop_norm_does_not_stretch_an_empty_crop():
    """A crop of nearly flat water (spread under the floor) is divided by the floor, not by
    its own spread: its noise stays small instead of becoming unit-scale structure. A floor of
    1 only centres the colour."""
    torch.manual_seed(1)
    flat = torch.full((2, 4, 16, 16), 0.4) + 0.004 * torch.randn(2, 4, 16, 16)
    centred = flat[:, :3] - flat[:, :3].mean(dim=(2, 3), keepdim=True)
    x = normalise_crop_colour(flat, 0.05)
    assert x[:, :3].abs().max() < 0.5
    assert torch.allclose(x[:, :3], centred / 0.05, atol=1e-6)
    busy = torch.rand(2, 4, 16, 16)
    assert torch.allclose(
        normalise_crop_colour(busy, 1.0)[:, :3],
        busy[:, :3] - busy[:, :3].mean(dim=(2, 3), keepdim=True),
        atol=1e-6,
    )
    with pytest.raises(ValueError, match="crop_norm"):
        HeadConfig(crop_norm=1.5).validate()
