"""Head export, torch vs onnxruntime, and model-file errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import onnx
import pytest
import torch

from sarmission.perception.export import export_head_onnx
from sarmission.perception.head import HeadConfig, MiteHead
from sarmission.perception.runtime import (
    ModelLoadError,
    OnnxHeadRuntime,
    TorchHeadRuntime,
    load_head_runtime,
    save_head_checkpoint,
)


@pytest.fixture(scope="module")
def model_files(tmp_path_factory) -> tuple[Path, Path]:
    torch.manual_seed(3)
    head = MiteHead()
    # Non-trivial BatchNorm statistics so that eval-mode folding is exercised.
    head.train()
    with torch.no_grad():
        head(torch.rand(64, 4, 16, 16))
    head.eval()
    d = tmp_path_factory.mktemp("models")
    pt = save_head_checkpoint(head, d / "head.pt")
    report = export_head_onnx(pt, d / "head.onnx")
    assert report.max_abs_diff < 1e-4 and report.opset == 17
    return pt, report.path


def test_onnx_matches_torch(model_files):
    pt, onnx_path = model_files
    crops = np.random.default_rng(0).random((25, 4, 16, 16), dtype=np.float32)
    t_logits, t_ltrb = load_head_runtime(pt).predict(crops)
    o_rt = load_head_runtime(onnx_path)
    assert isinstance(o_rt, OnnxHeadRuntime)
    o_logits, o_ltrb = o_rt.predict(torch.from_numpy(crops))
    np.testing.assert_allclose(o_logits, t_logits, atol=1e-4)
    np.testing.assert_allclose(o_ltrb, t_ltrb, atol=1e-4)
    # A checkpoint can also run on onnxruntime (exported in memory).
    m_logits, _ = load_head_runtime(pt, runtime="onnx").predict(crops)
    np.testing.assert_allclose(m_logits, t_logits, atol=1e-4)


def test_zero_proposals_and_bad_shapes(model_files):
    for path in model_files:
        rt = load_head_runtime(path)
        logits, ltrb = rt.predict(np.zeros((0, 4, 16, 16), np.float32))
        assert logits.shape == (0, 2) and ltrb.shape == (0, 4)
        assert rt.classes == ("swimmer", "swimmer_with_life_jacket")
        with pytest.raises(ValueError, match=r"\[N, 4, 16, 16\]"):
            rt.predict(np.zeros((2, 3, 16, 16), np.float32))


def test_checkpoint_round_trip(model_files, tmp_path):
    pt, _ = model_files
    rt = TorchHeadRuntime.from_checkpoint(pt)
    again = save_head_checkpoint(rt.model, tmp_path / "again.pt")
    crops = np.random.default_rng(1).random((3, 4, 16, 16), dtype=np.float32)
    for a, b in zip(rt.predict(crops), load_head_runtime(again).predict(crops), strict=True):
        np.testing.assert_array_equal(a, b)


def _expect_error(path: Path, phrase: str, runtime: str = "auto") -> None:
    with pytest.raises(ModelLoadError) as info:
        load_head_runtime(path, runtime=runtime)
    message = str(info.value)
    assert str(path) in message and phrase in message and "\n" not in message


def test_bad_model_files(model_files, tmp_path):
    pt, onnx_path = model_files
    _expect_error(tmp_path / "missing.pt", "file not found")
    _expect_error(tmp_path / "missing.onnx", "file not found")
    (tmp_path / "noise.onnx").write_bytes(np.random.default_rng(0).bytes(4096))
    _expect_error(tmp_path / "noise.onnx", "not an ONNX model")
    (tmp_path / "noise.pt").write_bytes(np.random.default_rng(0).bytes(4096))
    _expect_error(tmp_path / "noise.pt", "not a torch checkpoint")
    (tmp_path / "config.pt").write_text(json.dumps({"classes": ["a"]}))
    _expect_error(tmp_path / "config.pt", "not a torch checkpoint")
    (tmp_path / "config.onnx").write_text(json.dumps({"classes": ["a"]}))
    _expect_error(tmp_path / "config.onnx", "not an ONNX model")
    (tmp_path / "head.txt").write_text("x")
    _expect_error(tmp_path / "head.txt", "unknown model extension")
    _expect_error(onnx_path, "needs a .pt checkpoint", runtime="torch")


def test_bad_checkpoints(model_files, tmp_path):
    pt, _ = model_files
    ckpt = torch.load(pt, weights_only=True)
    torch.save(ckpt["state_dict"], tmp_path / "bare.pt")
    _expect_error(tmp_path / "bare.pt", "no 'format' entry")
    missing = dict(
        ckpt, state_dict={k: v for k, v in ckpt["state_dict"].items() if not k.startswith("stem.")}
    )
    torch.save(missing, tmp_path / "missing_keys.pt")
    _expect_error(tmp_path / "missing_keys.pt", "missing ['stem.")
    wider = dict(ckpt, config=HeadConfig(widths=(16, 32)).to_dict())
    torch.save(wider, tmp_path / "wider.pt")
    _expect_error(tmp_path / "wider.pt", "shape mismatch")
    future = dict(ckpt, format_version=99)
    torch.save(future, tmp_path / "future.pt")
    _expect_error(tmp_path / "future.pt", "unsupported format version 99")
    bad_cfg = dict(ckpt, config={"classes": [], "reg_max": 16})
    torch.save(bad_cfg, tmp_path / "bad_cfg.pt")
    _expect_error(tmp_path / "bad_cfg.pt", "invalid head config")


def test_bad_onnx_graphs(model_files, tmp_path):
    _, onnx_path = model_files
    proto = onnx.load(onnx_path)
    proto.graph.input[0].type.tensor_type.shape.dim[1].dim_value = 3
    onnx.save(proto, tmp_path / "three_channels.onnx")
    _expect_error(tmp_path / "three_channels.onnx", "expected [N, 4, 16, 16]")

    proto = onnx.load(onnx_path)
    proto.graph.input[0].type.tensor_type.shape.dim[0].dim_value = 25
    onnx.save(proto, tmp_path / "fixed_n.onnx")
    _expect_error(tmp_path / "fixed_n.onnx", "must be dynamic")

    proto = onnx.load(onnx_path)
    del proto.metadata_props[:]
    onnx.save(proto, tmp_path / "no_meta.onnx")
    _expect_error(tmp_path / "no_meta.onnx", "no 'sarmission.format' metadata")


def test_motion_floor_travels_with_the_head(tmp_path):
    """The motion floor is part of the head's input: checkpoint and ONNX metadata carry it, and
    the cascade cuts its crops with it."""
    from sarmission.perception.mitenet import MiteNet

    torch.manual_seed(0)
    head = MiteHead(HeadConfig(motion_floor=0.02)).eval()
    pt = save_head_checkpoint(head, tmp_path / "floor.pt")
    onnx_path = export_head_onnx(pt, tmp_path / "floor.onnx").path
    for path in (pt, onnx_path):
        runtime = load_head_runtime(path)
        assert runtime.config.motion_floor == 0.02
        assert MiteNet(runtime).motion_floor == 0.02
    assert load_head_runtime(model_files_default()).config.motion_floor == 0.0
    with pytest.raises(ValueError, match="motion_floor"):
        HeadConfig(motion_floor=-0.1).validate()
    with pytest.raises(ValueError, match="motion_floor"):
        HeadConfig.from_dict({"motion_floor": float("nan")})


def model_files_default() -> Path:
    """The shipped head (trained before the floor existed: its metadata has none)."""
    from sarmission.models import DEFAULT_ONNX_MODEL

    return DEFAULT_ONNX_MODEL


def test_crop_norm_travels_with_the_head(tmp_path):
    """A crop-normalised head normalises inside its graph: checkpoint and ONNX metadata say so,
    and onnxruntime gives torch's scores for the same raw crops."""
    torch.manual_seed(0)
    head = MiteHead(HeadConfig(crop_norm=0.05)).eval()
    pt = save_head_checkpoint(head, tmp_path / "norm.pt")
    report = export_head_onnx(pt, tmp_path / "norm.onnx")
    assert report.max_abs_diff < 1e-4
    crops = np.random.default_rng(1).random((9, 4, 16, 16), dtype=np.float32)
    crops[:3, :3] = 0.5  # flat crops: divided by the floor, not by zero
    t_logits, _ = load_head_runtime(pt).predict(crops)
    o_logits, _ = load_head_runtime(report.path).predict(crops)
    np.testing.assert_allclose(o_logits, t_logits, atol=1e-4)
    assert np.isfinite(o_logits).all()
    for path in (pt, report.path):
        assert load_head_runtime(path).config.crop_norm == 0.05
    assert load_head_runtime(model_files_default()).config.crop_norm == 0.0
