"""Motion borrowed from background (``sarmission.training.still_motion``) and ``--still-share``."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pytest
import torch
from small_training import small_config, write_small_training_data

from sarmission.commands import train as train_command
from sarmission.perception.runtime import load_head_checkpoint
from sarmission.training.dataset import load_crop_set
from sarmission.training.still_motion import MOTION, borrow_background_motion
from sarmission.training.train import TrainConfig, train

torch.set_num_threads(2)


def _batch() -> tuple[torch.Tensor, torch.Tensor]:
    crops = torch.rand(12, 4, 16, 16)
    labels = torch.tensor([0, -1, 1, -1, 0, 0, -1, 2, 0, 1, 0, 0])
    return crops, labels


def test_every_chosen_crop_takes_the_motion_of_a_negative_and_keeps_its_colour():
    crops, labels = _batch()
    before = crops.clone()
    out = borrow_background_motion(crops, labels, 1.0, np.random.default_rng(0))
    assert torch.equal(crops, before)  # the input is left as it was
    assert torch.equal(out[:, :MOTION], crops[:, :MOTION])
    negatives = [k for k in range(12) if labels[k] < 0]
    donors = [
        [j for j in negatives if torch.equal(out[k, MOTION], crops[j, MOTION])] for k in range(12)
    ]
    assert all(len(d) == 1 for d in donors)
    positives = [k for k in range(12) if labels[k] >= 0]
    assert all(not torch.equal(out[k, MOTION], crops[k, MOTION]) for k in positives)
    assert len({d[0] for d in donors}) > 1  # donors are drawn, not one for all


def test_the_share_decides_how_many_and_the_generator_which():
    crops = torch.rand(400, 4, 4, 4)
    labels = torch.tensor([-1] * 200 + [0] * 200)
    out = borrow_background_motion(crops, labels, 0.5, np.random.default_rng(5))
    changed = [not torch.equal(out[k], crops[k]) for k in range(200, 400)]
    assert 70 < sum(changed) < 130
    again = borrow_background_motion(crops, labels, 0.5, np.random.default_rng(5))
    assert torch.equal(out, again)
    other = borrow_background_motion(crops, labels, 0.5, np.random.default_rng(6))
    assert not torch.equal(out, other)


def test_nothing_changes_without_a_share_or_without_negatives():
    crops, labels = _batch()
    assert borrow_background_motion(crops, labels, 0.0, np.random.default_rng(0)) is crops
    positives_only = torch.zeros(12, dtype=torch.long)
    assert borrow_background_motion(crops, positives_only, 1.0, np.random.default_rng(0)) is crops
    for share in (-0.1, 1.5, float("nan")):
        with pytest.raises(ValueError, match="share must be in"):
            borrow_background_motion(crops, labels, share, np.random.default_rng(0))


def test_still_share_is_validated_and_reaches_the_cli(data, tmp_path):
    for share in (-0.1, 1.5):
        with pytest.raises(ValueError, match="still_share"):
            TrainConfig(Path("a"), Path("b"), Path("c"), still_share=share).validate()
    parser = argparse.ArgumentParser()
    train_command.add_parser(parser.add_subparsers())
    files = ["--train", str(data["train"]), "--val", str(data["val"])]
    argv = ["train", *files, "--out", str(tmp_path / "o.pt")]
    args = parser.parse_args([*argv, "--still-share", "0.3"])
    assert train_command.config_from_args(args).still_share == 0.3
    assert train_command.config_from_args(parser.parse_args(argv)).still_share == 0.0
    assert "still_share" not in TrainConfig(Path("a"), Path("b"), Path("c")).fingerprint()


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> dict[str, Path]:
    return write_small_training_data(tmp_path_factory.mktemp("still_data"))


def _scores_with_background_motion(checkpoint: Path, data: dict[str, Path]) -> torch.Tensor:
    """The head's top class probability on the validation positives, each given the motion
    channel of a validation negative (a still target under a still camera)."""
    config = small_config(data, Path("unused"))
    crops, _ = load_crop_set(data["val"], config.crops, data["cache"], progress=False)
    pos = (crops.labels >= 0).nonzero().flatten()
    neg = (crops.labels < 0).nonzero().flatten()
    assert len(pos) >= 10 and len(neg) >= 10
    still = crops.crops[pos].float().clone()
    donors = neg[torch.from_numpy(np.random.default_rng(0).integers(0, len(neg), len(pos)))]
    still[:, MOTION] = crops.crops[donors, MOTION].float()
    model = load_head_checkpoint(checkpoint).eval()
    with torch.no_grad():
        logits, _ = model(still)
    return torch.sigmoid(logits).amax(dim=1)


def test_a_head_trained_with_borrowed_motion_scores_still_targets_higher(data, tmp_path):
    """The synthetic sea's targets all move: a head trained on it alone leans on their motion,
    one trained with half its crops given background motion finds them without it."""
    plain = train(small_config(data, tmp_path / "plain" / "head.pt", epochs=6))
    still = train(small_config(data, tmp_path / "still" / "head.pt", epochs=6, still_share=0.5))
    again = train(small_config(data, tmp_path / "again" / "head.pt", epochs=6, still_share=0.5))
    a = torch.load(still.state, weights_only=True)["model"]
    b = torch.load(again.state, weights_only=True)["model"]
    assert all(torch.equal(a[k], b[k]) for k in a)
    before = _scores_with_background_motion(plain.checkpoint, data)
    after = _scores_with_background_motion(still.checkpoint, data)
    assert after.median() > before.median()
