"""``tools/ensemble_head.py``: several heads as one ONNX head averaging their probabilities."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import load_tool

from sarmission.perception.head import HeadConfig, MiteHead
from sarmission.perception.runtime import OnnxHeadRuntime, save_head_checkpoint


@pytest.fixture(scope="module")
def tool():
    return load_tool("ensemble_head")


def _head(seed: int, path, config: HeadConfig | None = None):
    torch.manual_seed(seed)
    head = MiteHead(config).eval()
    save_head_checkpoint(head, path)
    return head


def test_the_ensemble_scores_the_mean_probability_of_its_members(tool, tmp_path) -> None:
    heads = [_head(s, tmp_path / f"h{s}.pt") for s in (0, 1, 2)]
    out = tmp_path / "mean.onnx"
    assert tool.main([*(str(tmp_path / f"h{s}.pt") for s in (0, 1, 2)), "--out", str(out)]) == 0
    crops = np.random.default_rng(0).random((5, 4, 16, 16), dtype=np.float32)
    logits, ltrb = OnnxHeadRuntime(out).predict(crops)
    with torch.no_grad():
        outs = [h(torch.from_numpy(crops)) for h in heads]
    mean_p = np.mean([torch.sigmoid(o[0]).numpy() for o in outs], axis=0)
    np.testing.assert_allclose(1 / (1 + np.exp(-logits)), mean_p, atol=1e-5)
    np.testing.assert_allclose(ltrb, np.mean([o[1].numpy() for o in outs], axis=0), atol=1e-4)
    # and not merely one member's
    assert np.abs(1 / (1 + np.exp(-logits)) - torch.sigmoid(outs[0][0]).numpy()).max() > 1e-3


def test_members_of_other_classes_are_refused(tool, tmp_path, capsys) -> None:
    _head(0, tmp_path / "a.pt")
    _head(1, tmp_path / "b.pt", HeadConfig(classes=("swimmer", "boat")))
    assert tool.main([str(tmp_path / "a.pt"), str(tmp_path / "b.pt"), "--out", "x.onnx"]) == 2
    assert "configuration differs" in capsys.readouterr().err
    assert tool.main([str(tmp_path / "a.pt"), "--out", "x.onnx"]) == 2
    assert "two heads or more" in capsys.readouterr().err
