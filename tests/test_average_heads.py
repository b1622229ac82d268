"""One head from several (``sarmission.training.average``): the weighted mean of their weights."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import load_tool

from sarmission.cli import main as sarmission
from sarmission.models import shipped_checkpoint
from sarmission.perception.head import HeadConfig, MiteHead
from sarmission.perception.runtime import (
    OnnxHeadRuntime,
    TorchHeadRuntime,
    load_head_checkpoint,
    save_head_checkpoint,
)
from sarmission.training.average import AverageError, average_heads


def _head(path, seed: int, classes: tuple[str, ...] = ("person",)):
    torch.manual_seed(seed)
    head = MiteHead(HeadConfig(classes=classes))
    with torch.no_grad():  # every weight and batch-norm statistic its own, as after training
        for name, value in head.state_dict().items():
            if value.is_floating_point():
                value.uniform_(0.5, 1.5) if name.endswith("var") else value.normal_(0, 0.3)
    save_head_checkpoint(head, path)
    return head.state_dict()


def test_the_mean_is_weighted_and_covers_running_statistics(tmp_path):
    a = _head(tmp_path / "a.pt", 1)
    b = _head(tmp_path / "b.pt", 2)
    mixed = average_heads([tmp_path / "a.pt", tmp_path / "b.pt"], [3.0, 1.0]).state_dict()
    floats = [k for k, v in a.items() if v.is_floating_point()]
    assert any(k.endswith("running_mean") for k in floats)
    for key in floats:
        assert torch.allclose(mixed[key], 0.75 * a[key] + 0.25 * b[key], atol=1e-6), key
        assert not torch.allclose(mixed[key], a[key]), key
    counts = [k for k, v in a.items() if not v.is_floating_point()]
    assert counts and all(torch.equal(mixed[k], a[k]) for k in counts)


def test_equal_weights_by_default_and_a_zero_weight_keeps_the_other(tmp_path):
    a = _head(tmp_path / "a.pt", 1)
    b = _head(tmp_path / "b.pt", 2)
    paths = [tmp_path / "a.pt", tmp_path / "b.pt"]
    half = average_heads(paths).state_dict()
    only_b = average_heads(paths, [0.0, 2.0]).state_dict()
    key = "stem.0.0.weight"
    assert torch.allclose(half[key], (a[key] + b[key]) / 2, atol=1e-6)
    assert torch.equal(only_b[key], b[key])


def test_the_averaged_head_runs(tmp_path):
    _head(tmp_path / "a.pt", 1)
    _head(tmp_path / "b.pt", 2)
    head = average_heads([tmp_path / "a.pt", tmp_path / "b.pt"])
    crops = torch.rand(4, head.config.in_channels, head.config.crop_size, head.config.crop_size)
    logits = head(crops)[0]
    assert logits.shape[0] == 4 and torch.isfinite(logits).all()


@pytest.mark.parametrize(
    ("weights", "message"),
    [
        ([1.0], "1 weights for 2 heads"),
        ([1.0, -1.0], "non-negative"),
        ([0.0, 0.0], "not all 0"),
        ([float("nan"), 1.0], "finite"),
        ([float("inf"), 1.0], "finite"),
    ],
)
def test_bad_weights_are_refused(tmp_path, weights, message):
    _head(tmp_path / "a.pt", 1)
    _head(tmp_path / "b.pt", 2)
    with pytest.raises(AverageError, match=message):
        average_heads([tmp_path / "a.pt", tmp_path / "b.pt"], weights)


def test_heads_that_differ_are_refused(tmp_path):
    _head(tmp_path / "a.pt", 1)
    _head(tmp_path / "b.pt", 2, classes=("swimmer",))
    with pytest.raises(AverageError, match=r"b.pt: architecture or classes differ"):
        average_heads([tmp_path / "a.pt", tmp_path / "b.pt"])
    with pytest.raises(AverageError, match="two heads or more"):
        average_heads([tmp_path / "a.pt"])


def test_export_average_writes_the_mean_as_pt_and_onnx(tmp_path, capsys):
    a = _head(tmp_path / "a.pt", 1)
    b = _head(tmp_path / "b.pt", 2)
    out = tmp_path / "mixed.onnx"
    argv = ["export", "--average", str(tmp_path / "a.pt"), str(tmp_path / "b.pt")]
    assert sarmission([*argv, "--weights", "1,3", "--out", str(out)]) == 0
    assert "the mean of 2 heads" in capsys.readouterr().out
    mixed = load_head_checkpoint(tmp_path / "mixed.pt").state_dict()
    key = "cls_branch.fc.2.weight"
    assert torch.allclose(mixed[key], 0.25 * a[key] + 0.75 * b[key], atol=1e-6)
    config = load_head_checkpoint(tmp_path / "mixed.pt").config
    shape = (3, config.in_channels, config.crop_size, config.crop_size)
    crops = np.random.default_rng(0).random(shape, dtype=np.float32)
    onnx_logits = OnnxHeadRuntime(out).predict(crops)[0]
    torch_logits = TorchHeadRuntime(load_head_checkpoint(tmp_path / "mixed.pt")).predict(crops)[0]
    assert np.allclose(onnx_logits, torch_logits, atol=1e-4)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--weights", "1,x"], "--weights: 'x' is not a number"),
        (["--weights", "1,2,3"], "3 weights for 2 heads"),
        (["--model", "land"], "--model and --average exclude each other"),
    ],
)
def test_export_average_refuses_bad_arguments_in_one_line(tmp_path, capsys, extra, message):
    _head(tmp_path / "a.pt", 1)
    _head(tmp_path / "b.pt", 2)
    argv = ["export", "--average", str(tmp_path / "a.pt"), str(tmp_path / "b.pt")]
    assert sarmission([*argv, *extra, "--out", str(tmp_path / "x.onnx")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "x.onnx").exists()


def test_export_weights_without_average_is_refused(tmp_path, capsys):
    assert sarmission(["export", "--weights", "1,1", "--out", str(tmp_path / "x.onnx")]) == 2
    assert "--weights needs --average" in capsys.readouterr().err


def _stub_land_training(tool, tmp_path, monkeypatch):
    """Stub ``train_land_head`` and ``install`` of ``tools/train_default_model.py``: heads
    written at random; returns the calls, the heads' states and the installs."""
    trained, states, installed = [], {}, []

    def fake_train(args, extra, altworld, seed, reuse=False):
        out = tmp_path / f"head_alt{int(altworld)}_seed{seed}.pt"
        trained.append((altworld, seed, reuse))
        states[altworld] = _head(out, 10 * seed + altworld)
        return out, 0

    monkeypatch.setattr(tool, "train_land_head", fake_train)
    monkeypatch.setattr(tool, "install", lambda *paths: installed.append(paths))
    return trained, states, installed


def test_the_land_recipe_installs_the_3_to_1_mean_of_the_two_heads_it_trains(tmp_path, monkeypatch):
    """``tools/train_default_model.py --head land``: the land recipe's head (seed 2) and the
    head with the alternative world's land (seed 0), averaged 3 to 1 into ``--work`` and
    installed as the shipped land head (training stubbed: its heads are written at random)."""
    tool = load_tool("train_default_model")
    trained, states, installed = _stub_land_training(tool, tmp_path, monkeypatch)
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.setattr("sys.argv", ["x", "--head", "land", "--work", str(work)])
    assert tool.main() == 0
    assert trained == [(False, 2, True), (True, 0, True)]
    mean_pt = work / "mitenet_land_head_average_seed2_alt0_w3-1.pt"
    assert installed == [(mean_pt, shipped_checkpoint("land"))]
    key = "cls_branch.fc.2.weight"
    mean = 0.75 * states[False][key] + 0.25 * states[True][key]
    assert torch.allclose(load_head_checkpoint(mean_pt).state_dict()[key], mean, atol=1e-6)
    assert mean_pt.with_suffix(".onnx").is_file()


def test_the_land_recipe_takes_other_weights_and_seeds_without_installing(
    tmp_path, monkeypatch, capsys
):
    tool = load_tool("train_default_model")
    trained, states, installed = _stub_land_training(tool, tmp_path, monkeypatch)
    work = tmp_path / "work"
    work.mkdir()
    argv = ["x", "--head", "land", "--seed", "1", "--altworld-seed", "2", "--work", str(work)]
    monkeypatch.setattr("sys.argv", [*argv, "--average-weights", "1,1", "--no-install"])
    assert tool.main() == 0
    assert trained == [(False, 1, True), (True, 2, True)] and not installed
    mean_head = load_head_checkpoint(work / "mitenet_land_head_average_seed1_alt2_w1-1.pt")
    key = "cls_branch.fc.2.weight"
    mean = (states[False][key] + states[True][key]) / 2
    assert torch.allclose(mean_head.state_dict()[key], mean, atol=1e-6)
    monkeypatch.setattr("sys.argv", [*argv, "--average-weights", "1,1", "--single"])
    assert tool.main() == 2
    assert "--average-weights needs the mean of two heads" in capsys.readouterr().err


@pytest.mark.parametrize("flag", [["--single"], ["--altworld"], ["--land-presets", "urban"]])
def test_a_single_land_head_is_trained_alone_and_never_installed(tmp_path, monkeypatch, flag):
    tool = load_tool("train_default_model")
    trained, _, installed = _stub_land_training(tool, tmp_path, monkeypatch)
    monkeypatch.setattr("sys.argv", ["x", "--head", "land", *flag, "--work", str(tmp_path)])
    assert tool.main() == 0
    assert trained == [("--altworld" in flag, 2, False)] and not installed


def test_a_land_part_is_reused_only_when_trained_with_the_same_options(tmp_path, monkeypatch):
    """The land recipe's mean reuses a part found in ``--work`` only when the record beside
    it holds the arguments it would train it with and the same input files; a part trained
    with other options, other data, from another head, or with no record, is trained again
    (rendering and training stubbed)."""
    tool = load_tool("train_default_model")
    data, start = tmp_path / "data.json", tmp_path / "maritime.pt"
    data.write_text("clips")
    start.write_bytes(b"maritime head")
    for name in ("render_land_training_set", "add_altworld", "render_heldout_val"):
        monkeypatch.setattr(tool, name, lambda *a, **k: data)
    monkeypatch.setattr(tool, "shipped_head_path", lambda name, runtime: start)  # --init default
    runs = []

    def fake_sarmission(command):
        runs.append(command)
        out = tmp_path / command[command.index("--out") + 1]
        out.write_bytes(b"head")
        return 0

    monkeypatch.setattr(tool, "sarmission", fake_sarmission)
    args = tool.argparse.Namespace(work=tmp_path, land_presets="wild", from_scratch=False)
    out, code = tool.train_land_head(args, ["--still-share", "0.3"], False, 2, reuse=True)
    assert code == 0 and len(runs) == 1 and runs[0][-2:] == ["--still-share", "0.3"]
    assert tool.train_land_head(args, ["--still-share", "0.3"], False, 2, reuse=True)[0] == out
    assert len(runs) == 1  # the same options: reused
    tool.train_land_head(args, [], False, 2, reuse=True)
    assert len(runs) == 2 and "--still-share" not in runs[1]  # other options: trained again
    out.with_suffix(".args.json").write_text("not json")
    tool.train_land_head(args, [], False, 2, reuse=True)
    assert len(runs) == 3  # no readable record: trained again
    tool.train_land_head(args, [], False, 2, reuse=False)
    assert len(runs) == 4
    data.write_text("clips rendered again")
    tool.train_land_head(args, [], False, 2, reuse=True)
    assert len(runs) == 5  # another training set under the same name: trained again
    tool.train_land_head(args, [], False, 2, reuse=True)
    assert len(runs) == 5
    start.write_bytes(b"another maritime head")
    tool.train_land_head(args, [], False, 2, reuse=True)
    assert len(runs) == 6  # another head to start from: trained again

    def failing(command):
        runs.append(command)
        return 1

    monkeypatch.setattr(tool, "sarmission", failing)
    assert tool.train_land_head(args, [], False, 2, reuse=False)[1] == 1
    assert not out.with_suffix(".args.json").exists()  # a failed run leaves no record
