"""Procedural texture negatives: the bank, how a batch takes them, what training makes of them."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pytest
import torch
from small_training import small_config, write_small_training_data

from sarmission.commands import train as train_command
from sarmission.perception.runtime import load_head_checkpoint
from sarmission.training.textures import (
    FAMILIES,
    dead_leaves,
    fractal,
    grating,
    paste_on_textures,
    texture_bank,
)
from sarmission.training.train import (
    TrainConfig,
    train,
    with_positives_on_textures,
    with_texture_negatives,
)

torch.set_num_threads(2)


def test_bank_is_deterministic_in_range_and_varied():
    bank = texture_bank(64, 16, seed=3)
    assert bank.shape == (64, 3, 16, 16) and bank.dtype == np.float32
    assert bank.min() >= 0.0 and bank.max() <= 1.0
    assert np.array_equal(bank, texture_bank(64, 16, seed=3))
    assert not np.array_equal(bank, texture_bank(64, 16, seed=4))
    flat = bank.reshape(64, -1)
    assert len(np.unique(flat, axis=0)) == 64
    # most crops are textured, not flat colour
    assert (flat.std(axis=1) > 0.01).mean() > 0.8
    with pytest.raises(ValueError, match="count"):
        texture_bank(-1, 16, 0)


def _radial_power(crops: np.ndarray) -> tuple[float, float]:
    """Mean power of the luminance spectrum at low (1-2 cycles) and high (6-8) frequencies."""
    lum = crops.mean(axis=1)
    lum = lum - lum.mean(axis=(1, 2), keepdims=True)
    power = np.abs(np.fft.fft2(lum)) ** 2
    f = np.fft.fftfreq(lum.shape[-1]) * lum.shape[-1]
    radius = np.hypot(f[:, None], f[None, :])
    low = power[:, (radius >= 1) & (radius <= 2)].mean()
    high = power[:, (radius >= 6) & (radius <= 8)].mean()
    return float(low), float(high)


@pytest.mark.parametrize("family", [dead_leaves, fractal])
def test_natural_families_have_falling_spectra(family):
    """Dead leaves and 1/f noise put far more power at coarse scales than fine ones, as natural
    images do (white noise would give a ratio near 1)."""
    low, high = _radial_power(family(np.random.default_rng(0), 200, 16))
    assert low > 8 * high


def _coherence(crops: np.ndarray) -> np.ndarray:
    """Per crop, how much of the luminance gradient shares one orientation (structure tensor:
    ``(l1 - l2) / (l1 + l2)``, 1 for straight parallel lines, near 0 for isotropic texture)."""
    gy, gx = np.gradient(crops.mean(axis=1), axis=(1, 2))
    jxx, jyy, jxy = (gx * gx).sum((1, 2)), (gy * gy).sum((1, 2)), (gx * gy).sum((1, 2))
    root = np.sqrt((jxx - jyy) ** 2 + 4 * jxy**2)
    return root / np.maximum(jxx + jyy, 1e-12)


def test_gratings_are_oriented_and_fractal_noise_is_not():
    stripes = _coherence(grating(np.random.default_rng(1), 100, 16))
    noise = _coherence(fractal(np.random.default_rng(1), 100, 16))
    assert np.median(stripes) > 0.8 > 0.5 > np.median(noise)


def _batch(n: int) -> tuple[torch.Tensor, ...]:
    crops = torch.rand(n, 4, 16, 16)
    target = torch.rand(n, 4)
    scale = torch.rand(n, 2) + 0.5
    labels = torch.zeros(n, dtype=torch.long)
    symmetry = torch.zeros(n, dtype=torch.long)
    return crops, target, scale, labels, symmetry


def test_texture_negatives_join_a_batch_with_a_donor_motion_channel():
    bank = torch.from_numpy(texture_bank(8, 16, 0))
    donor_crops = torch.rand(5, 4, 16, 16).half()
    donor_scale = torch.arange(10, dtype=torch.float32).view(5, 2)
    batch = _batch(4)
    crops, target, scale, labels, symmetry = with_texture_negatives(
        batch, bank, (donor_crops, donor_scale), 6, np.random.default_rng(0)
    )
    assert crops.shape == (10, 4, 16, 16) and len(target) == len(scale) == len(labels) == 10
    assert torch.equal(crops[:4], batch[0]) and torch.equal(labels[:4], batch[3])
    assert (labels[4:] == -1).all() and (target[4:] == 0).all()
    for k in range(4, 10):
        rgb_match = [torch.equal(crops[k, :3], t) for t in bank]
        donor = [i for i in range(5) if torch.equal(crops[k, 3], donor_crops[i, 3].float())]
        assert sum(rgb_match) == 1 and len(donor) == 1
        assert torch.equal(scale[k], donor_scale[donor[0]])
    assert ((symmetry[4:] >= 0) & (symmetry[4:] < 8)).all()
    unchanged = with_texture_negatives(
        batch, bank, (donor_crops, donor_scale), 0, np.random.default_rng(0)
    )
    assert unchanged is batch


def _person_on_sea(n: int) -> np.ndarray:
    """Crops of a flat sea colour with a 6x4 px red 'person' in the middle."""
    rgb = np.empty((n, 3, 16, 16))
    rgb[:] = np.array([0.1, 0.3, 0.4])[None, :, None, None]
    rgb[:, :, 5:11, 6:10] = np.array([0.9, 0.1, 0.1])[None, :, None, None]
    return rgb


def test_paste_keeps_the_person_and_replaces_the_ground():
    rgb = _person_on_sea(4)
    textures = texture_bank(4, 16, 0).astype(np.float64)
    out = paste_on_textures(rgb, textures)
    assert np.allclose(out[:, :, 5:11, 6:10], rgb[:, :, 5:11, 6:10])
    ground = np.ones((16, 16), bool)
    ground[5:11, 6:10] = False
    assert np.allclose(out[:, :, ground], textures[:, :, ground])


def test_only_positives_go_on_textures_and_motion_stays():
    crops = torch.from_numpy(
        np.concatenate([_person_on_sea(6), np.random.default_rng(0).random((6, 1, 16, 16))], 1)
    ).float()
    labels = torch.tensor([0, -1, 1, -1, 0, 0])
    bank = torch.from_numpy(texture_bank(8, 16, 0))
    out = with_positives_on_textures(crops, labels, bank, 1.0, np.random.default_rng(0))
    changed = [not torch.equal(out[k, :3], crops[k, :3]) for k in range(6)]
    assert changed == [True, False, True, False, True, True]
    assert torch.equal(out[:, 3], crops[:, 3])
    none = with_positives_on_textures(crops, labels, bank, 0.0, np.random.default_rng(0))
    assert torch.equal(none, crops)


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> dict[str, Path]:
    return write_small_training_data(tmp_path_factory.mktemp("texture_data"))


def _texture_scores(checkpoint: Path, motion: torch.Tensor) -> torch.Tensor:
    """Person probability (largest class) of the head on textures of a bank it never saw."""
    model = load_head_checkpoint(checkpoint).eval()
    rgb = torch.from_numpy(texture_bank(256, 16, seed=99))
    crops = torch.cat([rgb, motion.expand(256, 1, 16, 16)], dim=1)
    with torch.no_grad():
        logits, _ = model(crops)
    return torch.sigmoid(logits).amax(dim=1)


def test_training_with_textures_lowers_scores_on_unseen_textures(data, tmp_path):
    plain = train(small_config(data, tmp_path / "plain" / "head.pt"))
    textured = train(small_config(data, tmp_path / "tex" / "head.pt", texture_negatives=0.5))
    again = train(small_config(data, tmp_path / "again" / "head.pt", texture_negatives=0.5))
    a = torch.load(textured.state, weights_only=True)["model"]
    b = torch.load(again.state, weights_only=True)["model"]
    assert all(torch.equal(a[k], b[k]) for k in a)
    motion = torch.zeros(1, 1, 1, 1)
    before = _texture_scores(plain.checkpoint, motion)
    after = _texture_scores(textured.checkpoint, motion)
    assert after.median() < before.median()
    assert textured.best_f2 > 0.0


def test_texture_share_is_validated_and_reaches_the_cli(data, tmp_path):
    with pytest.raises(ValueError, match="texture_negatives"):
        TrainConfig(Path("a"), Path("b"), Path("c"), texture_negatives=-0.1).validate()
    with pytest.raises(ValueError, match="texture_negatives"):
        TrainConfig(Path("a"), Path("b"), Path("c"), texture_negatives=5.0).validate()
    with pytest.raises(ValueError, match="texture_positives"):
        TrainConfig(Path("a"), Path("b"), Path("c"), texture_positives=1.5).validate()
    parser = argparse.ArgumentParser()
    train_command.add_parser(parser.add_subparsers())
    args = parser.parse_args(
        ["train", "--train", str(data["train"]), "--val", str(data["val"])]
        + ["--out", str(tmp_path / "o.pt"), "--texture-negatives", "0.25"]
        + ["--texture-positives", "0.5"]
    )
    config = train_command.config_from_args(args)
    assert config.texture_negatives == 0.25 and config.texture_positives == 0.5
    assert len(FAMILIES) == 4
