"""``tools/veto_head.py``: one head's person scores, another's names for the rest, as one head."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import load_tool

from sarmission.class_roles import MARITIME_CLASSES
from sarmission.perception.head import HeadConfig, MiteHead
from sarmission.perception.runtime import OnnxHeadRuntime, save_head_checkpoint


@pytest.fixture(scope="module")
def tool():
    return load_tool("veto_head")


def _head(seed: int, path, config: HeadConfig | None = None) -> MiteHead:
    torch.manual_seed(seed)
    head = MiteHead(config).eval()
    save_head_checkpoint(head, path)
    return head


def _split_namer(path, crops: np.ndarray) -> MiteHead:
    """A random class head that names about half of ``crops`` a buoy before a person: its buoy
    bias set to the median gap between its best person logit and its buoy logit."""
    head = _head(1, path, HeadConfig(classes=MARITIME_CLASSES))
    logits, _ = _outputs(head, crops)
    gap = np.median(logits[:, :2].max(axis=1) - logits[:, 4])
    with torch.no_grad():
        head.cls_branch.fc[2].bias[4] += float(gap)
    save_head_checkpoint(head, path)
    return head


def _outputs(head: MiteHead, crops: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    with torch.no_grad():
        logits, ltrb = head(torch.from_numpy(crops))
    return logits.numpy(), ltrb.numpy()


@pytest.mark.parametrize("gate", [False, True])
def test_people_are_scored_by_the_scorer_and_the_rest_named_by_the_namer(
    tool, tmp_path, gate: bool
) -> None:
    crops = np.random.default_rng(0).random((64, 4, 16, 16), dtype=np.float32)
    scorer = _head(0, tmp_path / "scorer.pt")
    namer = _split_namer(tmp_path / "namer.pt", crops)
    out = tmp_path / "veto.onnx"
    args = ["--scorer", str(tmp_path / "scorer.pt"), "--namer", str(tmp_path / "namer.pt")]
    assert tool.main([*args, "--out", str(out), *(["--gate"] if gate else [])]) == 0
    runtime = OnnxHeadRuntime(out)
    assert runtime.classes == MARITIME_CLASSES
    logits, ltrb = runtime.predict(crops)
    scored, scored_ltrb = _outputs(scorer, crops)
    named, _ = _outputs(namer, crops)
    np.testing.assert_allclose(ltrb, scored_ltrb, atol=1e-4)
    np.testing.assert_allclose(logits[:, 2:], named[:, 2:], atol=1e-4)
    vetoed = named[:, 2:].max(axis=1) > named[:, :2].max(axis=1)
    if gate:
        assert 10 < vetoed.sum() < len(crops) - 10  # both cases, as the namer was built
        np.testing.assert_allclose(logits[~vetoed, :2], scored[~vetoed, :2], atol=1e-4)
        assert (logits[vetoed, :2] < -1e3).all()
    else:
        np.testing.assert_allclose(logits[:, :2], scored[:, :2], atol=1e-4)


def test_a_namer_of_people_only_or_of_other_crops_is_refused(tool, tmp_path, capsys) -> None:
    _head(0, tmp_path / "scorer.pt")
    _head(1, tmp_path / "people.pt")
    _head(2, tmp_path / "wide.pt", HeadConfig(classes=MARITIME_CLASSES, crop_size=24))
    _head(3, tmp_path / "land.pt", HeadConfig(classes=("person", "boat")))
    scorer = ["--scorer", str(tmp_path / "scorer.pt"), "--out", str(tmp_path / "x.onnx")]
    assert tool.main([*scorer, "--namer", str(tmp_path / "people.pt")]) == 2
    assert "names people only" in capsys.readouterr().err
    assert tool.main([*scorer, "--namer", str(tmp_path / "wide.pt")]) == 2
    assert "crop_size differs" in capsys.readouterr().err
    assert tool.main([*scorer, "--namer", str(tmp_path / "land.pt")]) == 2
    assert "does not name every person class" in capsys.readouterr().err
