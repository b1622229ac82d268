"""``tools/object_curves.py``: heads compared at equal people taken, from results JSONs."""

from __future__ import annotations

import json

import pytest
from conftest import load_tool

THRESHOLDS = [0.5, 0.6, 0.7, 0.8]


@pytest.fixture(scope="module")
def tool():
    return load_tool("object_curves")


def _results(swimmers: list[int], jackets: list[int], buoys: list[int], debris: list[int]):
    def split(classes):
        return {"study": {"object_curve": {"thresholds": THRESHOLDS, "classes": classes}}}

    return {
        "splits": {
            "heldout_maritime": split(
                {
                    "swimmer": {"objects": 6, "called": swimmers},
                    "swimmer_with_life_jacket": {"objects": 4, "called": jackets},
                    "buoy": {"objects": 3, "called": [3, 3, 3, 3]},  # not counted as clutter
                }
            ),
            "heldout_maritime_clutter": split(
                {
                    "buoy": {"objects": 20, "called": buoys},
                    "debris": {"objects": 30, "called": debris},
                }
            ),
        }
    }


def test_people_and_clutter_add_up_per_threshold(tool) -> None:
    curve = tool.head_curve(_results([6, 5, 3, 1], [4, 3, 2, 0], [15, 10, 6, 2], [9, 5, 1, 0]))
    assert (curve["people"], curve["clutter"], curve["buoys"]) == (10, 50, 20)
    assert curve["people_taken"] == [10, 8, 5, 1]
    assert curve["clutter_taken"] == [24, 15, 7, 2]
    assert curve["buoys_taken"] == [15, 10, 6, 2]


def test_a_head_is_read_at_the_highest_threshold_that_takes_enough_people(tool) -> None:
    curve = tool.head_curve(_results([6, 5, 3, 1], [4, 3, 2, 0], [15, 10, 6, 2], [9, 5, 1, 0]))
    assert tool.at_people(curve, 5) == {"threshold": 0.7, "people": 5, "clutter": 7, "buoys": 6}
    assert tool.at_people(curve, 6)["threshold"] == 0.6
    assert tool.at_people(curve, 11) is None


def test_the_page_ranks_a_sharper_head_below_a_louder_one(tool, tmp_path) -> None:
    """Two heads taking the same people: the one that takes less clutter there reads lower,
    though at one threshold it takes more of both."""
    loud = tmp_path / "loud.json"
    sharp = tmp_path / "sharp.json"
    loud.write_text(json.dumps(_results([6, 5, 3, 1], [4, 3, 2, 0], [15, 10, 6, 2], [9, 5, 1, 0])))
    sharp.write_text(json.dumps(_results([6, 6, 5, 3], [4, 4, 3, 2], [16, 9, 3, 1], [9, 3, 1, 0])))
    doc = tmp_path / "page.md"
    assert tool.main([f"loud={loud}", f"sharp={sharp}", "--doc", str(doc)]) == 0
    page = doc.read_text()
    # 8 of 10 people: loud at 0.6 takes 15 distractors, sharp at 0.7 takes 4
    assert "| loud | 7 (6) at 0.70 | 7 (6) at 0.70 | 15 (10) at 0.60 | 15 (10) at 0.60 |" in page
    assert "| sharp | 1 (1) at 0.80 | 1 (1) at 0.80 | 4 (3) at 0.70 | 4 (3) at 0.70 |" in page
    assert "| loud | 10 / 24 | 8 / 15 | 5 / 7 | 1 / 2 |" in page
    # the text around the tables is kept when they are written again
    doc.write_text("# Mine\n\nWhat it shows.\n\n" + page)
    assert tool.main([f"sharp={sharp}", "--doc", str(doc)]) == 0
    again = doc.read_text()
    assert again.startswith("# Mine\n\nWhat it shows.") and "| loud |" not in again
    assert again.count("| sharp | 10 / 25 |") == 1


def test_bad_results_give_one_clear_line(tool, tmp_path, capsys) -> None:
    empty = tmp_path / "empty.json"
    empty.write_text(json.dumps({"splits": {}}))
    assert tool.main([f"x={empty}"]) == 2
    assert "no object curve for heldout_maritime" in capsys.readouterr().err
    assert tool.main(["no-label"]) == 2
    assert "expected LABEL=RESULTS_JSON" in capsys.readouterr().err
    assert tool.main([f"x={tmp_path / 'missing.json'}"]) == 2
    assert "cannot read results" in capsys.readouterr().err
    other = tmp_path / "other.json"
    other.write_text(json.dumps(_results([1] * 4, [1] * 4, [1] * 4, [1] * 4)))
    fewer = json.loads(other.read_text())
    fewer["splits"]["heldout_maritime"]["study"]["object_curve"]["classes"]["swimmer"][
        "objects"
    ] = 2
    odd = tmp_path / "odd.json"
    odd.write_text(json.dumps(fewer))
    assert tool.main([f"a={other}", f"b={odd}"]) == 2
    assert "not on the same clips" in capsys.readouterr().err
