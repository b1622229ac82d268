"""Rounding consistency: the perturbation, its loss, and what training with it does to a head."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pytest
import torch
from small_training import small_config, write_small_training_data

from sarmission.commands import train as train_command
from sarmission.training.consistency import (
    AMPLITUDE,
    E_RANGE,
    MAX_SHIFT,
    consistency_loss,
    rounding_perturbation,
)
from sarmission.training.train import TrainConfig, train

torch.set_num_threads(2)


def _flat_crops(n: int = 64, seed: int = 0) -> torch.Tensor:
    """Crops of one colour and one motion level each (a shift leaves them as they are)."""
    rng = np.random.default_rng(seed)
    rgb = rng.uniform(0.1, 0.9, size=(n, 3, 1, 1))
    motion = rng.uniform(0.2, 1.2, size=(n, 1, 1, 1))
    level = np.concatenate([rgb, motion], axis=1).astype(np.float32)
    return torch.from_numpy(np.broadcast_to(level, (n, 4, 16, 16)).copy())


def test_colour_moves_by_a_level_and_motion_smoothly():
    crops = _flat_crops()
    kept = crops.clone()
    out = rounding_perturbation(crops, np.random.default_rng(1))
    assert torch.equal(crops, kept)  # input untouched
    rgb_step = (out[:, :3] - crops[:, :3]).abs()
    assert rgb_step.max() <= 1.0 / 255 + 1e-6 and rgb_step.mean() > 0.25 / 255
    change = out[:, 3] - crops[:, 3]
    assert out[:, 3].min() >= E_RANGE[0] and out[:, 3].max() <= E_RANGE[1]
    # the change of each crop is smooth (neighbours move together) and its size varies by crop
    near = torch.corrcoef(torch.stack([change[:, :, :-1].flatten(), change[:, :, 1:].flatten()]))
    assert near[0, 1] > 0.5
    spread = change.flatten(1).std(dim=1)
    assert spread.min() < 3 * AMPLITUDE[0] and spread.max() > AMPLITUDE[1] / 3
    again = rounding_perturbation(crops, np.random.default_rng(1))
    assert torch.equal(out, again)
    assert not torch.equal(out, rounding_perturbation(crops, np.random.default_rng(2)))


def _centroid(plane: torch.Tensor) -> torch.Tensor:
    """``[n, 2]`` (x, y) centre of mass of ``[n, H, W]`` planes."""
    h, w = plane.shape[-2:]
    mass = plane.flatten(1).sum(dim=1)
    x = (plane.sum(dim=1) * torch.arange(w)).sum(dim=1) / mass
    y = (plane.sum(dim=2) * torch.arange(h)).sum(dim=1) / mass
    return torch.stack([x, y], dim=1)


def test_the_whole_crop_moves_by_a_pixel_or_two():
    """A bright blob at the centre of colour and motion: both move together, within the largest
    shift, by a pixel or so on average."""
    crops = torch.zeros(256, 4, 16, 16)
    crops[:, :, 6:10, 6:10] = 1.0
    out = rounding_perturbation(crops, np.random.default_rng(4))
    moved = _centroid(out[:, 1]) - _centroid(crops[:, 1])
    assert moved.abs().max() <= MAX_SHIFT + 0.05
    # along each axis, both ways: |U(-2.5, 2.5)| averages 1.25 px
    assert (moved.abs().mean(dim=0) > 0.9).all()
    assert (moved.amax(dim=0) > 1.5).all() and (moved.amin(dim=0) < -1.5).all()
    # the motion channel moved with the colour: its peak lies on the moved blob
    peak = out[:, 3].flatten(1).argmax(dim=1)
    on_blob = out[:, 1].flatten(1)[torch.arange(256), peak] > 0.5
    assert on_blob.float().mean() > 0.9


def test_the_loss_is_the_squared_gap_of_probabilities():
    logits = torch.tensor([[0.0, 2.0], [-1.0, 1.0]])
    assert consistency_loss(logits, logits) == 0.0
    other = torch.tensor([[0.0, 2.0], [-1.0, 3.0]])
    gap = torch.sigmoid(torch.tensor(3.0)) - torch.sigmoid(torch.tensor(1.0))
    assert consistency_loss(logits, other) == pytest.approx(float(gap**2) / 2, rel=1e-6)


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> dict[str, Path]:
    return write_small_training_data(tmp_path_factory.mktemp("consistency_data"))


def test_training_with_the_term_steadies_the_scores(data, tmp_path):
    """Two runs that differ in the term's weight alone (both put the perturbed copies through
    the head, so that batch statistics are the same kind): with weight 50 the last epoch's gap
    between crops and their copies is well under half of that with a weight of nothing (0.39
    when written)."""
    weak = train(small_config(data, tmp_path / "weak.pt", lr=0.05, rounding_consistency=1e-6))
    steady = train(small_config(data, tmp_path / "steady.pt", lr=0.05, rounding_consistency=50.0))
    assert all(r["rounding"] > 0 for r in weak.history + steady.history)
    assert steady.history[-1]["rounding"] < 0.5 * weak.history[-1]["rounding"]
    assert steady.best_f2 > 0.0


def test_the_weight_is_validated_and_reaches_the_cli(data, tmp_path):
    for bad in (-1.0, 101.0):
        with pytest.raises(ValueError, match="rounding_consistency"):
            TrainConfig(Path("a"), Path("b"), Path("c"), rounding_consistency=bad).validate()
    # a state written without the term still resumes: the fingerprint leaves it out at 0
    assert "rounding_consistency" not in TrainConfig(Path("a"), Path("b"), Path("c")).fingerprint()
    parser = argparse.ArgumentParser()
    train_command.add_parser(parser.add_subparsers())
    args = parser.parse_args(
        ["train", "--train", str(data["train"]), "--val", str(data["val"])]
        + ["--out", str(tmp_path / "o.pt"), "--rounding-consistency", "5"]
    )
    assert train_command.config_from_args(args).rounding_consistency == 5.0
