"""``tools/generalisation_study.py``: heads sharing one vSTMD pass detect what each would alone,
and the page is a pure function of the measured numbers."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import load_tool
from synthetic_video import write_dataset

from sarmission.data.coco_video import read_coco_video
from sarmission.evaluation.run_model import run_mitenet
from sarmission.perception.head import HeadConfig, MiteHead
from sarmission.perception.mitenet import MiteNet
from sarmission.perception.runtime import TorchHeadRuntime
from sarmission.perception.types import DEFAULT_CROP_SCALES


@pytest.fixture(scope="module")
def tool():
    module = load_tool("generalisation_study")
    return module


def _head(seed: int) -> TorchHeadRuntime:
    torch.manual_seed(seed)
    head = MiteHead(HeadConfig()).eval()
    with torch.no_grad():  # a bias that lets some crops score above the threshold
        for module in head.modules():
            if isinstance(module, torch.nn.Linear) and module.out_features == 2:
                module.bias.fill_(1.0)
    return TorchHeadRuntime(head)


def test_shared_pass_detects_what_each_head_detects_alone(tool, tmp_path) -> None:
    """Each head at its own crop scales (the same head at two settings gives two runs)."""
    dataset = read_coco_video(write_dataset(tmp_path / "d", n_videos=2, n_frames=6, seed=3))
    heads = {"a": _head(0), "b": _head(1), "a_wide": _head(0)}
    scales = {"a_wide": (1.0, 2.0), "b": None}
    shared = tool.run_heads(heads, dataset, scales)
    total = 0
    for name, head in heads.items():
        alone = run_mitenet(
            MiteNet(
                head,
                ds=2,
                topn=25,
                score_threshold=0.3,
                crop_scales=scales.get(name) or DEFAULT_CROP_SCALES,
            ),
            dataset,
            progress=False,
        )
        assert list(alone.detections) == list(shared[name].detections)
        for image_id, det in alone.detections.items():
            other = shared[name].detections[image_id]
            np.testing.assert_array_equal(det.boxes, other.boxes)
            np.testing.assert_array_equal(det.scores, other.scores)
            np.testing.assert_array_equal(det.class_ids, other.class_ids)
            total += len(det.boxes)
    assert total > 0
    for other in ("b", "a_wide"):
        assert any(
            not np.array_equal(shared["a"].detections[i].scores, shared[other].detections[i].scores)
            for i in shared["a"].detections
        )
    with pytest.raises(ValueError, match="first crop scale"):
        tool.run_heads(heads, dataset, {"b": (2.0,)})


def _split(ssr, far, r05, ap=None, et=None):
    """One split's figures; AP and ET recall left out as in runs tested before they existed."""
    return ({} if ap is None else {"ap_all": ap, "et_recall": et}) | {
        "ssr": ssr,
        "far_det": far,
        "head_r05": r05,
        "head_r01": r05,
        "rpn_r01": 0.8,
        "locked": 3,
        "lockable": 4,
    }


def test_page_reports_mean_and_range_over_seeds(tool) -> None:
    runs = {}
    for seed, (own, sea) in enumerate(((90.0, 10.0), (80.0, 30.0), (100.0, None))):
        runs[f"baseline/seed{seed}"] = {
            "variant": "baseline",
            "seed": seed,
            "checkpoint": "x",
            "best_epoch": 7,
            "val_f2": 0.25,
            "train_crops": 5000,
            "train_s": 120.0,
            "test": {
                "maritime_test": _split(own, 20.0, 0.5, *((0.1, 0.3) if seed < 2 else ())),
                "heldout_maritime": _split(sea, 90.0, 0.1),
                "heldout_land": _split(5.0, 99.0, 0.0),
            },
        }
    results = {
        "command": "python tools/generalisation_study.py --seeds 0,1,2",
        "generated": "2026-01-01T00:00:00+00:00",
        "wall_s": 600.0,
        "machine": {"nproc": 2},
        "settings": {
            "seeds": [0, 1, 2],
            "variants": ["baseline"],
            "train": {
                "epochs": 20,
                "select_from": 5,
                "batch_size": 64,
                "lr": 0.02,
                "frame_stride": 3,
                "jitters_per_gt": 4,
                "ds": 1,
            },
            "test_frames": 40,
            "test_clips": {"maritime_test": 2},
        },
        "variants": {
            "baseline": {
                "description": "maritime",
                "presets": [["maritime_train", 3, 40, "3840x2160"]],
                "randomise": "none",
                "background_negatives": 0,
            }
        },
        "runs": runs,
        "shipped": {
            "maritime_test": _split(93.9, 12.0, 0.72),
            "heldout_maritime": _split(16.7, 98.0, 0.04),
            "heldout_land": _split(38.5, 97.0, 0.06),
        },
    }
    md = tool.render_section(results)
    assert md.startswith(tool.BEGIN) and md.endswith(tool.END)
    assert (
        "| `baseline` | 3 | 90.0 (80.0-100.0) | 20.0 (20.0-20.0) | 0.50 (0.50-0.50) "
        "| 0.100 (0.100-0.100) | 0.30 (0.30-0.30) | 20.0 (10.0-30.0) |" in md
    )
    assert "| 93.9 | 12.0 | 0.72 | — | — |" in md
    assert "`python tools/generalisation_study.py --seeds 0,1,2`" in md
    assert (
        "| `baseline/seed2` | 7 | 0.250 | 5000 | 2.0 | 3/4 | 3/4 | 3/4 | 100.0 | 20.0 "
        "| 0.50 | — | — | — |" in md
    )
    assert tool.spread([None, None]) is None
    assert tool.spread([1.0, 3.0, None]) == (2.0, 1.0, 3.0)
    assert "Background only" not in md  # no run measured it

    for seed, (land, sea) in enumerate(((5.0, 1.0), (3.0, 0.5), (4.0, 0.3))):
        runs[f"baseline/seed{seed}"]["test"] |= {
            "heldout_land_empty": {
                "false_per_frame_above_0.5": land,
                "false_per_frame_above_0.9": land / 10,
            },
            "heldout_maritime_empty": {
                "false_per_frame_above_0.5": sea,
                "false_per_frame_above_0.9": None,
            },
        }
    md = tool.render_section(results)
    assert "### Background only" in md
    assert "| `baseline` | 3 | 4.00 (3.00-5.00) | 0.40 (0.30-0.50) | 0.60 (0.30-1.00) | — |" in md
