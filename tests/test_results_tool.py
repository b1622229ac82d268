"""``tools/results.py``: the results page is a pure function of the measured numbers."""

from __future__ import annotations

import pytest
from conftest import load_tool


@pytest.fixture(scope="module")
def tool():
    module = load_tool("results")
    return module


def _band(n_gt, ap, ar, f2):
    return {"n_gt": n_gt, "n_detections": 2 * n_gt, "ap": ap, "ar": ar, "f2": f2}


def _run(ds, ssr, far_det, far_frame, avg_t, max_t, ms, bands, rpn, head):
    return {
        "ds": ds,
        "topn": 25,
        "frames": 120,
        "skipped_frames": 0,
        "median_ms": ms,
        "fps": 1e3 / ms,
        "sar": {
            "search_success_rate": ssr,
            "false_alarm_rate_detections": far_det,
            "false_alarm_rate_per_frame": far_frame,
            "avg_search_time_frames": avg_t,
            "max_search_time_frames": max_t,
            "n_locked": 8,
            "n_trajectories": 10,
        },
        "boxes": {"bands": bands},
        "module_recall": {"rpn": rpn, "head": head},
        "dataset": {"n_videos": 2, "n_frames": 120, "n_gt_boxes": 900},
        "gflops": {"vstmd": 0.30, "rpn_other": 0.02, "head": 0.20, "total": 0.52},
        "parameters": 140_000,
    }


def _results(sweep=None):
    maritime_bands = {
        "extremely_tiny": _band(300, 0.1111, 0.2222, 0.3333),
        "tiny": _band(400, 0.5555, 0.6666, 0.7777),
        "small": _band(50, 0.4444, 0.4545, 0.4646),
        "all": _band(750, 0.0101, 0.0202, 0.0303),
    }
    urban_bands = {b: _band(100, 0.2, 0.3, 0.25) for b in maritime_bands}
    return {
        "command": "python tools/results.py --frames 60 --sequences 2",
        "generated": "2025-01-02T03:04:05+00:00",
        "machine": {
            "nproc": 2,
            "cpu": "Test CPU 9000",
            "python": "3.11.7",
            "platform": "Linux-test",
        },
        "settings": {
            "frames": 60,
            "sequences": 2,
            "size": [3840, 2160],
            "fps": 30.0,
            "model": "shipped default model",
            "runtime": "onnx",
            "topn": 25,
            "conf": 0.3,
            "ego_motion": "estimate",
            "m": 3,
            "k": 5,
            "score_thr": 0.5,
            "nwd_thr": 0.5,
        },
        "splits": {
            "maritime_test": {
                "preset": {"seed": 3003, "description": "dense sea"},
                "runs": {
                    "2": _run(
                        2,
                        80.0,
                        50.0,
                        123.45,
                        12.5,
                        40,
                        250.0,
                        maritime_bands,
                        {"R@0.1": 0.8123, "R@0.5": 0.7001},
                        {"R@0.1": 0.5123, "R@0.5": 0.4321},
                    ),
                    "8": _run(
                        8,
                        83.33,
                        90.0,
                        300.0,
                        20.0,
                        50,
                        120.0,
                        maritime_bands,
                        {"R@0.1": 0.6, "R@0.5": 0.5},
                        {"R@0.1": 0.4, "R@0.5": 0.3},
                    ),
                },
            },
            "urban_test": {
                "preset": {"seed": 6006, "description": "city"},
                "runs": {
                    "2": _run(
                        2,
                        50.0,
                        99.9,
                        500.0,
                        30.0,
                        59,
                        260.0,
                        urban_bands,
                        {"R@0.1": 0.3, "R@0.5": 0.2},
                        {"R@0.1": 0.1, "R@0.5": 0.05},
                    ),
                },
            },
        },
        "sweep": sweep,
        "definitions": {
            "false_alarm_rate_per_frame": "unmatched detections / frames",
            "false_alarm_rate_detections": "unmatched / detections",
        },
    }


def _line(md: str, *parts: str) -> str:
    hits = [line for line in md.splitlines() if all(p in line for p in parts)]
    assert hits, f"no line with {parts}"
    return hits[0]


def _section(md: str, start: str, end: str | None = None) -> str:
    text = md[md.index(start) :]
    return text[: text.index(end)] if end else text


def test_header_says_how_it_was_produced(tool):
    md = tool.render_results_md(_results())
    assert "`python tools/results.py --frames 60 --sequences 2`" in md
    assert "2025-01-02T03:04:05+00:00" in md
    assert "Test CPU 9000" in md and "2 CPU core(s)" in md
    assert "seed 3003" in md and "seed 6006" in md
    assert "2 clip(s) x 60 frames at 3840x2160" in md


def test_sar_rows_hold_measured_and_published_numbers(tool):
    md = tool.render_results_md(_results())
    maritime = _section(md, "### `maritime_test` vs SeaDroneSee-Tiny", "### `urban_test`")
    assert _line(maritime, "Search Success Rate (%)").split("|")[2:6] == [
        " 80.00 ",
        " 100.00 ",
        " 83.33 ",
        " 83.33 ",
    ]
    assert "| 50.00 | 67.72 | 90.00 | 82.29 |" in _line(maritime, "per detection (%)")
    assert "| 123.45 | — | 300.00 | — |" in _line(maritime, "per frame (%)")
    assert "| 40 | 299 | 50 | 119 |" in _line(maritime, "Max Search Time")
    assert "| 250.00 | 32.97 | 120.00 | 19.11 |" in _line(maritime, "Latency")
    urban = _section(md, "### `urban_test` vs UAVID-Tiny", "## 2.")
    assert "| 50.00 | 8.33 | not run | 0.00 |" in _line(urban, "Search Success Rate (%)")
    assert "| 8/10 | — |" in _line(maritime, "Trajectories locked")  # older JSON: no n_lockable
    results = _results()
    results["splits"]["maritime_test"]["runs"]["2"]["sar"]["n_lockable"] = 9
    maritime = _section(tool.render_results_md(results), "### `maritime_test`", "### `urban_test`")
    assert "| 8/10 (9 lockable) | — |" in _line(maritime, "Trajectories locked")


def test_statements_follow_the_numbers(tool):
    md = tool.render_results_md(_results())
    maritime = _section(md, "### `maritime_test` vs SeaDroneSee-Tiny", "### `urban_test`")
    assert "**Worse** — SSR at ds=2: 80.00 % here vs 100.00 % in the paper." in maritime
    assert "**On par** — SSR at ds=8: 83.33 % here vs 83.33 % in the paper." in maritime
    assert "**Better** — FAR per detection at ds=2: 50.00 % here vs 67.72 %" in maritime
    assert "**Worse** — FAR per detection at ds=8: 90.00 % here vs 82.29 %" in maritime
    assert "**Better** — Avg. search time at ds=2: 12.50 frames here vs 69.00 frames" in maritime
    assert "**Worse** — Latency at ds=2: 250.00 ms" in maritime
    assert "Apples-to-oranges" in _line(maritime, "Latency at ds=2")
    urban = _section(md, "### `urban_test` vs UAVID-Tiny", "## 2.")
    assert "**Better** — SSR at ds=2: 50.00 % here vs 8.33 % in the paper." in urban
    assert "**Worse**" not in _line(urban, "SSR at ds=2")


def test_ssr_shortfall_counts_the_unlocked_trajectories(tool):
    results = _results()
    sar = results["splits"]["maritime_test"]["runs"]["2"]["sar"]
    sar.update(
        m=3,
        k=5,
        unlocked=[
            {"n_frames": 1, "n_hits": 0},
            {"n_frames": 7, "n_hits": 3},
            {"n_frames": 150, "n_hits": 1},
        ],
    )
    line = _line(tool.render_results_md(results), "**Worse** — SSR at ds=2")
    assert (
        "3 trajectories not locked: 1 annotated in fewer than 3 frames (no detector can "
        "lock it), 1 with 3 or more hits that never fall inside one 5-frame window, 1 with "
        "fewer than 3 hits."
    ) in line
    sar.update(unlocked=[{"n_frames": 1, "n_hits": 0}])
    line = _line(tool.render_results_md(results), "**Worse** — SSR at ds=2")
    assert (
        "1 trajectory not locked: 1 annotated in fewer than 3 frames (no detector can lock "
        "it). The RPN's"
    ) in line
    assert "come within NWD 0.1 of 81 % of the target boxes" in line


def test_box_table_and_statements(tool):
    md = tool.render_results_md(_results())
    boxes = _section(md, "## 2.", "## 3.")
    row = _line(boxes, "| extremely tiny")
    assert "| 300 | 600 | 0.1111 | 0.27 | 0.2222 | 0.47 | 0.3333 | 0.30 |" in row
    assert "| 0.5555 | 0.38 | 0.6666 | 0.48 | 0.7777 | 0.40 |" in _line(boxes, "| tiny (")
    assert "| 0.4444 | — | 0.4545 | — | 0.4646 | — |" in _line(boxes, "| small")
    assert "**Worse** — AP (extremely tiny): 0.11 here vs 0.27" in boxes
    assert "**Better** — AP (tiny): 0.56 here vs 0.38" in boxes
    assert "**Worse** — AR (all): 0.02 here vs 0.48" in boxes


def test_module_recall_rows_and_statements(tool):
    md = tool.render_results_md(_results())
    module = _section(md, "## 4.", "## Definitions")
    assert "| 0.8123 | 0.9584 | 0.7001 | 0.5812 |" in _line(module, "TTM-RPN", "maritime_test")
    assert "| 0.5123 | 0.7377 | 0.4321 | 0.7072 |" in _line(module, "head", "maritime_test")
    assert "| 0.3000 | 0.1047 | 0.2000 | 0.0580 |" in _line(module, "TTM-RPN", "urban_test")
    assert "**Worse** — TTM-RPN (no category) R@0.1 on `maritime_test`" in module
    assert "**Better** — TTM-RPN (no category) R@0.5 on `maritime_test`" in module
    assert "**Better** — R-CNN-like head (category) R@0.1 on `urban_test`" in module


def test_scalability_from_main_runs_and_from_sweep(tool):
    md = tool.render_results_md(_results())
    scal = _section(md, "## 3.", "## 4.")
    assert "the main runs (no `--sweep` in this run)" in scal
    assert _line(scal, "| 2 | 25 |").startswith("| 2 | 25 | 80.00 | 100.00 | 50.00 (123.45) |")
    assert "| 1 | 25 | not run | 100.00 |" in scal
    sweep = [
        {
            "ds": ds,
            "topn": n,
            "ssr": 100.0 if ds < 8 else 90.0,
            "far_detections": far,
            "far_per_frame": 2 * far,
            "median_ms": 100.0,
            "fps": 10.0,
            "gflops": {"vstmd": 0.4 / ds, "rpn_other": 0.02, "head": 0.1, "total": 0.5},
        }
        for ds, n, far in ((2, 10, 20.0), (2, 50, 60.0), (2, 25, 40.0), (8, 25, 70.0))
    ]
    scal = _section(tool.render_results_md(_results(sweep)), "## 3.", "## 4.")
    assert "the `--sweep` run" in scal
    assert _line(scal, "| 2 | 10 |").startswith("| 2 | 10 | 100.00 | 100.00 | 20.00 (40.00) |")
    assert "**Better** — FAR per detection at ds=2, N=10: 20.00 % here vs 35.41 %" in scal
    assert "**Worse** — SSR at ds=8, N=25: 90.00 % here vs 83.33 %" not in scal
    assert "**Better** — SSR at ds=8, N=25: 90.00 % here vs 83.33 %" in scal
    assert "from 20.00 % at N=10 to 60.00 % at N=50 (rises with N" in scal
    assert "SSR 100.00 % at ds=2 and 90.00 % at ds=8 (drops" in scal
    assert "Head GFLOPs overtake vSTMD GFLOPs at ds=8 " in scal


def test_verdict(tool):
    assert tool.verdict(80.0, 100.0, True, 0.5) == "worse"
    assert tool.verdict(50.0, 67.72, False, 0.5) == "better"
    assert tool.verdict(100.0, 100.0, True, 0.5) == "on par"
    assert tool.verdict(None, 1.0, True, 0.5) is None


def test_split_notes(tool):
    results = _results()
    results["splits"]["urban_test"]["category_as_class"] = {"person": "swimmer"}
    results["splits"]["urban_test"]["runs"]["2"]["dataset"]["n_gt_boxes"] = 0
    urban = _section(tool.render_results_md(results), "### `urban_test` vs UAVID-Tiny", "## 2.")
    assert "category `person` is scored as the head's class `swimmer`" in urban
    assert "No ground-truth target in these frames" in urban


def test_colour_section_sets_the_variants_side_by_side(tool):
    results = _results()
    assert "1b. Colour proposals" not in tool.render_results_md(results)  # older JSON: no runs
    results["settings"]["colour_share"] = 0.4
    results["splits"]["maritime_test"]["motion_only"] = _run(
        2,
        60.0,
        30.0,
        100.0,
        25.0,
        59,
        240.0,
        {},
        {"R@0.1": 0.5512, "R@0.5": 0.2},
        {"R@0.1": 0.4412, "R@0.5": 0.3},
    )
    md = tool.render_results_md(results)
    assert "N = 25 proposals (40% of them from colour anomalies" in md
    section = _section(md, "## 1b. Colour proposals", "## 2.")
    mixed = _line(section, "`maritime_test`, motion + colour, single crop").split("|")[2:9]
    paper = _line(section, "`maritime_test`, motion only (paper), single crop").split("|")[2:9]
    assert mixed == [" 80.00 ", " 8/10 ", " 50.00 ", " 12.50 ", " 0.8123 ", " 0.5123 ", " 250.00 "]
    assert paper == [" 60.00 ", " 8/10 ", " 30.00 ", " 25.00 ", " 0.5512 ", " 0.4412 ", " 240.00 "]
    assert "`urban_test`" not in section  # no motion-only run there
    assert "crops S and 2 S" not in section and "colour, every proposal" not in section
    results["splits"]["maritime_test"]["second_look"] = _run(
        2,
        95.0,
        45.0,
        700.0,
        5.0,
        44,
        260.0,
        {},
        {"R@0.1": 0.8123, "R@0.5": 0.2},
        {"R@0.1": 0.8012, "R@0.5": 0.3},
    )
    results["splits"]["maritime_test"]["refine_all"] = _run(
        2,
        70.0,
        35.0,
        600.0,
        6.0,
        44,
        270.0,
        {},
        {"R@0.1": 0.8123, "R@0.5": 0.2},
        {"R@0.1": 0.7012, "R@0.5": 0.3},
    )
    section = _section(tool.render_results_md(results), "## 1b. Colour proposals", "## 2.")
    two = _line(section, "`maritime_test`, motion + colour, crops S and 2 S").split("|")[2:9]
    every = _line(section, "`maritime_test`, motion + colour, every proposal").split("|")[2:9]
    assert every == [" 70.00 ", " 8/10 ", " 35.00 ", " 6.00 ", " 0.8123 ", " 0.7012 ", " 270.00 "]
    assert two == [" 95.00 ", " 8/10 ", " 45.00 ", " 5.00 ", " 0.8123 ", " 0.8012 ", " 260.00 "]
    # a JSON of the days when the second look was the default: the single crop beside it
    results["settings"]["crop_scales"] = [1.0, 2.0]
    split = results["splits"]["maritime_test"]
    split["single_crop"] = split.pop("second_look")
    section = _section(tool.render_results_md(results), "## 1b. Colour proposals", "## 2.")
    main = _line(section, "`maritime_test`, motion + colour, crops S and 2 S").split("|")[2:9]
    one = _line(section, "`maritime_test`, motion + colour, single crop (paper)").split("|")[2:9]
    assert main == mixed and one == two


def test_a_single_crop_run_measures_the_second_look_beside_it(tool):
    single = tool.ds2_variants([1.0])
    assert single["second_look"][1] == {"crop_scales": [1.0, 2.0]}
    assert "single_crop" not in single
    assert tool.ds2_variants([1.0, 2.0])["single_crop"][1] == {"crop_scales": [1.0]}
    for scales in ([1.0], [1.0, 2.0]):
        refine = tool.ds2_variants(scales)["refine_all"][1]
        assert refine == {"crop_scales": [1.0, 2.0], "refine_threshold": 0.0}
