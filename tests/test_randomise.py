"""Crop-level domain randomisation: seeded, shape- and label-preserving, each transform doing what
it says to the channels it may touch."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from sarmission.training.randomise import (
    ALL,
    TRANSFORMS,
    Randomisation,
    blocks,
    geometry,
    haze,
    hue,
    randomise_crops,
    white_balance,
)


def _batch(n: int = 12, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    crops = torch.rand(n, 4, 16, 16, generator=g)
    crops[:, 3] = crops[:, 3] * 3 - 1  # the motion channel spans [-1, 2]
    ltrb = torch.rand(n, 4, generator=g) * 4 + 1
    labels = torch.tensor([0, 1, -1] * (n // 3))
    ltrb[labels < 0] = 0
    return crops, ltrb, labels


@pytest.mark.parametrize("name", TRANSFORMS)
def test_each_transform_is_seeded_and_keeps_shapes_dtypes_and_labels(name: str) -> None:
    crops, ltrb, labels = _batch()
    before = (crops.clone(), ltrb.clone(), labels.clone())
    config = Randomisation((name,), probability=1.0)
    a = randomise_crops(crops, ltrb, labels, config, np.random.default_rng(7))
    b = randomise_crops(crops, ltrb, labels, config, np.random.default_rng(7))
    c = randomise_crops(crops, ltrb, labels, config, np.random.default_rng(8))
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
    assert not torch.equal(a[0], c[0])
    assert a[0].shape == crops.shape and a[0].dtype == crops.dtype
    assert a[1].shape == ltrb.shape and a[1].dtype == ltrb.dtype
    # inputs untouched, labels untouched, negatives keep zero targets
    assert torch.equal(crops, before[0]) and torch.equal(ltrb, before[1])
    assert torch.equal(labels, before[2])
    assert torch.all(a[1][labels < 0] == 0)
    assert not torch.equal(a[0][:, :3], crops[:, :3])
    assert a[0][:, :3].min() >= 0 and a[0][:, :3].max() <= 1


@pytest.mark.parametrize("name", [n for n in TRANSFORMS if n != "geometry"])
def test_photometric_transforms_leave_motion_and_targets_alone(name: str) -> None:
    crops, ltrb, labels = _batch()
    out, targets = randomise_crops(
        crops, ltrb, labels, Randomisation((name,), 1.0), np.random.default_rng(3)
    )
    assert torch.equal(out[:, 3], crops[:, 3])
    assert torch.equal(targets, ltrb)


def test_probability_zero_changes_nothing_and_one_changes_every_crop() -> None:
    crops, ltrb, labels = _batch()
    out, _ = randomise_crops(
        crops, ltrb, labels, Randomisation(TRANSFORMS, 0.0), np.random.default_rng(0)
    )
    assert torch.equal(out, crops)
    out, _ = randomise_crops(
        crops, ltrb, labels, Randomisation(("noise",), 1.0), np.random.default_rng(0)
    )
    assert all(not torch.equal(out[i], crops[i]) for i in range(len(crops)))


def test_hue_turns_saturated_colours_and_keeps_greys() -> None:
    crops = torch.zeros(8, 3, 16, 16)
    crops[:, :, :, :8] = 0.5  # grey half
    crops[:, 0, :, 8:], crops[:, 1, :, 8:], crops[:, 2, :, 8:] = 0.9, 0.3, 0.1  # orange half
    out = hue(crops, np.random.default_rng(1))
    assert torch.allclose(out[:, :, :, :8], crops[:, :, :, :8], atol=1e-5)
    change = (out[:, :, :, 8:] - crops[:, :, :, 8:]).abs().amax(dim=(1, 2, 3))
    assert change.max() > 0.3
    assert len(torch.unique(out[:, :, 0, 15], dim=0)) == 8  # a hue of its own per crop


def test_blocks_quantise_away_faint_fine_texture_and_keep_flat_areas() -> None:
    """A faint grey checkerboard (its only DCT coefficient below half a quantisation step at any
    quality drawn) comes out nearly flat; a flat crop stays within a DC step; colour detail of one
    pixel is averaged over 2x2 (4:2:0)."""
    y, x = torch.meshgrid(torch.arange(16), torch.arange(16), indexing="ij")
    board = ((x + y) % 2).float() * 0.02 + 0.5
    crops = board.expand(4, 3, 16, 16).clone()
    out = blocks(crops, np.random.default_rng(0))
    assert out.shape == crops.shape

    def ripple(x: torch.Tensor) -> float:  # mean step between neighbours along rows
        return float((x[..., 1:] - x[..., :-1]).abs().mean())

    assert ripple(crops) == pytest.approx(0.02)
    assert ripple(out) < 0.2 * ripple(crops)  # only the steps between blocks are left
    flat = torch.full((4, 3, 16, 16), 0.5)
    assert (blocks(flat, np.random.default_rng(0)) - flat).abs().max() < 0.02
    dot = torch.full((4, 3, 16, 16), 0.5)
    dot[:, 0, 8, 8] = 1.0
    assert (blocks(dot, np.random.default_rng(0))[:, 0, 8, 8] < 0.9).all()


def test_geometry_moves_content_and_box_together() -> None:
    """A bright off-centre bar lands where the transformed target box says."""
    crops = torch.zeros(1, 4, 16, 16)
    crops[0, :, 3:7, 9:15] = 1.0  # rows 3..6, columns 9..14
    # l, t, r, b from the centre (8, 8): the bar lies right of and above it, so l and b < 0
    ltrb = torch.tensor([[8 - 9.0, 8 - 3.0, 15 - 8.0, 7 - 8.0]])
    out, moved = geometry(crops, ltrb, torch.tensor([0]), np.random.default_rng(5))
    mask = out[0, 0] > 0.5
    rows, cols = torch.nonzero(mask, as_tuple=True)
    found = torch.tensor(
        [8 - cols.min(), 8 - rows.min(), cols.max() + 1 - 8, rows.max() + 1 - 8],
        dtype=torch.float32,
    )
    assert torch.allclose(found, moved[0], atol=1.6)
    assert not torch.allclose(moved, ltrb)
    # the motion channel moved with the colour
    assert torch.equal(out[0, 3] > 0.5, mask)


def test_geometry_keeps_negative_targets_zero() -> None:
    crops, ltrb, labels = _batch()
    _, moved = geometry(crops, ltrb, labels, np.random.default_rng(2))
    assert torch.all(moved[labels < 0] == 0)
    rotated = moved[labels >= 0]
    # an envelope of a rotated, scaled box: never smaller than 0.86 of the original per side
    assert torch.all(
        rotated[:, 0] + rotated[:, 2]
        >= math.exp(-0.15) * (ltrb[labels >= 0][:, 0] + ltrb[labels >= 0][:, 2]) - 1e-4
    )


def test_parse_names_all_and_none() -> None:
    # the recipes written with "all" before haze existed train as they did
    assert Randomisation.parse("all").transforms == (
        "tone",
        "white_balance",
        "hue",
        "blur",
        "noise",
        "blocks",
        "geometry",
    )
    assert Randomisation.parse("all").transforms == ALL
    assert Randomisation.parse("all,haze").transforms == TRANSFORMS
    assert Randomisation.parse("haze, all").transforms == TRANSFORMS
    assert Randomisation.parse("none").transforms == ()
    assert Randomisation.parse("noise, tone").transforms == ("tone", "noise")
    with pytest.raises(ValueError, match="unknown randomisation"):
        Randomisation.parse("tone,sparkle")
    with pytest.raises(ValueError, match="probability"):
        Randomisation.parse("tone", probability=1.5)


def test_haze_brightens_and_washes_out_colour() -> None:
    crops = torch.zeros(64, 3, 16, 16)
    crops[:, 0], crops[:, 1], crops[:, 2] = 0.9, 0.4, 0.1  # a life jacket's orange
    out = haze(crops, np.random.default_rng(0))
    spread_before = crops.amax(dim=1) - crops.amin(dim=1)
    spread_after = out.amax(dim=1) - out.amin(dim=1)
    brightness_before, brightness_after = crops.mean(dim=1), out.mean(dim=1)
    assert torch.all(spread_after <= spread_before + 0.1 + 1e-6)  # the tint is at most 0.1
    assert (spread_after < 0.75 * spread_before).float().mean() > 0.3
    assert torch.all(brightness_after >= brightness_before - 1e-6)
    assert (brightness_after > brightness_before + 0.05).float().mean() > 0.5
    # the same transmission and airlight over the whole crop
    assert torch.allclose(out[:, :, :1, :1].expand_as(out), out)


def test_a_transform_not_asked_for_draws_nothing() -> None:
    """``haze`` sits between ``white_balance`` and ``hue``; without it the others draw what
    they drew before it existed, so a recipe of ``all`` trains bit for bit as it did."""
    crops, ltrb, labels = _batch(n=24)
    out, _ = randomise_crops(
        crops, ltrb, labels, Randomisation(("white_balance", "hue"), 0.5), np.random.default_rng(5)
    )
    rng = np.random.default_rng(5)
    expected = crops.clone()
    for transform in (white_balance, hue):
        chosen = torch.from_numpy(np.flatnonzero(rng.random(len(crops)) < 0.5))
        expected[chosen, :3] = transform(expected[chosen, :3], rng)
    assert torch.equal(out, expected)
    hazed, _ = randomise_crops(
        crops,
        ltrb,
        labels,
        Randomisation(("white_balance", "haze", "hue"), 0.5),
        np.random.default_rng(5),
    )
    assert not torch.equal(hazed, out)
