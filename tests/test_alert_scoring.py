"""Scoring alerts against truth, on hand-made frames: people in view for 3 s, found by pixel or
(washed over by a wave at the lock) by position, false alerts named after what lay under them,
duplicates, time to alert and geolocation error computed by hand."""

from dataclasses import dataclass

import pymap3d
import pytest

from sarmission.evaluation.alert_scoring import score_flight
from sarmission.evaluation.dataset_truth import TruthBox as Ann
from sarmission.evaluation.dataset_truth import TruthFrame as Frame

ORIGIN = (54.0, 7.0)


@dataclass
class Alert:
    frame_index: int
    pixel_track: list
    position: tuple[float, float] | None
    error_m: float | None = 1.0
    discarded: str | None = None
    alert_id: str = "a"
    score: float = 0.9
    class_name: str = "swimmer"
    confidence: float | None = None


def at(north: float, east: float) -> tuple[float, float]:
    lat, lon, _ = pymap3d.ned2geodetic(north, east, 0.0, *ORIGIN, 0.0)
    return float(lat), float(lon)


def frames() -> list[Frame]:
    """10 s at 10 frames/s: person 1 in view 0-5 s at pixel (100, 100), 10 m north; person 2
    in view 1-2 s only; a boat at (400, 300) throughout; person 1 hidden by a wave at 3.0 s."""
    out = []
    for k in range(100):
        t = k / 10
        targets = []
        if t < 5.0 and k != 30:
            targets.append(Ann(1, "swimmer", (95, 95, 106, 106), *at(10.0, 0.0)))
        if 1.0 <= t <= 2.0:
            targets.append(Ann(2, "swimmer", (295, 95, 306, 106), *at(10.0, 20.0)))
        out.append(Frame(k, t, targets, [Ann(9, "boat", (380, 280, 421, 321))]))
    return out


def test_found_false_duplicate_time_and_error():
    alerts = [
        (Alert(30, [(30, 100.0, 100.0)], at(12.0, 0.0)), 35, 3.5),  # washed over at its lock
        (Alert(40, [(40, 100.0, 100.0)], at(10.0, 0.0)), 45, 4.5),  # person 1 again
        (Alert(50, [(50, 400.0, 300.0)], at(50.0, 50.0)), 55, 5.5),  # the boat
        (Alert(60, [(60, 700.0, 100.0)], at(80.0, 0.0)), 65, 6.5),  # nothing there
    ]
    s = score_flight(frames(), alerts)
    assert (s.people_in_view, s.found, s.found_briefly_seen) == (1, 1, 0)
    assert (s.false_alerts, s.duplicates) == (2, 1)
    assert dict(s.false_on) == {"boat": 1, "open water": 1}
    assert s.time_to_alert_s == [pytest.approx(3.5)]  # first seen at 0 s
    assert s.geo_error_m == [pytest.approx(2.0, abs=0.01)]
    assert s.false_per_hour == pytest.approx(2 / (9.9 / 3600))


def test_a_person_seen_briefly_counts_apart():
    s = score_flight(frames(), [(Alert(15, [(15, 300.0, 100.0)], at(10.0, 20.0)), 18, 1.8)])
    assert (s.people_in_view, s.found, s.found_briefly_seen) == (1, 0, 1)
    assert s.missed == ["person 1 (4.9 s in view; never locked)"]
    candidate = Alert(20, [(20, 100.0, 100.0)], at(10.0, 0.0))
    candidate.discarded = "seen in 30 % of frames"
    clutter = Alert(60, [(60, 700.0, 100.0)], at(80.0, 0.0), alert_id="b", score=0.95)
    s = score_flight(frames(), [], candidates=[candidate, clutter], track_scores={"a": 0.8})
    assert s.missed == ["person 1 (4.9 s in view; discarded: seen in 30 % of frames)"]
    assert (s.candidate_scores, s.candidate_right) == ([0.8, 0.95], [True, False])


def test_a_life_ring_alert_over_a_life_ring_is_counted_apart():
    ring = [
        Frame(k, k / 10, [], [Ann(8, "life_saving_appliances", (195, 195, 206, 206))])
        for k in range(40)
    ]
    as_ring = Alert(10, [(10, 200.0, 200.0)], at(-10.0, 10.0), class_name="life_saving_appliances")
    as_swimmer = Alert(20, [(20, 200.0, 200.0)], at(-10.0, 10.0))
    s = score_flight(ring, [(as_ring, 15, 1.5), (as_swimmer, 25, 2.5)])
    assert (s.appliances_found, s.false_alerts) == (1, 1)
    assert s.false_on == {"life_saving_appliances": 1}
    assert s.as_dict()["appliances_found"] == 1


def test_the_position_is_scored_as_it_went_out_and_as_refined_against_its_own_error():
    """Alerted 12 m north of a person 10 m north with a 1.5 m error (2 m off: within twice it),
    refined by the flight's end to 10.5 m north with 0.2 m (0.5 m off: not within twice it)."""
    sent = Alert(40, [(40, 100.0, 100.0)], at(12.0, 0.0), error_m=1.5)
    refined = Alert(40, [(40, 100.0, 100.0)], at(10.5, 0.0), error_m=0.2)
    s = score_flight(frames(), [(sent, 45, 4.5)], final={"a": refined})
    assert s.geo_error_m == [pytest.approx(2.0, abs=0.01)]
    assert s.geo_error_final_m == [pytest.approx(0.5, abs=0.01)]
    assert (s.geo_within_2x, s.geo_within_2x_final) == ([True], [False])
    d = s.as_dict()
    assert d["geo_error_final_m"]["p50"] == pytest.approx(0.5, abs=0.01)
    assert d["geo_within_2x"] == {"at_alert": 1.0, "final": 0.0}
    # without a stored alert at the end, the one that went out is the final one
    s = score_flight(frames(), [(sent, 45, 4.5)])
    assert s.geo_error_final_m == s.geo_error_m and s.geo_within_2x_final == [True]


def test_a_refined_position_is_scored_against_where_the_person_was_in_its_frame():
    """A swimmer drifting north at 1 m/s: the alert went out at the lock (frame 10, 1 m north)
    and was refined to 8 m north in frame 80; scored against the lock's truth it would look 7 m
    off, against frame 80's it is 0."""
    drifting = [
        Frame(k, k / 10, [Ann(1, "swimmer", (95, 95, 106, 106), *at(k / 10, 0.0))], [])
        for k in range(100)
    ]
    sent = Alert(10, [(10, 100.0, 100.0)], at(1.0, 0.0), error_m=1.0)
    refined = Alert(10, [(10, 100.0, 100.0)], at(8.0, 0.0), error_m=1.0)
    s = score_flight(drifting, [(sent, 20, 2.0)], final={"a": refined}, position_frames={"a": 80})
    assert s.geo_error_m == [pytest.approx(0.0, abs=0.01)]
    assert s.geo_error_final_m == [pytest.approx(0.0, abs=0.01)]
    s = score_flight(drifting, [(sent, 20, 2.0)], final={"a": refined})
    assert s.geo_error_final_m == [pytest.approx(7.0, abs=0.01)]


def test_each_confirmed_alert_s_confidence_is_scored_against_what_lay_under_it():
    """A duplicate on a person counts as right, the boat and open water as wrong; an alert
    without a confidence is left out of the table."""
    alerts = [
        (Alert(40, [(40, 100.0, 100.0)], at(10.0, 0.0), confidence=0.8), 45, 4.5),
        (Alert(41, [(41, 100.0, 100.0)], at(10.0, 0.0), confidence=0.6), 46, 4.6),
        (Alert(50, [(50, 400.0, 300.0)], at(50.0, 50.0), confidence=0.2), 55, 5.5),
        (Alert(60, [(60, 700.0, 100.0)], at(80.0, 0.0), confidence=0.05), 65, 6.5),
        (Alert(61, [(61, 700.0, 100.0)], at(80.0, 0.0)), 66, 6.6),
    ]
    s = score_flight(frames(), alerts)
    assert list(zip(s.alert_confidences, s.alert_right, strict=True)) == [
        (0.8, True),
        (0.6, True),
        (0.2, False),
        (0.05, False),
    ]
    bins = s.as_dict()["alert_confidence_reliability"]["bins"]
    assert [(b["low"], b["n"], b["share_correct"]) for b in bins] == [
        (0.0, 1, 0.0),
        (0.1, 1, 0.0),
        (0.5, 1, 1.0),
        (0.7, 1, 1.0),
    ]
