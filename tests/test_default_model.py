"""The shipped default head, loaded the way every command loads it, finds people in a 4K maritime
clip rendered from a world it was not trained on."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sarmission.cli import main
from sarmission.models import DEFAULT_ONNX_MODEL, DEFAULT_TORCH_MODEL
from sarmission.perception.runtime import load_head_checkpoint
from sim.generate import generate_split

#: A world seed no training or validation preset uses.
UNSEEN_SEED = 4321
FRAMES = 45


@pytest.fixture(scope="module")
def unseen_clip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """45 frames of 4K maritime_test footage over a world of seed :data:`UNSEEN_SEED`."""
    return generate_split(
        "maritime_test",
        1,
        FRAMES,
        tmp_path_factory.mktemp("unseen"),
        progress=False,
        seed=UNSEEN_SEED,
    )


def test_the_shipped_files_load_as_a_small_head() -> None:
    head = load_head_checkpoint(DEFAULT_TORCH_MODEL)
    assert sum(p.numel() for p in head.parameters()) < 140_000
    assert head.config.classes == ("swimmer", "swimmer_with_life_jacket")
    assert DEFAULT_ONNX_MODEL.stat().st_size < 1_000_000


def test_the_shipped_head_locks_people_in_an_unseen_maritime_clip(unseen_clip, capsys) -> None:
    """``sarmission eval`` with no --model: the shipped ONNX head over the clip's MP4 locks most
    trajectories with few false alarms (the bounds below; docs/heldout.md has its figures)."""
    assert main(["eval", "--annotations", str(unseen_clip), "--no-progress", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    sar = report["sar"]
    assert Path(report["detector"]["model"]) == DEFAULT_ONNX_MODEL
    assert sar["n_frames"] == FRAMES and sar["n_lockable"] >= 5
    assert sar["n_locked"] >= 0.7 * sar["n_lockable"], sar
    assert sar["false_alarm_rate_detections"] < 40.0, sar
    assert report["module_recall"]["head"]["R@0.5"] > 0.5


def test_the_shipped_land_head_is_a_small_person_head_with_a_matching_onnx() -> None:
    """The land head (``model = "land"``) ships as a checkpoint and an ONNX of the same
    weights: the two runtimes give the same scores on the same crops."""
    import numpy as np

    from sarmission.models import shipped_head_path
    from sarmission.perception.runtime import load_head_runtime

    checkpoint = shipped_head_path("land", "torch")
    head = load_head_checkpoint(checkpoint)
    assert sum(p.numel() for p in head.parameters()) < 140_000
    assert head.config.classes == ("person",)
    crops = np.random.default_rng(0).random((8, 4, 16, 16), dtype=np.float32)
    torch_logits, _ = load_head_runtime("land", "torch").predict(crops)
    onnx_logits, _ = load_head_runtime("land", "onnx").predict(crops)
    assert shipped_head_path("land", "onnx").suffix == ".onnx"
    np.testing.assert_allclose(onnx_logits, torch_logits, atol=1e-4)
