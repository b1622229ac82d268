"""tools/review_cost.py: the review's cost per frame, figures kept against refitted, printed as
a table per flight and in all; a bad record is refused in one line."""

import json

import pytest
from conftest import load_tool
from test_confirmation_rules import BOAT, DEBRIS, FRAMES, PERSON, candidate, record

from sarmission.mission.config import ConfirmConfig

cost = load_tool("review_cost")


def test_each_mode_times_its_own_blocks_of_frames_and_counts_the_candidates():
    candidates = [c for _, c in cost.recorded(record([candidate(1, True, "wait", PERSON)]))]
    times = cost.review_times(FRAMES, candidates, ConfirmConfig(), block=10)
    # the candidate is reviewed from its first sighting until a verdict, in both modes
    assert len(times["kept"]) + len(times["refitted"]) == len(FRAMES)
    assert len(times["kept"]) == len(times["refitted"]) == len(FRAMES) // 2
    assert times["count"][0] == 1 and sum(times["count"]) < len(FRAMES)


def test_the_table_has_a_row_per_flight_and_one_in_all(tmp_path, capsys):
    path = tmp_path / "record.json"
    path.write_text(
        json.dumps(
            record(
                [
                    candidate(1, True, "discard", PERSON),
                    candidate(2, False, "discard", DEBRIS),
                    candidate(3, False, "discard", BOAT),
                ]
            )
        )
    )
    assert cost.main(["--record", str(path), "--repeats", "1", "--block", "5"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| ")]
    assert [r.split(" | ")[0] for r in rows] == ["| flight", "| dev", "| all"]


def test_a_record_that_cannot_be_read_is_one_line(tmp_path, capsys):
    with pytest.raises(SystemExit):
        cost.main(["--record", str(tmp_path / "missing.json")])
    assert "cannot read the record" in capsys.readouterr().err
