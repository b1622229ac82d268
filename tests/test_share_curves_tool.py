"""``tools/share_curves.py``: object curves of renders with other people counts, as shares."""

from __future__ import annotations

import json

import pytest
from conftest import load_tool

THRESHOLDS = [0.3, 0.5, 0.7, 0.9]


@pytest.fixture(scope="module")
def tool():
    return load_tool("share_curves")


def _result(swimmers, jackets, buoys, debris, altitude=None) -> dict:
    """A stripped results file: each class as (objects, called per threshold)."""

    def row(entry):
        return {"objects": entry[0], "called": entry[1]}

    return {
        "command": "python tools/heldout_eval.py ...",
        "generated": "2026-12-02T00:00:00+00:00",
        "settings": {"altitude_m": altitude, "ds": 2},
        "splits": {
            "heldout_maritime": {
                "module_recall": {"rpn": {"R@0.1": 0.9}},
                "study": {
                    "object_curve": {
                        "thresholds": THRESHOLDS,
                        "classes": {
                            "swimmer": row(swimmers),
                            "swimmer_with_life_jacket": row(jackets),
                            "buoy": row((1, [1, 1, 1, 0])),  # on the people's sea: not counted
                        },
                    }
                },
            },
            "heldout_maritime_clutter": {
                "module_recall": {"rpn": {"R@0.1": 0.0}},
                "study": {
                    "object_curve": {
                        "thresholds": THRESHOLDS,
                        "classes": {"buoy": row(buoys), "debris": row(debris)},
                    }
                },
            },
        },
    }


def test_shares_are_of_each_group_s_own_objects(tool) -> None:
    curve = tool.shares(
        _result((6, [6, 5, 3, 1]), (4, [4, 4, 4, 0]), (10, [8, 6, 4, 0]), (10, [2, 2, 0, 0]))
    )
    people_total, people = curve["groups"]["people"]
    assert people_total == 10 and people == pytest.approx([1.0, 0.9, 0.7, 0.1])
    assert curve["groups"]["jackets"][1] == pytest.approx([1.0, 1.0, 1.0, 0.0])
    assert curve["groups"]["distractors"] == (20, pytest.approx([0.5, 0.4, 0.2, 0.0]))
    assert curve["groups"]["buoys"][1] == pytest.approx([0.8, 0.6, 0.4, 0.0])


def test_distractors_are_read_where_the_people_share_is_nearest(tool) -> None:
    curve = tool.shares(
        _result((10, [9, 8, 4, 1]), (0, [0, 0, 0, 0]), (10, [9, 5, 2, 0]), (0, [0] * 4))
    )
    assert tool.at_people_share(curve, 0.75) == (0.5, pytest.approx(0.8), pytest.approx(0.5))
    assert tool.at_people_share(curve, 0.6) == (0.7, pytest.approx(0.4), pytest.approx(0.2))
    jackets = tool.shares(
        _result((10, [9, 8, 4, 1]), (0, [0, 0, 0, 0]), (1, [1] * 4), (0, [0] * 4))
    )
    assert jackets["groups"]["jackets"] == (0, [pytest.approx(float("nan"), nan_ok=True)] * 4)


def test_the_page_compares_each_render_with_the_reference_at_equal_people(tool, tmp_path) -> None:
    ref = tmp_path / "ref.json"
    low = tmp_path / "low.json"
    ref.write_text(
        json.dumps(_result((10, [9, 8, 6, 1]), (0, [0] * 4), (10, [9, 6, 4, 0]), (0, [0] * 4)))
    )
    low.write_text(
        json.dumps(
            _result((20, [18, 12, 8, 2]), (0, [0] * 4), (10, [5, 2, 1, 0]), (0, [0] * 4), [35, 55])
        )
    )
    doc = tmp_path / "page.md"
    doc.write_text("# Page\n\nkept text\n")
    assert tool.main(["--doc", str(doc), f"ref={ref}", f"low={low}"]) == 0
    text = doc.read_text()
    assert text.startswith("# Page\n\nkept text\n")
    ref_row = next(line for line in text.splitlines() if line.startswith("| `ref`"))
    low_row = next(line for line in text.splitlines() if line.startswith("| `low`"))
    assert ref_row.endswith("| 40 % (0.7, 60 %) |")
    assert low_row.endswith("| 20 % (0.5, 60 %) |") and "| 35-55 | 2 | 1 S |" in low_row
    assert tool.main(["--doc", str(doc), f"ref={ref}"]) == 0
    assert text.count(tool.BEGIN) == 1 and doc.read_text().count(tool.BEGIN) == 1


def test_bad_arguments_get_one_line(tool, tmp_path, capsys) -> None:
    doc = tmp_path / "page.md"
    assert tool.main(["--doc", str(doc), "no-label"]) == 2
    assert "expected LABEL=FILE.json" in capsys.readouterr().err
    assert tool.main(["--doc", str(doc), f"a={tmp_path / 'missing.json'}"]) == 2
    assert "not readable" in capsys.readouterr().err
    assert not doc.exists()


def test_a_whole_results_file_is_read_and_kept_stripped(tool, tmp_path) -> None:
    """A ``heldout_results.json`` as the evaluation writes it (the front-end's recall inside
    each split's report, more keys beside) reads as its stripped form; ``--keep`` writes that
    form, which reads back to the same page, and a sized crop's settings name it."""
    stripped = _result((10, [9, 8, 6, 1]), (0, [0] * 4), (10, [9, 6, 4, 0]), (0, [0] * 4))
    stripped["settings"] = {"ds": 2, "crop_scales": [1.0], "person_m": 0.45, "range_shift": 0.5}
    whole = json.loads(json.dumps(stripped))
    whole["renders_reused"] = []
    for split in whole["splits"].values():
        split["report"] = {"module_recall": split.pop("module_recall"), "sar": {}}
        split["study"]["scores"] = {}
    full = tmp_path / "full.json"
    full.write_text(json.dumps(whole))
    assert tool.stripped(whole) == stripped
    doc, kept = tmp_path / "page.md", tmp_path / "kept"
    assert tool.main(["--doc", str(doc), "--keep", str(kept), f"sized={full}"]) == 0
    assert json.loads((kept / "sized.json").read_text()) == stripped
    page = doc.read_text()
    assert "| 1 S, sized to 0.45 m, shift 0.5 |" in page
    assert tool.main(["--doc", str(doc), f"sized={kept / 'sized.json'}"]) == 0
    assert doc.read_text() == page
