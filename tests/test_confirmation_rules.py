"""tools/confirmation_rules.py: a flight's candidates replayed frame by frame through a rule
give the verdict the rule gives live, and a variant's verdicts follow its own settings."""

import dataclasses
import json

import pytest
from conftest import load_tool

from sarmission.mission.config import ConfirmConfig
from sarmission.mission.confirmation import Sighting

rules = load_tool("confirmation_rules")
FPS = 10.0
FRAMES = [100.0 + k / FPS for k in range(400)]  # 40 s of reviewed frames


def track(scores, start=100.0, size=0.6):
    """A still target's sightings, one per frame from ``start``, scored ``scores`` in turn."""
    return [
        dataclasses.astuple(Sighting(start + k / FPS, 54.17, 7.89, 1.0, size, score))
        for k, score in enumerate(scores)
    ]


def record(candidates):
    return {
        "seconds": 40,
        "flights": [{"scenario": "dev", "frames": FRAMES, "candidates": candidates}],
    }


def candidate(target, person, verdict, sightings):
    return {
        "target": target,
        "person": person,
        "under": "person" if person else "debris",
        "verdict": verdict,
        "first_review": sightings[0][0],
        "first_seen": sightings[0][0],
        "sightings": sightings,
    }


# a person first seen poorly (0.5 for 3 s), then well (0.95); debris steady at 0.8; a boat
PERSON = track([0.5] * 30 + [0.95] * 60)
DEBRIS = track([0.8] * 120)
BOAT = track([0.95] * 40, size=6.0)


def test_the_defaults_replayed_give_the_flights_verdicts():
    flown = record(
        [
            candidate(1, True, "discard", PERSON),
            candidate(2, False, "discard", DEBRIS),
            candidate(3, False, "discard", BOAT),
            candidate(4, True, "confirm", track([0.9] * 40)),
        ]
    )
    rows = rules.compare(flown, [("defaults", ConfirmConfig())])
    assert rows[0]["disagree"] == 0
    assert (rows[0]["people"], rows[0]["people confirmed"]) == (2, 1)
    assert (rows[0]["clutter"], rows[0]["clutter confirmed"]) == (2, 0)
    flown["flights"][0]["candidates"][3]["verdict"] = "discard"  # the flight said otherwise
    assert rules.compare(flown, [("defaults", ConfirmConfig())])[0]["disagree"] == 1


def test_a_variant_is_judged_by_its_own_settings():
    flown = record([candidate(1, True, "discard", PERSON), candidate(2, False, "discard", DEBRIS)])
    variants = [rules.variant("window:score_window_s=2"), rules.variant("low:min_score=0.75")]
    window, low = rules.compare(flown, variants)
    assert (window["people confirmed"], window["clutter confirmed"]) == (1, 0)
    # confirmed once the latest 2 s average 0.85: 4 poor and 17 good sightings, 4.6 s in
    assert window["delay p50"] == pytest.approx(4.6, abs=0.05)
    assert (low["people confirmed"], low["clutter confirmed"]) == (0, 1)


def test_a_record_file_round_trips_and_bad_variants_are_refused(tmp_path):
    flown = record([candidate(1, True, "discard", PERSON)])
    path = tmp_path / "record.json"
    path.write_text(json.dumps(flown))
    again = json.loads(path.read_text())
    assert rules.compare(again, [("defaults", ConfirmConfig())])[0]["disagree"] == 0
    assert "| defaults | 0 of 1 | 0 of 0 |" in rules.table(
        rules.compare(again, [("defaults", ConfirmConfig())])
    )
    with pytest.raises(SystemExit, match="unknown \\[confirm\\] key 'min_scor'"):
        rules.variant("x:min_scor=0.7")
    with pytest.raises(SystemExit, match="min_score expects a number"):
        rules.variant("x:min_score=high")
