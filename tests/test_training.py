"""Training of the MITE-Net head: sampling, losses, crop cache, training loop and CLI."""

from __future__ import annotations

import argparse
import math
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest
import torch
from synthetic_video import write_dataset

from sarmission.commands import train as train_command
from sarmission.perception.head import HeadConfig, MiteHead, ltrb_to_boxes
from sarmission.perception.runtime import load_head_checkpoint, load_head_runtime
from sarmission.perception.types import MotionMaps
from sarmission.training import dataset as dataset_module
from sarmission.training import train as train_module
from sarmission.training.dataset import (
    CropSettings,
    cache_key,
    load_crop_set,
    ltrb_targets,
    polarity_near,
    source_fingerprint,
)
from sarmission.training.losses import LossWeights, dfl_loss, head_loss, ltrb_nwd
from sarmission.training.sampling import assign_by_nwd, hardest_negatives, jitter_boxes
from sarmission.training.train import (
    TrainConfig,
    WeightAverage,
    dihedral,
    state_path,
    train,
    validation_settings,
)

torch.set_num_threads(2)


# --------------------------------------------------------------------------- sampling


def test_nwd_assignment_hand_computed():
    gt = np.array([[4, 4, 12, 12], [100, 100, 108, 108]], float)
    proposals = np.array([[0, 0, 16, 16], [20, 0, 36, 16], [96, 96, 112, 112]], float)
    # P0 vs A: same centre, sizes 16 vs 8: W = sqrt((8^2 + 8^2) / 4) = sqrt(32).
    # P1 vs A: dx = 20: W = sqrt(400 + 32).
    near, far = math.exp(-math.sqrt(32) / 12.8), math.exp(-math.sqrt(432) / 12.8)
    a = assign_by_nwd(proposals, gt, pos_threshold=0.4)
    np.testing.assert_array_equal(a.gt_index, [0, 0, 1])
    np.testing.assert_allclose(a.nwd, [near, far, near], rtol=1e-12)
    np.testing.assert_array_equal(a.positive, [True, False, True])
    assert not assign_by_nwd(proposals, gt, pos_threshold=0.65).positive.any()
    empty = assign_by_nwd(proposals, np.zeros((0, 4)))
    np.testing.assert_array_equal(empty.gt_index, [-1, -1, -1])
    assert not empty.positive.any()


def test_jitter_stays_within_scale_and_shift():
    gt = np.array([[50.0, 60.0, 56.0, 64.0], [10.0, 10.0, 13.0, 14.0]])
    boxes, src = jitter_boxes(gt, np.random.default_rng(3), 500, scale=0.2, shift=0.25, side=16)
    assert boxes.shape == (1000, 4)
    np.testing.assert_array_equal(src, np.repeat([0, 1], 500))
    w, h = boxes[:, 2] - boxes[:, 0], boxes[:, 3] - boxes[:, 1]
    np.testing.assert_allclose(w, h)
    assert w.min() >= 16 * 0.8 - 1e-9 and w.max() <= 16 * 1.2 + 1e-9
    assert w.min() < 13.5 and w.max() > 18.5  # the range is used, not just bounded
    centre = (boxes[:, :2] + boxes[:, 2:]) / 2
    gt_centre = ((gt[:, :2] + gt[:, 2:]) / 2)[src]
    assert (np.abs(centre - gt_centre) <= 0.25 * w[:, None] + 1e-9).all()
    assert np.abs(centre - gt_centre).max() > 0.2 * 16
    # Without a side the GT's own size is scaled, per axis.
    own, _ = jitter_boxes(gt[:1], np.random.default_rng(3), 200, scale=0.2, shift=0.0)
    ow, oh = own[:, 2] - own[:, 0], own[:, 3] - own[:, 1]
    assert ow.min() >= 6 * 0.8 - 1e-9 and ow.max() <= 6 * 1.2 + 1e-9
    assert oh.min() >= 4 * 0.8 - 1e-9 and oh.max() <= 4 * 1.2 + 1e-9
    np.testing.assert_allclose((own[:, :2] + own[:, 2:]) / 2, [[53.0, 62.0]] * 200)
    again, _ = jitter_boxes(gt, np.random.default_rng(3), 500, side=16)
    np.testing.assert_array_equal(boxes, again)


def test_hard_negatives_keep_three_per_positive_highest_first():
    logits = torch.tensor(
        [
            [0.1, -2.0],
            [3.0, 0.0],
            [-1.0, 2.5],
            [0.0, 0.2],
            [-5.0, -4.0],
            [1.0, 1.5],
            [0.3, 0.0],
            [-0.5, -0.6],
        ]
    )
    keep = hardest_negatives(logits, num_positives=2, ratio=3)
    # max over classes: 0.1, 3.0, 2.5, 0.2, -4.0, 1.5, 0.3, -0.5 → six highest in order.
    assert keep.tolist() == [1, 2, 5, 6, 3, 0]
    assert hardest_negatives(logits, num_positives=0, min_negatives=2).tolist() == [1, 2]
    assert len(hardest_negatives(logits, num_positives=5)) == 8
    assert len(hardest_negatives(logits[:0], num_positives=1)) == 0


# --------------------------------------------------------------------------- losses


def test_dfl_hand_computed():
    torch.manual_seed(0)
    logits = torch.randn(1, 4, 17)
    target = torch.tensor([[3.4, 20.0, -1.0, 7.0]])
    s = torch.softmax(logits[0], dim=-1)
    expected = -(
        0.6 * torch.log(s[0, 3])
        + 0.4 * torch.log(s[0, 4])
        + 0.01 * torch.log(s[1, 15])
        + 0.99 * torch.log(s[1, 16])  # clamp to 15.99
        + torch.log(s[2, 0])  # clamp to 0
        + torch.log(s[3, 7])
    )
    got = dfl_loss(logits, target, reg_max=16)
    assert got.shape == (1,)
    assert got.item() == pytest.approx(expected.item(), rel=1e-5)


def test_ltrb_nwd_in_full_resolution_pixels():
    pred = torch.tensor([[4.0, 4.0, 4.0, 4.0]])
    target = torch.tensor([[3.0, 4.0, 5.0, 4.0]])  # centre 1 crop px right, same size
    scale = torch.tensor([[2.0, 2.0]])
    assert ltrb_nwd(pred, target, scale).item() == pytest.approx(math.exp(-2 / 12.8), rel=1e-5)
    assert ltrb_nwd(target, target, scale).item() == pytest.approx(1.0, abs=1e-4)


def test_head_loss_terms_hand_computed():
    cls_logits = torch.tensor(
        [[2.0, -1.0], [0.5, 0.0], [-3.0, -2.0], [1.0, 2.0], [0.0, -1.0], [-1.0, -1.0]]
    )
    labels = torch.tensor([0, -1, -1, -1, -1, -1])
    bins = torch.zeros(6, 4, 17)
    ltrb = torch.full((6, 4), 8.0)
    target = torch.tensor([[8.0, 8.0, 8.0, 8.0]] * 6)
    scale = torch.ones(6, 2)
    terms = head_loss(cls_logits, bins, ltrb, labels, target, scale, LossWeights())

    def bce(z: float, y: float) -> float:
        p = 1 / (1 + math.exp(-z))
        return -(y * math.log(p) + (1 - y) * math.log(1 - p))

    # Positive (class 0) plus the 3 negatives with the highest max logit: rows 3, 1, 4.
    expected_cls = (
        bce(2.0, 1)
        + bce(-1.0, 0)
        + bce(1.0, 0)
        + bce(2.0, 0)
        + bce(0.5, 0)
        + bce(0.0, 0)
        + bce(0.0, 0)
        + bce(-1.0, 0)
    )
    assert terms.num_pos == 1 and terms.num_neg == 3
    assert terms.cls.item() == pytest.approx(expected_cls, rel=1e-5)
    assert terms.nwd.item() == pytest.approx(0.0, abs=1e-4)
    assert terms.dfl.item() == pytest.approx(4 * math.log(17), rel=1e-5)  # uniform bins
    total = 1.0 * expected_cls + 5.0 * terms.nwd.item() + 0.5 * 4 * math.log(17)
    assert terms.total.item() == pytest.approx(total, rel=1e-5)
    none = head_loss(
        cls_logits, bins, ltrb, torch.full((6,), -1), target, scale, LossWeights(min_negatives=2)
    )
    assert none.num_pos == 0 and none.num_neg == 2 and none.dfl.item() == 0.0


# --------------------------------------------------------------------------- geometry


def test_ltrb_targets_invert_ltrb_to_boxes():
    crop = np.array([[100.0, 50.0, 116.0, 66.0], [10.0, 10.0, 29.2, 29.2]])
    gt = np.array([[104.0, 55.0, 110.0, 61.0], [15.0, 12.0, 20.0, 30.0]])
    ltrb = ltrb_targets(crop, gt)
    np.testing.assert_allclose(ltrb[0], [4.0, 3.0, 2.0, 3.0])
    np.testing.assert_allclose(ltrb_to_boxes(ltrb, crop), gt, atol=1e-4)


def test_dihedral_moves_boxes_with_crops():
    crop = torch.zeros(8, 4, 16, 16)
    crop[:, :, 3:10, 5:15] = 1.0  # rows [3, 10), cols [5, 15) around the centre (8, 8)
    ltrb = torch.tensor([[3.0, 5.0, 7.0, 2.0]]).repeat(8, 1)
    scale = torch.tensor([[1.0, 2.0]]).repeat(8, 1)
    out, t, s = dihedral(crop, ltrb, scale, torch.arange(8))
    for i in range(8):
        rows = torch.nonzero(out[i, 0].sum(dim=1)).flatten()
        cols = torch.nonzero(out[i, 0].sum(dim=0)).flatten()
        measured = [
            8 - cols.min().item(),
            8 - rows.min().item(),
            cols.max().item() + 1 - 8,
            rows.max().item() + 1 - 8,
        ]
        assert t[i].tolist() == measured, i
        assert s[i].tolist() == ([1.0, 2.0] if i % 2 == 0 else [2.0, 1.0])
    assert len({tuple(v.tolist()) for v in t}) == 8


def test_polarity_near_takes_the_strongest_response():
    response = np.zeros((40, 40), np.float32)
    change = np.full((40, 40), 0.5, np.float32)
    response[20, 14] = 1.0  # the trailing-edge peak, where L is negative
    change[20, 14] = -0.3
    motion = MotionMaps(1, change, change, change, change, response)
    np.testing.assert_array_equal(polarity_near(motion, np.array([[18.0, 20.0]]), 16.0), [0.0])
    # Far from any response: the sign of L at the point itself.
    np.testing.assert_array_equal(polarity_near(motion, np.array([[35.0, 5.0]]), 16.0), [1.0])


# --------------------------------------------------------------------------- crops and training


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("train_data")
    return {
        "train": write_dataset(root / "train", n_videos=2, n_frames=14, seed=1),
        "val": write_dataset(root / "val", n_videos=1, n_frames=14, seed=2),
        "cache": root / "cache",
    }


SETTINGS = CropSettings(frame_stride=2, jitters_per_gt=3)


def test_validation_scores_the_rpn_crops_only():
    """Validation sees what inference classifies first: every training-only sampler is off
    (including any a later recipe adds under the same naming), the RPN's settings are kept."""
    samplers = [
        f.name
        for f in fields(CropSettings)
        if f.name.endswith(("_negatives", "_per_gt", "_context"))
    ]
    assert {"jitters_per_gt", "background_negatives", "object_negatives", "object_context"} <= set(
        samplers
    )
    busy = replace(
        CropSettings(),
        **{name: 3 for name in samplers},
        frame_stride=5,
        seed=7,
        topn=30,
        ds=2,
        colour_share=0.25,
    )
    val = validation_settings(busy)
    assert {name: getattr(val, name) for name in samplers} == dict.fromkeys(samplers, 0)
    assert (val.frame_stride, val.seed) == (1, 0)
    assert (val.topn, val.ds, val.colour_share, val.classes) == (30, 2, 0.25, busy.classes)


def test_crop_cache_key_follows_the_recipe_source(tmp_path, monkeypatch):
    module = tmp_path / "recipe_probe.py"
    module.write_text("SIDE = 16\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    before = source_fingerprint(("recipe_probe",))
    assert source_fingerprint(("recipe_probe",)) == before
    module.write_text("SIDE = 24\n")
    assert source_fingerprint(("recipe_probe",)) != before
    # The key of a cache changes with the recipe's code, not only with the settings.
    annotations = tmp_path / "a.json"
    annotations.write_text("{}")
    key = cache_key(annotations, SETTINGS)
    assert cache_key(annotations, SETTINGS) == key
    monkeypatch.setattr(dataset_module, "source_fingerprint", lambda: "edited recipe")
    assert cache_key(annotations, SETTINGS) != key


def test_crops_cut_with_frames_missing_are_not_cached(tmp_path):
    """A set cut while images were missing was cached under the file's key, so the frames
    put back later were never read: '41 training crops from 1 frames' again."""
    annotations = write_dataset(tmp_path / "d", n_videos=1, n_frames=14, seed=3)
    images = sorted((tmp_path / "d").rglob("*.png"))
    hidden = {path: path.read_bytes() for path in images[6:10]}
    for path in hidden:
        path.unlink()
    partial, cached = load_crop_set(annotations, SETTINGS, tmp_path / "cache", progress=False)
    assert not cached and partial.frames_unread == 4
    assert not list((tmp_path / "cache").glob("crops-*.pt"))
    for path, data in hidden.items():
        path.write_bytes(data)
    whole, cached = load_crop_set(annotations, SETTINGS, tmp_path / "cache", progress=False)
    assert not cached and whole.frames_unread == 0 and len(whole.frame_ids) > len(partial.frame_ids)
    again, cached = load_crop_set(annotations, SETTINGS, tmp_path / "cache", progress=False)
    assert cached and torch.equal(again.crops, whole.crops)


def test_crop_cache_matches_inference_and_is_reused(data):
    crop_set, cached = load_crop_set(data["train"], SETTINGS, data["cache"], progress=False)
    assert not cached
    again, cached = load_crop_set(data["train"], SETTINGS, data["cache"], progress=False)
    assert cached and torch.equal(again.crops, crop_set.crops)
    n = len(crop_set)
    assert crop_set.crops.shape == (n, 4, 16, 16) and crop_set.crops.dtype == torch.float16
    # Only swimmer (0) and swimmer with life jacket (1) are targets; boats are background.
    assert set(crop_set.labels.unique().tolist()) == {-1, 0, 1}
    assert len(crop_set.frame_ids) == 2 * 6  # frames 3, 5, ..., 13 of each video
    assert len(crop_set.gt_boxes) == 12 * 4
    assert (crop_set.labels[crop_set.jittered] >= 0).all()
    assert int(crop_set.jittered.sum()) == 12 * 4 * 3
    rpn_pos = (crop_set.labels >= 0) & ~crop_set.jittered
    assert rpn_pos.any() and (crop_set.labels[~crop_set.jittered] == -1).any()

    # The RPN crops are what MiteNet (ds=1) makes at the same frame.
    from sarmission.data.coco_video import read_coco_video
    from sarmission.data.sequence import iter_sequence
    from sarmission.perception.crops import motion_enhanced_crops
    from sarmission.perception.mitenet import MiteNet, build_head_runtime

    dataset = read_coco_video(data["train"])
    net = MiteNet(build_head_runtime(None, "torch"), ds=1)
    frame_id = int(crop_set.frame_ids[1])
    for item in iter_sequence(dataset, dataset.videos[0].id):
        result = net.process(item.frame_bgr, 0.0)
        if item.image.id == frame_id:
            expected = motion_enhanced_crops(
                item.frame_bgr, result.motion, result.proposals.boxes, result.proposals.polarity
            )
            break
    rows = (crop_set.image_ids == frame_id) & ~crop_set.jittered
    np.testing.assert_array_equal(crop_set.boxes[rows].numpy(), result.proposals.boxes)
    torch.testing.assert_close(
        crop_set.crops[rows].float(), torch.from_numpy(expected), atol=2e-3, rtol=1e-3
    )
    # Positive RPN crops clear the NWD threshold against their box target.
    boxes = ltrb_to_boxes(crop_set.target_ltrb[rpn_pos].numpy(), crop_set.boxes[rpn_pos].numpy())
    nwd = assign_by_nwd(crop_set.boxes[rpn_pos].numpy(), boxes).nwd
    assert (nwd >= 0.4 - 1e-4).all()


def _config(data: dict[str, Path], out: Path, **kw) -> TrainConfig:
    base = {
        "epochs": 3,
        "batch_size": 32,
        "crops": SETTINGS,
        "cache_dir": data["cache"],
        "progress": False,
    }
    return TrainConfig(train=data["train"], val=data["val"], out=out, **(base | kw))


def _weights(path: Path) -> dict[str, torch.Tensor]:
    return torch.load(path, weights_only=True)["model"]


def test_training_lowers_loss_saves_checkpoint_and_is_deterministic(data, tmp_path):
    first = train(_config(data, tmp_path / "a" / "head.pt", epochs=4))
    losses = [h["loss"] for h in first.history]
    assert len(losses) == 4 and losses[-1] < 0.8 * losses[0]
    assert first.best_f2 > 0.0 and 1 <= first.best_epoch <= 4
    model = load_head_checkpoint(first.checkpoint)
    assert model.config.classes == ("swimmer", "swimmer_with_life_jacket")
    second = train(_config(data, tmp_path / "b" / "head.pt", epochs=4))
    a, b = _weights(first.state), _weights(second.state)
    assert all(torch.equal(a[k], b[k]) for k in a)
    other = train(_config(data, tmp_path / "c" / "head.pt", epochs=1, seed=1))
    assert not torch.equal(_weights(other.state)["stem.0.0.weight"], a["stem.0.0.weight"])


def test_weight_average_hand_computed():
    """Decay min(d, (1 + i) / (10 + i)) at update i: 0.1 first, then d = 0.15 caps it."""
    model = MiteHead(HeadConfig())
    weight = next(model.parameters())
    with torch.no_grad():
        weight.fill_(1.0)
    average = WeightAverage(model, decay=0.15)
    with torch.no_grad():
        weight.fill_(3.0)
    average.update(model)  # 0.1 * 1 + 0.9 * 3 = 2.8
    assert torch.allclose(next(average.model.parameters()), torch.full_like(weight, 2.8))
    with torch.no_grad():
        weight.fill_(-1.0)
    average.update(model)  # min(0.15, 2 / 11) = 0.15: 0.15 * 2.8 + 0.85 * -1 = -0.43
    assert torch.allclose(next(average.model.parameters()), torch.full_like(weight, -0.43))
    # Integer buffers (BatchNorm's batch counter) follow the model, the averaged head is frozen.
    counters = [k for k, v in model.state_dict().items() if not v.is_floating_point()]
    assert counters and all(
        torch.equal(average.model.state_dict()[k], model.state_dict()[k]) for k in counters
    )
    assert not any(p.requires_grad for p in average.model.parameters())
    with pytest.raises(ValueError, match="ema_decay"):
        replace(
            TrainConfig(train=Path("t"), val=Path("v"), out=Path("o.pt")), ema_decay=1.0
        ).validate()


def test_the_checkpoint_is_the_weight_average(data, tmp_path):
    run = train(_config(data, tmp_path / "head.pt", epochs=1, ema_decay=0.999))
    saved = load_head_checkpoint(run.checkpoint).state_dict()
    state = torch.load(run.state, weights_only=True)
    assert all(torch.equal(saved[k], state["average"]["model"][k]) for k in saved)
    assert not torch.equal(saved["stem.0.0.weight"], state["model"]["stem.0.0.weight"])
    raw = train(_config(data, tmp_path / "raw" / "head.pt", epochs=1))
    saved = load_head_checkpoint(raw.checkpoint).state_dict()
    assert torch.equal(saved["stem.0.0.weight"], _weights(raw.state)["stem.0.0.weight"])


def test_checkpoint_is_chosen_from_select_from_on(data, tmp_path):
    """Same run, epochs 1-2 barred: the best of epochs 3-4 by validation F2 is kept."""
    late = train(_config(data, tmp_path / "late" / "head.pt", epochs=4, select_from=3))
    f2 = [h["f2"] for h in late.history]
    assert late.best_epoch in (3, 4)
    assert late.best_f2 == max(f2[2:])
    assert late.best_epoch == 3 + int(f2[3] > f2[2])
    with pytest.raises(ValueError, match="select_from"):
        _config(data, tmp_path / "x.pt", epochs=4, select_from=5).validate()
    with pytest.raises(ValueError, match="select_from"):
        _config(data, tmp_path / "x.pt", epochs=4, select_from=0).validate()


def test_resume_continues_exactly(data, tmp_path, monkeypatch):
    full = train(_config(data, tmp_path / "full" / "head.pt", ema_decay=0.99))
    out = tmp_path / "cut" / "head.pt"
    real_epoch = train_module._train_epoch
    calls = []

    def interrupted(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real_epoch(*args, **kwargs)

    monkeypatch.setattr(train_module, "_train_epoch", interrupted)
    with pytest.raises(KeyboardInterrupt):
        train(_config(data, out, ema_decay=0.99))
    monkeypatch.setattr(train_module, "_train_epoch", real_epoch)
    state = torch.load(state_path(out), weights_only=True)
    assert state["epoch"] == 2
    # a state written before the motion floor existed has no such setting: it still resumes
    assert state["config"]["crops"].pop("motion_floor", None) is None
    torch.save(state, state_path(out))
    with pytest.raises(ValueError, match="crops"):
        floored = replace(SETTINGS, motion_floor=0.02)
        train(_config(data, out, resume=True, ema_decay=0.99, crops=floored))
    resumed = train(_config(data, out, resume=True, ema_decay=0.99))
    assert resumed.epochs_run == 1 and len(resumed.history) == 3
    a, b = _weights(full.state), _weights(resumed.state)
    assert all(torch.equal(a[k], b[k]) for k in a)
    a, b = (torch.load(run.state, weights_only=True)["average"] for run in (full, resumed))
    assert a["updates"] == b["updates"]
    assert all(torch.equal(a["model"][k], b["model"][k]) for k in a["model"])
    assert [h["f2"] for h in resumed.history] == [h["f2"] for h in full.history]
    with pytest.raises(ValueError, match="lr"):
        train(_config(data, out, resume=True, lr=0.01, ema_decay=0.99))


# --------------------------------------------------------------------------- CLI


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    train_command.add_parser(parser.add_subparsers())
    return parser.parse_args(["train", *argv])


def test_cli_trains_and_exports_onnx(data, tmp_path, capsys):
    out = tmp_path / "model.pt"
    args = _parse(
        [
            "--train",
            str(data["train"]),
            "--val",
            str(data["val"]),
            "--out",
            str(out),
            "--epochs",
            "1",
            "--frame-stride",
            "2",
            "--jitters",
            "3",
            "--cache-dir",
            str(data["cache"]),
            "--no-progress",
            "--onnx",
            "--motion-floor",
            "0.02",
        ]
    )
    assert args.func(args) == 0
    printed = capsys.readouterr().out
    assert f"wrote {out.with_suffix('.onnx')}: " in printed and "max |onnx - torch| " in printed
    config = load_head_checkpoint(out).config
    assert config.classes == ("swimmer", "swimmer_with_life_jacket")
    assert config.motion_floor == 0.02  # the crops were cut with it: the head keeps it
    assert load_head_runtime(out.with_suffix(".onnx")).config.motion_floor == 0.02


def test_cli_errors_are_clear(data, tmp_path):
    missing = _parse(
        [
            "--train",
            str(tmp_path / "nope.json"),
            "--val",
            str(data["val"]),
            "--out",
            str(tmp_path / "m.pt"),
        ]
    )
    with pytest.raises(OSError, match="nope.json"):
        missing.func(missing)
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    broken = _parse(
        [
            "--train",
            str(bad),
            "--val",
            str(data["val"]),
            "--out",
            str(tmp_path / "m.pt"),
            "--no-progress",
        ]
    )
    with pytest.raises(ValueError, match="not valid JSON"):
        broken.func(broken)
    # once accepted: a head with two outputs for one class; a folder said "not found"
    for extra, message in (
        (["--classes", "swimmer,Swimmer,boat"], "names Swimmer, swimmer more than once"),
        (["--train", str(tmp_path)], "a folder; give its annotation file"),
    ):
        args = _parse(
            [
                "--train",
                str(data["train"]),
                "--val",
                str(data["val"]),
                "--out",
                str(tmp_path / "m.pt"),
                *extra,
            ]
        )
        with pytest.raises(ValueError, match=message):
            args.func(args)
    foreign = _parse(
        [
            "--train",
            str(data["train"]),
            "--val",
            str(data["val"]),
            "--out",
            str(tmp_path / "m.pt"),
            "--classes",
            "kayak",
            "--no-progress",
            "--cache-dir",
            str(data["cache"]),
        ]
    )
    with pytest.raises(ValueError, match="kayak"):
        foreign.func(foreign)
    resume = _parse(
        [
            "--train",
            str(data["train"]),
            "--val",
            str(data["val"]),
            "--out",
            str(tmp_path / "fresh.pt"),
            "--resume",
            "--no-progress",
            "--cache-dir",
            str(data["cache"]),
            "--frame-stride",
            "2",
        ]
    )
    with pytest.raises(OSError, match="no training state"):
        resume.func(resume)


def test_settings_are_validated():
    with pytest.raises(ValueError, match="optimizer"):
        TrainConfig(Path("a"), Path("b"), Path("c"), optimizer="rmsprop").validate()
    with pytest.raises(ValueError, match="pos_nwd"):
        replace(SETTINGS, pos_nwd=0.0).validate()
    with pytest.raises(ValueError, match="motion_floor"):
        replace(SETTINGS, motion_floor=-0.01).validate()
    # once accepted: inf trained to NaN weights and wrote them; NaN overflowed mid-cutting
    for lr in (float("inf"), float("nan")):
        with pytest.raises(ValueError, match="lr must be a positive number"):
            TrainConfig(Path("a"), Path("b"), Path("c"), lr=lr).validate()
    with pytest.raises(ValueError, match="jitter_shift"):
        replace(SETTINGS, jitter_shift=float("nan")).validate()
    with pytest.raises(ValueError, match="is a folder"):  # found before training, not after
        TrainConfig(Path("a"), Path("b"), Path(".")).validate()


def test_a_diverged_training_stops_and_a_broken_state_is_named(data, tmp_path, monkeypatch):
    """A loss of NaN went on to save a head of NaN weights, exit 0; a truncated resume state
    gave a torch traceback."""
    out = tmp_path / "head.pt"
    real_epoch = train_module._train_epoch

    def diverging(*args, **kwargs):
        return real_epoch(*args, **kwargs) | {"loss": float("nan")}

    monkeypatch.setattr(train_module, "_train_epoch", diverging)
    with pytest.raises(ValueError, match="training diverged in epoch 1 \\(loss nan\\)"):
        train(_config(data, out, epochs=1))
    assert not out.exists()
    monkeypatch.setattr(train_module, "_train_epoch", real_epoch)
    # a head of boats alone, validated on F2 over people: 0 at every epoch, so epoch 1 was
    # kept without a word
    with pytest.raises(ValueError, match="no person box in the validation frames"):
        train(_config(data, out, epochs=1, crops=replace(SETTINGS, classes=("boat",))))
    state_path(out).write_bytes(b"PK\x03\x04 not a whole zip")
    with pytest.raises(ValueError, match="cannot resume: .* is not readable .*delete it"):
        train(_config(data, out, resume=True))
