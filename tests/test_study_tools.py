"""The land-head and background-only study tools: their tables are pure functions of the JSON."""

from __future__ import annotations

import dataclasses
import json
import math
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import load_tool


def _head(label: str, scored_as: str, locked: int, ssr: float, still: float) -> dict:
    return {
        "head": label,
        "scored_as": scored_as,
        "report": {
            "sar": {
                "n_locked": locked,
                "n_lockable": 17,
                "search_success_rate": ssr,  # per cent, as `sarmission eval` reports it
                "false_alarm_rate_detections": 70.0 + locked,
            },
            "module_recall": {"head": {"R@0.5": locked / 20}},
        },
        "study": {
            "scores": {"false_per_frame_above_0.5": 6.0, "false_per_frame_above_0.9": 2.0},
            "by_motion": {}
            if math.isnan(still)
            else {"still person, hovering camera": {"detected": still}},
        },
    }


def test_land_table_groups_seeds_by_recipe():
    tool = load_tool("land_head_eval")
    results = {
        "command": "c",
        "generated": "g",
        "wall_s": 1.0,
        "clips": 3,
        "frames": 40,
        "heads": [
            _head("maritime (shipped)", "person -> swimmer", 14, 82.35, 0.23),
            _head("land a", "person", 12, 70.59, 0.25),
            _head("land a_seed1", "person", 13, 76.47, 0.27),
            _head("land b", "person", 4, 23.53, math.nan),
        ],
    }
    table = tool.render(results)
    assert "| maritime (shipped) (person -> swimmer) | 14/17 | 82.3 | 84.0 | 0.70 |" in table
    assert "| land b (person) | 4/17 | 23.5 | 74.0 | 0.20 | 6.00 | 2.00 | — |" in table
    assert "| **land a**, mean of 2 seeds (min-max) | 12.5/17 | 73.5 (70.6-76.5) |" in table
    assert "**land b**" not in table  # one seed: no spread to report


def test_background_summary_counts_every_detection_as_false():
    tool = load_tool("background_eval")
    frames = [
        SimpleNamespace(scores=np.array([0.95, 0.6, 0.4])),
        SimpleNamespace(scores=np.array([0.3])),
        SimpleNamespace(scores=np.array([0.91, 0.92])),
    ]
    summary = tool.summarise(frames)
    assert summary["frames"] == 3 and summary["detections"] == 6
    assert summary["false_per_frame_above_0.5"] == 4 / 3
    assert summary["false_per_frame_above_0.9"] == 1.0
    assert summary["frames_without_any_above_0.5"] == 1 / 3
    assert summary["score_quantiles"][0] == np.percentile([0.95, 0.6, 0.4, 0.3, 0.91, 0.92], 50)
    empty = tool.summarise([])
    assert empty["score_quantiles"] is None and empty["frames_without_any_above_0.5"] is None


def test_background_table_reports_every_world_and_head():
    tool = load_tool("background_eval")
    row = {
        "frames": 120,
        "detections": 700,
        "false_per_frame_above_0.5": 5.108,
        "false_per_frame_above_0.9": 0.5166,
        "frames_without_any_above_0.5": 0.025,
        "score_quantiles": [0.8, 0.9, 0.951],
    }
    results = {
        "command": "c",
        "generated": "g",
        "wall_s": 1.0,
        "clips": 3,
        "frames": 40,
        "worlds": {"heldout_land_empty": {"shipped default": row}},
    }
    table = tool.render(results)
    assert (
        "| `heldout_land_empty` | shipped default | 120 | 5.11 | 0.52 | 2 % | 0.80 / 0.90 / 0.95 |"
        in table
    )


def _figures(locked: int, far: float, et: float) -> dict:
    return {
        "locked": locked,
        "lockable": 19,
        "far_detections": far,
        "far_frame": 4 * far,
        "head_r05": None if et is None else et / 2,
        "et_recall": et,
        "et_n": 118,
        "tiny_recall": 0.1,
        "ap_all": 0.05,
        "ms": 10.0,
    }


def test_recentring_table_puts_each_figure_beside_its_recentred_one():
    tool = load_tool("recentring_study")
    results = {
        "command": "python tools/recentring_study.py",
        "frames": 40,
        "clips": 3,
        "own_sequences": 2,
        "reused": ["a", "b", "a"],
        "rows": [
            {
                "head": "maritime",
                "split": "held-out sea, test",
                "off": _figures(11, 70.1, 0.31),
                "on": _figures(12, 66.7, None),
            }
        ],
        "offsets_head": "maritime",
        "offsets": [
            {
                "split": "held-out sea, test",
                "bands": {
                    "tiny": {
                        "n": 5,
                        "proposal_p50": 4.94,
                        "proposal_p75": 7.8,
                        "proposal_6px": 0.41,
                        "head_p50": 3.1,
                    }
                },
            }
        ],
    }
    section = tool.render_section(results)
    assert section.startswith(tool.BEGIN) and section.endswith(tool.END)
    assert "renders reused: a, b." in section  # each once, in order
    assert (
        "| maritime | held-out sea, test | 11/19 → 12/19 | 70.1 → 66.7 | 280 → 267 "
        "| 0.15 → — | 0.31 → — (118) | 0.10 → 0.10 | 0.050 → 0.050 |"
    ) in section
    assert "| held-out sea, test | tiny | 5 | 4.9 / 7.8 | 41 % | 3.1 |" in section


def test_recentring_study_names_bands_and_nearest_centres():
    tool = load_tool("recentring_study")
    assert [tool.band_of(a) for a in (64.0, 64.5, 256.0, 1024.0, 1025.0)] == [
        "extremely_tiny",
        "tiny",
        "tiny",
        "small",
        "larger",
    ]
    boxes = np.array([[0.0, 0.0, 16.0, 16.0], [20.0, 0.0, 36.0, 16.0]])
    assert tool.nearest_centre(boxes, np.array([25.0, 8.0])) == 3.0
    assert tool.nearest_centre(np.zeros((0, 4)), np.array([0.0, 0.0])) == float("inf")
    assert tool.parse_models(None) == {"maritime": "maritime", "land": "land"}
    assert tool.parse_models(["a=/x.onnx"]) == {"a": "/x.onnx"}
    with pytest.raises(SystemExit, match="NAME=PATH"):
        tool.parse_models(["/x.onnx"])


def test_size_gate_table_gives_each_measure_its_share_kept():
    tool = load_tool("size_gate")
    rule = SimpleNamespace(min_size_m=0.15, max_size_m=2.5)
    sizes = {
        ("swimmer", 0): {"across the sight": [0.5, 1.0, 2.0, 3.0], "on the ground": [4.0, 1.0]},
        ("boat", 2): {"across the sight": [6.0, 7.0], "on the ground": [6.5, 8.0]},
        ("buoy", 1): {"across the sight": [], "on the ground": [1.0]},  # nothing sized: no row
    }
    rows = tool.table(sizes, rule)
    assert rows[2].startswith("| swimmer | 3-30 | 4 |")
    assert rows[2].endswith("| 75 % | 50 % |")
    assert rows[3].startswith("| boat | 60-90 | 2 |") and rows[3].endswith("| 0 % | 0 % |")
    assert len(rows) == 4


def test_size_gate_sizes_real_boxes_by_band_with_both_measures():
    tool = load_tool("size_gate")
    from sim_vs_real import REAL

    if not REAL.is_file():
        pytest.skip(f"{REAL} not present")
    from sarmission.data.coco_video import read_coco_video

    real = read_coco_video(REAL)
    # every fourth box (each is geolocated twice; the whole file takes 20 s)
    sizes = tool.box_sizes(dataclasses.replace(real, annotations=real.annotations[::4]))
    low = sizes[("swimmer", 0)]
    assert len(low["across the sight"]) > 200
    # the ground extent stretches people seen low: larger at the median, sometimes unsized
    assert np.median(low["on the ground"]) > 1.2 * np.median(low["across the sight"])
    assert {name for name, _ in sizes} <= set(tool.CLASSES)


def test_batch_norm_statistics_are_those_of_the_footage_crops() -> None:
    """tools/bn_adaptation_study.py: a batch-norm layer's running mean becomes the mean of what
    reaches it over all the crops (two full batches: the mean of their means), its variance
    that of the crops to within the spread between the batches; the weights stay."""
    import torch

    from sarmission.perception.head import MiteHead

    study = load_tool("bn_adaptation_study")
    torch.manual_seed(0)
    model = MiteHead()
    before = {k: v.clone() for k, v in model.state_dict().items() if "running" not in k}
    crops = np.random.default_rng(0).random((2 * study.BATCH, 4, 16, 16)).astype(np.float32) * 3
    seen = []
    stem_conv, stem_bn = model.stem[0][0], model.stem[0][1]
    adapted = study.with_statistics_of(model, crops)
    assert not adapted.training
    hook = stem_conv.register_forward_hook(lambda _m, _i, out: seen.append(out.detach()))
    with torch.no_grad():
        adapted(torch.from_numpy(crops))
    hook.remove()
    out = seen[0]
    mean = out.mean(dim=(0, 2, 3))
    torch.testing.assert_close(stem_bn.running_mean, mean, rtol=1e-4, atol=1e-5)
    torch.testing.assert_close(stem_bn.running_var, out.var(dim=(0, 2, 3)), rtol=0.02, atol=1e-4)
    assert not torch.allclose(stem_bn.running_mean, torch.zeros_like(mean), atol=1e-2)
    for name, value in adapted.state_dict().items():
        if name in before and value.is_floating_point():
            torch.testing.assert_close(value, before[name])


def test_extent_study_judges_a_track_as_the_confirmation_does():
    tool = load_tool("object_extent_study")
    from sarmission.mission.config import ConfirmConfig

    rule = ConfirmConfig()  # box 0.15-2.5 m, extent at most 4 m

    def track(box_m, extents):
        return [tool.Sized(("clip", 1, 7), box_m, e, 1.0) for e in extents]

    boat = track(0.9, [4.1] * 8)
    assert tool.kept_by_gate(boat, rule) == (True, False)
    person = track(0.6, [0.7, 3.6, 0.8, None])  # one wide measurement: the median stays small
    assert tool.kept_by_gate(person, rule) == (True, True)
    rarely = track(0.9, [4.1, 4.1] + [None] * 4)  # measured twice: not judged
    assert tool.kept_by_gate(rarely, rule) == (True, True)
    assert tool.kept_by_gate(track(None, [4.1]), rule) is None
    rows = tool.table({"boat": boat, "person": person}, rule)
    assert rows[2].startswith("| boat | 8 |") and rows[2].endswith("| 1 | 100 % | 0 % |")
    assert rows[3].startswith("| person | 4 |") and rows[3].endswith("| 1 | 100 % | 100 % |")


def test_box_fit_counts_changed_boxes_and_tables_both_runs():
    tool = load_tool("box_fit_study")
    from sarmission.evaluation.matching import FrameBoxes
    from sarmission.evaluation.run_model import ModelRun

    box = np.array([[10, 10, 26, 26], [50, 50, 66, 66]], np.float32)
    wider = box.copy()
    wider[1] = [45, 50, 80, 66]
    plain, fitted = ModelRun(), ModelRun()
    plain.detections = {1: FrameBoxes.of(box, np.ones(2)), 2: FrameBoxes.of(box[:1], np.ones(1))}
    fitted.detections = {1: FrameBoxes.of(wider, np.ones(2)), 2: FrameBoxes.of(box[:1], np.ones(1))}
    assert tool._fitted(plain, fitted) == (3, 1)

    def outcome(locked: int, fitted_boxes: int) -> object:
        ssr = {f"{t:g}": (100.0 * locked / 8, locked, 8) for t in tool.NWD_THRESHOLDS}
        return tool.Outcome(ssr, 40.0, 3, fitted_boxes, 30.0, 1.5)

    lines = tool.table([("`sea` | maritime", {False: outcome(6, 0), True: outcome(7, 1)})])
    assert lines[2].startswith("| `sea` | maritime | head | 75.0 % (6/8) |")
    assert lines[3].startswith("| `sea` | maritime | fitted | 87.5 % (7/8) |")
    assert lines[3].endswith("| 33 % | 30.0 | 1.50 |") and lines[2].endswith("| - | 30.0 | - |")
    empty = tool.Outcome({f"{t:g}": (None, 0, 0) for t in tool.NWD_THRESHOLDS}, None, 0, 0, 1, 0)
    assert "| - (0/0) |" in tool.table([("`land` | maritime", {False: empty})])[2]


def test_box_fit_near_misses_are_boxes_on_a_person_too_far_off_to_match():
    tool = load_tool("box_fit_study")
    from sarmission.evaluation.matching import FrameBoxes
    from sarmission.evaluation.sar_metrics import SequenceFrame

    people = FrameBoxes.of([[100, 100, 140, 112], [300, 300, 312, 312]], ids=[1, 2])
    detections = FrameBoxes.of(
        [
            [100, 100, 140, 112],  # the first person exactly: matched at NWD 0.5
            [300, 300, 336, 336],  # 36 px around a 12 px person: near, three times too long
            [600, 600, 616, 616],  # on nobody
        ],
        [0.9, 0.8, 0.9],
    )
    near = tool.near_misses({"s": [SequenceFrame(0, people, detections)]})
    assert near["n"] == 1 and near["long"] == 1.0 and near["short"] == 0.0
    assert near["ratio_p50"] == pytest.approx(3.0) and near["long_side_px"] == 12.0
    assert tool.near_misses({"s": [SequenceFrame(0, people, FrameBoxes.empty())]}) == {"n": 0}

    ssr = {f"{t:g}": (50.0, 1, 2) for t in tool.NWD_THRESHOLDS}
    far = {"0.5": 66.7, "0.3": 66.7, "0.1": 33.3}
    measured = tool.Outcome(ssr, 66.7, 3, 0, 30.0, 0.0, far, near)
    old = tool.Outcome(ssr, 66.7, 3, 0, 30.0, 0.0)  # results kept before near misses were
    lines = tool.near_table(
        [("`sea` | maritime", {False: measured}), ("`old` | land", {False: old})]
    )
    assert len(lines) == 3
    assert lines[2] == (
        "| `sea` | maritime | head | 66.7 % / 66.7 % / 33.3 % | 1 | 0 % | 100 % (12 px) "
        "| 3.00 / 3.00 / 3.00 |"
    )
    assert tool.near_table([("`old` | land", {False: old})]) == []


def test_box_fit_scores_only_clips_with_people_as_swimmers(tmp_path):
    tool = load_tool("box_fit_study")
    categories = [{"id": 1, "name": "swimmer"}, {"id": 3, "name": "person"}]
    sea, land = tmp_path / "sea.json", tmp_path / "land.json"
    sea.write_text(json.dumps({"categories": categories, "annotations": [{"category_id": 1}]}))
    land.write_text(json.dumps({"categories": categories, "annotations": [{"category_id": 3}]}))
    assert not tool._has_people(sea) and tool._has_people(land)


def test_the_fit_cost_table_gives_the_ratio_of_the_medians():
    fit_cost = load_tool("fit_cost")
    result = {
        True: {"frame_ms": 34.5, "fit_ms": 1.7, "frames": 88},
        False: {"frame_ms": 30.0, "fit_ms": 0.0, "frames": 88},
    }
    rows = fit_cost.table(result).splitlines()
    assert rows[2] == "| fitted | 34.50 | 1.70 | 88 | 1.150 |"
    assert rows[3] == "| head's | 30.00 | 0.00 | 88 | 1 |"


def test_the_fit_cost_measures_both_settings_over_the_same_frames():
    fit_cost = load_tool("fit_cost")
    result = fit_cost.measure(blocks=4, frames=3, width=640, height=360)
    for on in (True, False):
        assert result[on]["frames"] == 8  # the last two blocks, one per setting, 2 skipped each
        assert result[on]["frame_ms"] > 0
    assert result[False]["fit_ms"] < 0.05  # off: the stage only returns
