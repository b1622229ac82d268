"""Fine-tuning on an imported image set: ``train --init`` and stills in the crop set."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from sarmission.cli import main as sarmission
from sarmission.models import DEFAULT_TORCH_MODEL
from sarmission.perception.head import HeadConfig, MiteHead
from sarmission.perception.runtime import load_head_checkpoint
from sarmission.training.dataset import CropSettings, load_crop_set
from sarmission.training.init_weights import initialise_from


def test_init_carries_every_weight_and_the_rows_of_shared_classes():
    shipped = load_head_checkpoint(DEFAULT_TORCH_MODEL)
    torch.manual_seed(1)
    model = MiteHead(HeadConfig(classes=("person", "swimmer")))
    fresh = {k: v.clone() for k, v in model.state_dict().items()}
    report = initialise_from(model, "default")
    assert (report.carried_classes, report.new_classes) == (("swimmer",), ("person",))
    assert "swimmer carried; person new" in report.summary()
    mine, theirs = model.state_dict(), shipped.state_dict()
    layer = "cls_branch.fc.2"
    for key, value in mine.items():
        if not key.startswith(layer):
            assert torch.equal(value, theirs[key]), key
    old = shipped.config.classes.index("swimmer")
    assert torch.equal(mine[f"{layer}.weight"][1], theirs[f"{layer}.weight"][old])
    assert torch.equal(mine[f"{layer}.bias"][1], theirs[f"{layer}.bias"][old])
    assert torch.equal(mine[f"{layer}.weight"][0], fresh[f"{layer}.weight"][0])  # new: fresh


def test_init_refuses_another_architecture_and_onnx(tmp_path):
    wider = MiteHead(HeadConfig(widths=(16, 32)))
    with pytest.raises(ValueError, match=r"architecture differs .*widths \(16, 24\) vs \(16, 32\)"):
        initialise_from(wider, "default")
    with pytest.raises(ValueError, match="needs a .pt checkpoint"):
        initialise_from(MiteHead(HeadConfig()), tmp_path / "head.onnx")


def _image_set(root: Path, n: int) -> Path:
    """``n`` VOC images (LADD layout), each with two people: small coloured blobs on grass."""
    rng = np.random.default_rng(5)
    (root / "Annotations").mkdir(parents=True)
    (root / "JPEGImages").mkdir(parents=True)
    for k in range(n):
        image = np.clip(rng.normal((60, 120, 70), 12, (240, 320, 3)), 0, 255).astype(np.uint8)
        objects = ""
        for x, y in ((60 + 40 * k, 80), (200, 150 - 20 * k)):
            cv2.rectangle(image, (x, y), (x + 5, y + 11), (40, 40, 200), -1)
            cv2.circle(image, (x + 2, y - 2), 2, (120, 160, 210), -1)
            objects += (
                f"<object><name>Pedestrian</name><difficult>0</difficult><bndbox>"
                f"<xmin>{x + 1}</xmin><ymin>{y - 4}</ymin><xmax>{x + 6}</xmax>"
                f"<ymax>{y + 12}</ymax></bndbox></object>"
            )
        cv2.imwrite(str(root / "JPEGImages" / f"{k}.png"), image)
        (root / "Annotations" / f"{k}.xml").write_text(
            f"<annotation><filename>{k}.png</filename><size><width>320</width>"
            f"<height>240</height></size>{objects}</annotation>"
        )
    return root


def test_stills_give_crops_from_every_image_as_a_held_camera_sees_them(tmp_path):
    root = _image_set(tmp_path / "LADD", 3)
    out = tmp_path / "ladd.json"
    assert (
        sarmission(["data", "import", "ladd", str(root), "--out", str(out), "--no-progress"]) == 0
    )
    settings = CropSettings(classes=("person",), frame_stride=5, jitters_per_gt=2)
    crops, _ = load_crop_set(out, settings, tmp_path / "cache", progress=False)
    # three stills, fewer than the warm-up: every one is sampled, none is skipped
    assert crops.frame_ids.tolist() == [1, 2, 3]
    assert sorted(set(crops.image_ids.tolist())) == [1, 2, 3]
    positives = crops.labels >= 0
    assert int(positives.sum()) >= 3 * 2 * 2  # two jitters per person at least
    # a held camera: the motion channel holds (nearly) nothing
    assert float(crops.crops[:, 3].float().abs().max()) < 0.05


def test_fine_tune_an_imported_set_from_the_shipped_head(tmp_path, capsys):
    root = _image_set(tmp_path / "LADD", 4)
    data = tmp_path / "ladd.json"
    assert (
        sarmission(["data", "import", "ladd", str(root), "--out", str(data), "--no-progress"]) == 0
    )
    out = tmp_path / "land" / "head.pt"
    args = ["train", "--train", str(data), "--val", str(data), "--out", str(out), "--epochs", "1"]
    args += ["--classes", "swimmer,person", "--init", "default", "--no-progress", "--onnx"]
    assert sarmission(args) == 0
    head = load_head_checkpoint(out)
    assert head.config.classes == ("swimmer", "person")
    assert out.with_suffix(".onnx").is_file()
    assert "initialised from" in capsys.readouterr().err
    missing = tmp_path / "nothing.pt"
    assert sarmission([*args[:-4], "--init", str(missing)]) == 2
    assert f"--init checkpoint not found: {missing}" in capsys.readouterr().err


def test_a_new_class_may_start_from_a_trained_one():
    shipped = load_head_checkpoint(DEFAULT_TORCH_MODEL)
    model = MiteHead(HeadConfig(classes=("person",)))
    report = initialise_from(model, "default", {"person": "swimmer"})
    assert (report.carried_classes, report.new_classes) == (("person (from swimmer)",), ())
    old = shipped.config.classes.index("swimmer")
    layer = "cls_branch.fc.2"
    assert torch.equal(
        model.state_dict()[f"{layer}.weight"][0], shipped.state_dict()[f"{layer}.weight"][old]
    )
    with pytest.raises(ValueError, match="has no class boat"):
        initialise_from(MiteHead(HeadConfig(classes=("person",))), "default", {"person": "boat"})
    # a typo in the new class's name was ignored: the class started from scratch, silently
    with pytest.raises(ValueError, match="the head being trained has no class persn"):
        initialise_from(MiteHead(HeadConfig(classes=("person",))), "default", {"persn": "swimmer"})


def test_evaluate_an_imported_land_set_with_the_shipped_head(tmp_path, capsys):
    root = _image_set(tmp_path / "LADD", 3)
    data = tmp_path / "ladd.json"
    assert (
        sarmission(["data", "import", "ladd", str(root), "--out", str(data), "--no-progress"]) == 0
    )
    capsys.readouterr()
    args = ["eval", "--annotations", str(data), "--json", "--no-progress", "--runtime", "onnx"]
    assert sarmission(args) == 2  # people on land are no class of the maritime head
    assert "--rename person=swimmer" in capsys.readouterr().err
    assert sarmission([*args, "--rename", "persons=swimmer"]) == 2
    assert "no category 'persons' (they have 'person')" in capsys.readouterr().err
    assert sarmission([*args, "--rename", "person=swimmer"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["boxes"]["bands"]["all"]["n_gt"] == 6  # two people in each of three stills


def test_init_by_a_shipped_heads_name_starts_from_that_head():
    """``--init land`` starts from the shipped land head: its person row is carried."""
    from sarmission.models import shipped_head_path

    land = load_head_checkpoint(shipped_head_path("land", "torch"))
    model = MiteHead(HeadConfig(classes=("person",)))
    report = initialise_from(model, "land")
    assert report.carried_classes == ("person",)
    for key, value in model.state_dict().items():
        assert torch.equal(value, land.state_dict()[key]), key
