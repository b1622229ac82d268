"""Kept person scores: a head learning other classes keeps a trained head's level for people."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest
import torch
from small_training import small_config, write_small_training_data

from sarmission.class_roles import MARITIME_CLASSES
from sarmission.commands import train as train_command
from sarmission.models import DEFAULT_TORCH_MODEL
from sarmission.perception.head import HeadConfig, MiteHead
from sarmission.perception.runtime import load_head_checkpoint
from sarmission.training.dataset import CropSettings, load_crop_set
from sarmission.training.init_weights import initialise_from
from sarmission.training.kept_scores import ScoreKeeper, load_keeper
from sarmission.training.train import TrainConfig, train

torch.set_num_threads(2)

BUOY = MARITIME_CLASSES.index("buoy")


def _crops(n: int = 12, seed: int = 0) -> torch.Tensor:
    generator = torch.Generator().manual_seed(seed)
    return torch.rand(n, 4, 16, 16, generator=generator)


def _student(seed: int = 3) -> MiteHead:
    torch.manual_seed(seed)
    model = MiteHead(HeadConfig(classes=MARITIME_CLASSES))
    initialise_from(model, "default")
    return model.eval()


def test_a_head_with_the_keepers_scores_gets_no_push():
    """The term is a cross-entropy against the keeper's probabilities: its gradient vanishes
    where the new head's person logits are the keeper's, and not elsewhere."""
    keeper = load_keeper("default", MARITIME_CLASSES)
    crops, labels = _crops(), torch.full((12,), -1)
    student = _student()
    same = student(crops)[0].detach().requires_grad_(True)
    keeper.loss(same, crops, labels).backward()
    assert same.grad[:, :2].abs().max() < 1e-7
    moved = (same.detach() + torch.linspace(-2, 2, 12)[:, None]).requires_grad_(True)
    keeper.loss(moved, crops, labels).backward()
    assert moved.grad[:, :2].abs().max() > 1e-3
    assert moved.grad[:, 2:].abs().max() == 0.0  # only the person classes are taught


def test_classes_are_matched_by_name_whatever_their_order():
    """A new head naming its people in another order than the keeper is taught each person
    class's own score: with the keeper's logits in its own order, nothing pushes."""
    classes = ("buoy", "swimmer_with_life_jacket", "swimmer")
    keeper = load_keeper("default", classes)
    crops, labels = _crops(), torch.full((12,), -1)
    with torch.no_grad():
        theirs = keeper.keeper(crops)[0]
    named = keeper.keeper.config.classes
    columns = [torch.zeros(12)] + [theirs[:, named.index(c)] for c in classes[1:]]
    logits = torch.stack(columns, dim=1).requires_grad_(True)
    keeper.loss(logits, crops, labels).backward()
    assert logits.grad.abs().max() < 1e-7


def test_crops_of_the_new_heads_other_classes_are_left_to_their_labels():
    keeper = load_keeper("default", MARITIME_CLASSES)
    crops = _crops()
    logits = torch.randn(12, len(MARITIME_CLASSES))
    buoys = torch.full((12,), BUOY)
    assert float(keeper.loss(logits, crops, buoys)) == 0.0
    mixed = buoys.clone()
    mixed[:4] = torch.tensor([-1, 0, 1, -1])
    alone = keeper.loss(logits[:4], crops[:4], mixed[:4])
    assert float(keeper.loss(logits, crops, mixed)) == pytest.approx(float(alone), rel=1e-6)


def test_the_keeper_must_name_the_people_and_cut_crops_alike(tmp_path):
    with pytest.raises(ValueError, match="names no class person"):
        load_keeper("default", ("person", "buoy"))
    keeper = load_keeper("default", MARITIME_CLASSES)
    other = MiteHead(HeadConfig(classes=MARITIME_CLASSES, widths=(16, 32)))
    with pytest.raises(ValueError, match="differs from the head being trained in widths"):
        keeper.check_fits(other, "default")
    keeper.check_fits(_student(), "default")  # the shipped head's own architecture fits
    with pytest.raises(ValueError, match="needs a .pt checkpoint"):
        load_keeper(tmp_path / "head.onnx", MARITIME_CLASSES)


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> dict[str, Path]:
    return write_small_training_data(tmp_path_factory.mktemp("kept_scores_data"))


def _gap_to_keeper(head_path: Path, crops: torch.Tensor, keeper: ScoreKeeper) -> float:
    """Mean absolute gap of the person probabilities of ``head_path`` and the keeper."""
    head = load_head_checkpoint(head_path)
    with torch.no_grad():
        mine = torch.sigmoid(head(crops)[0][:, keeper.student_ids])
        theirs = torch.sigmoid(keeper.keeper(crops)[0][:, keeper.keeper_ids])
    return float((mine - theirs).abs().mean())


def test_training_with_kept_scores_stays_near_the_keeper(data, tmp_path):
    """Two fine-tunes of the shipped head on the synthetic sea, with the maritime classes (its
    boat is a class of its own), that differ in the kept scores alone: on the validation
    crops the kept one's person probabilities stay much nearer the shipped head's (half the
    gap when written, at a weight of 20; the labels of this small set pull the other way)."""
    crops_settings = CropSettings(frame_stride=2, jitters_per_gt=3, classes=MARITIME_CLASSES)
    common = {"lr": 0.01, "init": "default", "crops": crops_settings, "epochs": 3}
    free = train(small_config(data, tmp_path / "free.pt", **common))
    kept = train(
        small_config(
            data, tmp_path / "kept.pt", keep_scores="default", kept_scores_weight=20.0, **common
        )
    )
    assert all(r["kept"] > 0 for r in kept.history)
    assert all(r["kept"] == 0 for r in free.history)
    val, _ = load_crop_set(data["val"], crops_settings, data["cache"], False, "val")
    keeper = load_keeper(DEFAULT_TORCH_MODEL, MARITIME_CLASSES)
    crops = val.crops.float()
    assert _gap_to_keeper(kept.checkpoint, crops, keeper) < 0.65 * _gap_to_keeper(
        free.checkpoint, crops, keeper
    )


def test_the_setting_is_validated_resumes_and_reaches_the_cli(data, tmp_path):
    for bad in (0.0, -1.0, 101.0):
        with pytest.raises(ValueError, match="kept_scores_weight"):
            TrainConfig(Path("a"), Path("b"), Path("c"), kept_scores_weight=bad).validate()
    plain = TrainConfig(Path("a"), Path("b"), Path("c")).fingerprint()
    assert "keep_scores" not in plain and "kept_scores_weight" not in plain
    keeping = TrainConfig(Path("a"), Path("b"), Path("c"), keep_scores="default").fingerprint()
    assert (keeping["keep_scores"], keeping["kept_scores_weight"]) == ("default", 4.0)
    parser = argparse.ArgumentParser()
    train_command.add_parser(parser.add_subparsers())
    base = ["train", "--train", str(data["train"]), "--val", str(data["val"])]
    base += ["--out", str(tmp_path / "o.pt")]
    args = parser.parse_args(base + ["--keep-scores", "default", "--kept-scores-weight", "9"])
    config = train_command.config_from_args(args)
    assert (config.keep_scores, config.kept_scores_weight) == ("default", 9.0)
    args = parser.parse_args(base + ["--keep-scores", str(tmp_path / "none.pt")])
    with pytest.raises(FileNotFoundError, match="--keep-scores checkpoint not found"):
        train_command.config_from_args(args)


def test_a_bad_keeper_fails_before_any_crop_is_cut(data, tmp_path):
    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(b"not a head")
    cache = tmp_path / "cache"
    config = small_config(data, tmp_path / "o.pt", keep_scores=str(garbage), cache_dir=cache)
    with pytest.raises(ValueError, match="not a torch checkpoint"):
        train(config)
    assert not cache.exists()
