"""Training beyond one renderer: background negatives and randomised crops in the training loop."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch
from synthetic_video import write_dataset

from sarmission.boxes import nwd_matrix
from sarmission.commands import train as train_command
from sarmission.data.coco_video import read_coco_video
from sarmission.data.sequence import iter_sequence
from sarmission.training.dataset import (
    BACKGROUND_MAX_NWD,
    CropSet,
    CropSettings,
    background_boxes,
    load_crop_set,
    object_negative_boxes,
    part_of_objects,
)
from sarmission.training.randomise import TRANSFORMS, Randomisation
from sarmission.training.sampling import (
    CONTEXT_MAX_SCALE,
    CONTEXT_MIN_SCALE,
    context_boxes,
    context_negative_boxes,
)
from sarmission.training.train import TrainConfig, train

torch.set_num_threads(2)


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("randomise_data")
    return {
        "train": write_dataset(root / "train", n_videos=1, n_frames=12, seed=1),
        "val": write_dataset(root / "val", n_videos=1, n_frames=12, seed=2),
        "cache": root / "cache",
    }


def test_background_boxes_are_seeded_inside_the_frame_and_away_from_targets() -> None:
    gt = np.array([[100.0, 100.0, 110.0, 112.0], [300.0, 50.0, 306.0, 58.0]])
    a = background_boxes((240, 400), gt, 50, 16.0, np.random.default_rng(4))
    b = background_boxes((240, 400), gt, 50, 16.0, np.random.default_rng(4))
    assert np.array_equal(a, b) and 40 <= len(a) <= 50
    assert np.allclose(a[:, 2] - a[:, 0], 16) and np.allclose(a[:, 3] - a[:, 1], 16)
    assert a[:, :2].min() >= 0 and a[:, 2].max() <= 400 and a[:, 3].max() <= 240
    assert nwd_matrix(a, gt).max() < BACKGROUND_MAX_NWD
    # a frame covered by one target leaves no room for background negatives
    assert (
        len(
            background_boxes(
                (32, 32), np.array([[8.0, 8.0, 24.0, 24.0]]), 5, 16.0, np.random.default_rng(0)
            )
        )
        == 0
    )


def _without_and_with(data: dict[str, Path], **extra: int) -> tuple[CropSet, CropSet]:
    """The training crops without and with the ``extra`` crop settings (cached)."""
    plain = CropSettings(frame_stride=3, jitters_per_gt=2)
    sets = (plain, replace(plain, **extra))
    base, more = (load_crop_set(data["train"], c, data["cache"], progress=False)[0] for c in sets)
    return base, more


def test_background_negatives_add_labelled_negatives_per_frame(data) -> None:
    base, more = _without_and_with(data, background_negatives=6)
    frames = len(base.frame_ids)
    added = len(more) - len(base)
    assert 0 < added <= 6 * frames and added >= 4 * frames
    assert int((more.labels >= 0).sum()) == int((base.labels >= 0).sum())
    new = more.labels == -1
    assert int(new.sum()) - int((base.labels == -1).sum()) == added
    assert torch.all(more.target_ltrb[new] == 0)
    # the crops are cut at those places: same colour as the frame's pixels there (16-px box)
    dataset = read_coco_video(data["train"])
    frame_id = int(more.frame_ids[0])
    rows = torch.nonzero(more.image_ids == frame_id).flatten()
    last = int(rows[-1])  # the frame's last crop is a background negative
    assert int(more.labels[last]) == -1 and not bool(more.jittered[last])
    x1, y1 = (int(round(v)) for v in more.boxes[last, :2].tolist())
    for item in iter_sequence(dataset, dataset.videos[0].id):
        if item.image.id == frame_id:
            pixels = item.frame_bgr[y1 : y1 + 16, x1 : x1 + 16, ::-1].astype(np.float32) / 255
            break
    crop = more.crops[last, :3].float().permute(1, 2, 0).numpy()
    assert np.abs(crop.mean(axis=(0, 1)) - pixels.mean(axis=(0, 1))).max() < 0.05


def test_object_negatives_lie_on_the_boat_and_never_on_a_swimmer(data) -> None:
    base, more = _without_and_with(data, object_negatives=3)
    frames = len(base.frame_ids)
    added = len(more) - len(base)
    assert int((more.labels >= 0).sum()) == int((base.labels >= 0).sum())
    assert frames <= added <= 3 * frames  # one boat per frame, some copies near a swimmer dropped
    dataset = read_coco_video(data["train"])
    boats = {a.image_id: a.bbox for a in dataset.annotations if a.category_id == 3}
    for frame_id in more.frame_ids.tolist():
        rows = torch.nonzero(more.image_ids == frame_id).flatten()
        extra_rows = rows[int((base.image_ids == frame_id).sum()) :]  # cut last
        assert bool(torch.all(more.labels[extra_rows] == -1))
        x, y, w, h = boats[frame_id]
        centres = (more.boxes[extra_rows, :2] + more.boxes[extra_rows, 2:]) / 2
        # jittered by at most half a (1.2 x 16 px) side around the boat's centre
        assert float((centres[:, 0] - (x + w / 2)).abs().max()) <= 9.7
        assert float((centres[:, 1] - (y + h / 2)).abs().max()) <= 9.7
        swimmers = more.gt_boxes[more.gt_image_ids == frame_id].numpy()
        if len(swimmers):
            assert nwd_matrix(more.boxes[extra_rows].numpy(), swimmers).max() < BACKGROUND_MAX_NWD


def test_object_negative_boxes_drop_squares_on_a_target() -> None:
    settings = CropSettings()
    boat = np.array([[100.0, 100.0, 140.0, 120.0]])
    person_on_deck = np.array([[114.0, 104.0, 126.0, 116.0]])
    far_person = np.array([[400.0, 400.0, 410.0, 410.0]])
    rng = np.random.default_rng(0)
    assert len(object_negative_boxes(boat, far_person, 5, settings, rng)) == 5
    near = object_negative_boxes(boat, person_on_deck, 50, settings, np.random.default_rng(0))
    assert len(near) < 50
    if len(near):
        assert nwd_matrix(near, person_on_deck).max() < BACKGROUND_MAX_NWD
    assert len(object_negative_boxes(np.zeros((0, 4)), far_person, 5, settings, rng)) == 0
    assert len(object_negative_boxes(boat, far_person, 0, settings, rng)) == 0


def _config(data: dict[str, Path], out: Path, **kw) -> TrainConfig:
    base = {
        "epochs": 2,
        "batch_size": 32,
        "cache_dir": data["cache"],
        "progress": False,
        "crops": CropSettings(frame_stride=3, jitters_per_gt=2),
    }
    return TrainConfig(train=data["train"], val=data["val"], out=out, **(base | kw))


def test_randomised_training_is_deterministic_and_differs_from_plain(data, tmp_path) -> None:
    every = Randomisation(TRANSFORMS, 0.5)
    a = train(_config(data, tmp_path / "a" / "h.pt", randomise=every))
    b = train(_config(data, tmp_path / "b" / "h.pt", randomise=every))
    plain = train(_config(data, tmp_path / "c" / "h.pt"))
    wa, wb, wp = (torch.load(r.state, weights_only=True)["model"] for r in (a, b, plain))
    assert all(torch.equal(wa[k], wb[k]) for k in wa)
    assert not torch.equal(wa["stem.0.0.weight"], wp["stem.0.0.weight"])
    # resuming with other randomisation is refused
    changed = _config(
        data,
        tmp_path / "a" / "h.pt",
        randomise=Randomisation(("tone",), 0.5),
        resume=True,
        epochs=2,
    )
    with pytest.raises(ValueError, match="randomise"):
        train(changed)


def test_cli_options_reach_the_config(data, tmp_path) -> None:
    parser = argparse.ArgumentParser()
    train_command.add_parser(parser.add_subparsers())
    args = parser.parse_args(
        [
            "train",
            "--train",
            str(data["train"]),
            "--val",
            str(data["val"]),
            "--out",
            str(tmp_path / "m.pt"),
            "--randomise",
            "blur,noise",
            "--randomise-p",
            "0.3",
            "--background-negatives",
            "8",
        ]
    )
    config = train_command.config_from_args(args)
    assert config.randomise == Randomisation(("blur", "noise"), 0.3)
    assert config.crops.background_negatives == 8
    assert config.crops.classes == ("swimmer", "swimmer_with_life_jacket")
    args.classes = "maritime"
    assert train_command.config_from_args(args).crops.classes[2:] == (
        "boat",
        "jetski",
        "buoy",
        "life_saving_appliances",
    )
    args.randomise = "glitter"
    with pytest.raises(ValueError, match="glitter"):
        train_command.config_from_args(args)


def test_part_of_objects_takes_the_smallest_larger_object_under_the_centre() -> None:
    proposals = np.array(
        [
            [100.0, 100.0, 116.0, 116.0],  # centre (108, 108): on the boat's stern
            [190.0, 100.0, 206.0, 116.0],  # centre (198, 108): on the buoy beside the hull
            [300.0, 300.0, 316.0, 316.0],  # open water
            [400.0, 400.0, 416.0, 416.0],  # on a swimmer (a person class: NWD decides)
            [500.0, 500.0, 516.0, 516.0],  # on an object no larger than the proposal
        ]
    )
    gt = np.array(
        [
            [90.0, 90.0, 220.0, 140.0],  # boat
            [185.0, 95.0, 215.0, 125.0],  # buoy, 30 px
            [395.0, 395.0, 425.0, 425.0],  # swimmer
            [502.0, 502.0, 514.0, 530.0],  # a life ring 12 px wide
        ]
    )
    is_object = np.array([True, True, False, True])
    assert part_of_objects(proposals, gt, is_object).tolist() == [0, 1, -1, -1, -1]
    assert part_of_objects(proposals, gt, np.zeros(4, bool)).tolist() == [-1] * 5
    assert part_of_objects(np.zeros((0, 4)), gt, is_object).shape == (0,)


BOAT_CLASSES = ("swimmer", "swimmer_with_life_jacket", "boat")


def _big_boat_crops(data, **change) -> tuple[Path, CropSettings, CropSet, CropSet]:
    """A clip with a 60-px boat (a head class here); its crop sets without and with
    ``change`` to the settings."""
    root = data["cache"].parent / "big_boat"
    train = write_dataset(root, n_videos=1, n_frames=12, seed=3, boat_size=60.0)
    plain = CropSettings(classes=BOAT_CLASSES, frame_stride=3, jitters_per_gt=2)
    base, changed = (
        load_crop_set(train, c, data["cache"], progress=False)[0]
        for c in (plain, replace(plain, **change))
    )
    return train, plain, base, changed


def test_object_parts_label_the_rpn_crops_on_the_boat_as_boat(data) -> None:
    """With boats a head class, the RPN's proposals whose centre lies on a boat larger than
    them are cut as boats with --object-parts, and as negatives without; nothing else moves."""
    classes = BOAT_CLASSES
    train, _, base, parts = _big_boat_crops(data, object_parts=True)
    assert len(parts) == len(base) and torch.equal(parts.boxes, base.boxes)
    boat = classes.index("boat")
    changed = parts.labels != base.labels
    assert int(changed.sum()) > 0
    assert bool(torch.all(base.labels[changed] == -1)) and bool(
        torch.all(parts.labels[changed] == boat)
    )
    dataset = read_coco_video(train)
    boats = {a.image_id: a.bbox for a in dataset.annotations if a.category_id == 3}
    for row in torch.nonzero(changed).flatten().tolist():
        x, y, w, h = boats[int(parts.image_ids[row])]
        cx, cy = ((parts.boxes[row, :2] + parts.boxes[row, 2:]) / 2).tolist()
        assert x <= cx < x + w and y <= cy < y + h
        assert float(parts.target_ltrb[row].abs().sum()) > 0


def test_context_boxes_see_large_boxes_whole_at_the_wide_crop_scales() -> None:
    """Wide squares only for boxes larger than S, 2-8 S, centred on the box's central part,
    at least 1.2 times the box's side unless 8 S caps them."""
    gt = np.array(
        [
            [0.0, 0.0, 12.0, 12.0],  # fits in a 16-px proposal: none
            [100.0, 100.0, 140.0, 120.0],  # 40 px wide
            [300.0, 300.0, 500.0, 360.0],  # 200 px: capped at 8 S
        ]
    )
    boxes, src = context_boxes(gt, np.random.default_rng(0), 50, 16.0)
    assert sorted(set(src.tolist())) == [1, 2] and len(boxes) == 100
    side = boxes[:, 2] - boxes[:, 0]
    assert np.allclose(side, boxes[:, 3] - boxes[:, 1])
    assert side.min() >= CONTEXT_MIN_SCALE * 16 - 1e-9
    assert side.max() <= CONTEXT_MAX_SCALE * 16 + 1e-9
    assert np.all(side[src == 1] >= 1.2 * 40 - 1e-9)
    assert np.allclose(side[src == 2], CONTEXT_MAX_SCALE * 16)
    g = gt[src]
    cx, cy = (boxes[:, 0] + boxes[:, 2]) / 2, (boxes[:, 1] + boxes[:, 3]) / 2
    w, h = g[:, 2] - g[:, 0], g[:, 3] - g[:, 1]
    assert np.all(np.abs(cx - (g[:, 0] + g[:, 2]) / 2) <= 0.35 * w + 1e-9)
    assert np.all(np.abs(cy - (g[:, 1] + g[:, 3]) / 2) <= 0.35 * h + 1e-9)
    empty, none = context_boxes(gt[:1], np.random.default_rng(0), 3, 16.0)
    assert empty.shape == (0, 4) and none.size == 0
    with pytest.raises(ValueError):
        context_boxes(gt, np.random.default_rng(0), -1, 16.0)


def test_context_negatives_hold_no_target_and_stay_in_the_frame() -> None:
    targets = np.array([[200.0, 100.0, 210.0, 110.0], [600.0, 300.0, 620.0, 320.0]])
    boxes = context_negative_boxes((540, 960), targets, 40, 16.0, np.random.default_rng(1))
    assert 0 < len(boxes) <= 40
    side = boxes[:, 2] - boxes[:, 0]
    assert side.min() >= 32 - 1e-9 and side.max() <= 128 + 1e-9
    assert boxes[:, :2].min() >= 0 and boxes[:, 2].max() <= 960 and boxes[:, 3].max() <= 540
    for tx, ty in ((205.0, 105.0), (610.0, 310.0)):
        holds = (
            (boxes[:, 0] <= tx) & (tx <= boxes[:, 2]) & (boxes[:, 1] <= ty) & (ty <= boxes[:, 3])
        )
        assert not holds.any()
    assert context_negative_boxes((20, 20), targets, 5, 16.0, np.random.default_rng(1)).size == 0
    assert context_negative_boxes((540, 960), targets, 0, 16.0, np.random.default_rng(1)).size == 0


def test_object_context_adds_wide_boat_crops_and_wide_negatives(data) -> None:
    """--object-context adds wide crops on the boat labelled boat with its box as target, and
    wide negatives that hold no person; the other crops keep their labels."""
    classes = BOAT_CLASSES
    train, plain, base, wide = _big_boat_crops(data, object_context=2)
    side = wide.boxes[:, 2] - wide.boxes[:, 0]
    added = side >= CONTEXT_MIN_SCALE * plain.box_size - 1e-3
    assert len(wide) == len(base) + int(added.sum())
    assert torch.equal(wide.labels[~added], base.labels)
    boat = classes.index("boat")
    dataset = read_coco_video(train)
    boats = {a.image_id: a.bbox for a in dataset.annotations if a.category_id == 3}
    on_boat = added & (wide.labels == boat)
    negative = added & (wide.labels == -1)
    assert int(on_boat.sum()) >= 2 and int(negative.sum()) >= 2
    for row in torch.nonzero(on_boat).flatten().tolist():
        x, y, w, h = boats[int(wide.image_ids[row])]
        cx, cy = ((wide.boxes[row, :2] + wide.boxes[row, 2:]) / 2).tolist()
        assert x <= cx < x + w and y <= cy < y + h
        assert float(side[row]) >= 1.2 * max(w, h) - 1e-3
    people = [a for a in dataset.annotations if a.category_id != 3]
    for row in torch.nonzero(negative).flatten().tolist():
        b = wide.boxes[row].tolist()
        for a in (a for a in people if a.image_id == int(wide.image_ids[row])):
            x, y, w, h = a.bbox
            assert not (b[0] <= x + w / 2 <= b[2] and b[1] <= y + h / 2 <= b[3])
    with pytest.raises(ValueError, match="object_context"):
        replace(plain, object_context=-1).validate()
