"""Confirmation over seconds in the world frame: a person (still or drifting) is confirmed, sun
glint moving with the aircraft, a boat, a speck and a faint blob are discarded, short evidence
waits. Positions are built with pymap3d and seeded noise of each fix's stated error."""

import dataclasses
import math

import numpy as np
import pymap3d
import pytest

from sarmission.mission.config import ConfirmConfig
from sarmission.mission.confirmation import Sighting, TargetEvidence, assess, drift_speed

ORIGIN = (54.17, 7.89)
# the rule's shape, not its tuned defaults: a second of at least six sightings
RULE = ConfirmConfig(
    min_seen_s=1.0,
    min_sightings=6,
    min_seen_share=0.4,
    max_speed_m_s=1.5,
    min_size_m=0.15,
    max_size_m=2.5,
    min_score=0.6,
    give_up_s=20.0,
)


def sightings(
    velocity=(0.0, 0.0),
    seconds=1.5,
    fps=30.0,
    error=1.5,
    size=0.6,
    score=0.85,
    seed=0,
    bias=(0.8, -0.5),
):
    """Fixes of an object moving at ``velocity`` (m/s north, east): each fix off by a shared
    bias (GNSS) plus independent noise, together about ``error`` DRMS."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(int(seconds * fps) + 1):
        t = 100.0 + k / fps
        n = velocity[0] * (t - 100.0) + bias[0] + rng.normal(0, 0.5)
        e = velocity[1] * (t - 100.0) + bias[1] + rng.normal(0, 0.5)
        lat, lon, _ = pymap3d.ned2geodetic(n, e, 0.0, *ORIGIN, 0.0)
        out.append(Sighting(t, float(lat), float(lon), error, size, score))
    return out


def evidence_of(items):
    ev = TargetEvidence()
    for s in items:
        ev.add(s)
    return ev


@pytest.mark.parametrize("velocity", [(0.0, 0.0), (0.3, -0.4), (0.0, 1.0)])
def test_a_still_or_drifting_person_is_confirmed(velocity):
    found = assess(evidence_of(sightings(velocity)), 101.5, RULE)
    assert found.verdict == "confirm", found
    assert found.speed_m_s == pytest.approx(math.hypot(*velocity), abs=0.5)
    assert "46 sightings" in found.summary()


@pytest.mark.parametrize(
    ("kwargs", "why"),
    [
        ({"velocity": (10.0, 0.0)}, "moves 10"),  # glint under a 10 m/s aircraft
        ({"velocity": (0.0, -6.0)}, "moves 5.9"),  # a bird
        ({"size": 6.0}, "6.00 m across is no person"),  # a boat
        ({"size": 0.05}, "0.05 m across is no person"),  # a speck
        ({"score": 0.45}, "score 0.45 below 0.6"),
    ],
)
def test_clutter_is_discarded_with_the_reason(kwargs, why):
    found = assess(evidence_of(sightings(**kwargs)), 101.5, RULE)
    assert found.verdict == "discard" and why in found.reason, found


def test_short_evidence_waits_then_gives_up():
    short = evidence_of(sightings(seconds=0.5))
    assert assess(short, 100.5, RULE).verdict == "wait"
    late = assess(short, 100.0 + RULE.give_up_s + 0.1, RULE)
    # the reason says what was still missing: here a second of evidence
    assert late.verdict == "discard", late
    assert late.reason == (
        "not confirmed within 20 s (16 sightings over 0.5 s; needs 6 over 1 s)"
    ), late
    # enough evidence but no size (no ground fix at the box centre): waits, then gives up
    unsized = evidence_of(sightings(seconds=3.0, size=None))
    assert assess(unsized, 103.0, RULE).reason == "size unknown"
    late = assess(unsized, 100.0 + RULE.give_up_s + 0.1, RULE)
    assert late.verdict == "discard", late
    assert late.reason == "not confirmed within 20 s (size unknown)", late
    unplaced = TargetEvidence()
    unplaced.note_unplaced(100.0)
    assert assess(unplaced, 110.0, RULE).reason == "no position yet"
    assert "never placed" in assess(unplaced, 121.0, RULE).reason


def test_drift_speed_of_a_straight_line_and_its_error():
    speed, sigma = drift_speed(sightings((0.6, 0.8), seconds=3.0, error=0.1, bias=(0, 0)))
    assert speed == pytest.approx(1.0, abs=0.1) and sigma < 0.2
    _, wide = drift_speed(sightings((0.6, 0.8), seconds=3.0, error=5.0, bias=(0, 0)))
    assert wide > sigma  # a poor fix error widens the speed's uncertainty


def test_clutter_seen_in_few_of_the_frames_is_discarded():
    every = sightings(seconds=2.0)
    flicker = evidence_of(every[::4])  # placed in one frame of four
    flicker.frames = len(every)
    found = assess(flicker, 102.0, RULE)
    assert found.verdict == "discard" and "seen in 26 % of frames" in found.reason  # 16 of 61
    steady = evidence_of(every[::2])
    steady.frames = len(every)
    assert assess(steady, 102.0, RULE).verdict == "confirm"


def labelled(labels):
    """The standing person's sightings, the head's class of each taken from ``labels`` in turn."""
    return [
        Sighting(s.t, s.lat, s.lon, s.error_m, s.size_m, s.score, labels[i % len(labels)])
        for i, s in enumerate(sightings())
    ]


@pytest.mark.parametrize(
    ("labels", "verdict"),
    [
        (["boat"], "discard"),
        (["swimmer", "jetski"], "discard"),  # half called an object
        (["swimmer", "buoy", "swimmer"], "confirm"),
        (["life_saving_appliances"], "confirm"),
        ([""], "confirm"),  # class unknown: taken for a person
    ],
)
def test_a_target_the_head_calls_an_object_is_discarded(labels, verdict):
    found = assess(evidence_of(labelled(labels)), 101.5, RULE)
    assert found.verdict == verdict, found
    if verdict == "discard":
        assert found.reason.startswith(f"called {labels[-1]} in "), found


def improving(seconds=4.0, low=0.2, high=0.9, switch_s=2.0):
    """A person first seen poorly (score ``low``), then better (``high``) from ``switch_s`` on."""
    return [
        Sighting(s.t, s.lat, s.lon, s.error_m, s.size_m, low if s.t < 100.0 + switch_s else high)
        for s in sightings(seconds=seconds)
    ]


def test_a_score_window_waits_for_a_better_view():
    windowed = ConfirmConfig(**{**RULE.__dict__, "score_window_s": 1.0})
    first = evidence_of([s for s in improving() if s.t <= 101.5])
    # over all sightings the poor start decides at once; over the latest second it waits
    assert assess(first, 101.5, RULE).verdict == "discard"
    waiting = assess(first, 101.5, windowed)
    assert waiting.verdict == "wait" and "score 0.20 below 0.6" in waiting.reason, waiting
    later = assess(evidence_of(improving()), 104.0, windowed)
    assert later.verdict == "confirm" and later.score == pytest.approx(0.9), later
    assert assess(evidence_of(improving()), 104.0, RULE).verdict == "discard"  # mean 0.55


def test_a_score_window_still_gives_up_and_still_drops_flicker():
    windowed = ConfirmConfig(**{**RULE.__dict__, "score_window_s": 1.0})
    faint = evidence_of(sightings(seconds=3.0, score=0.45))
    assert assess(faint, 103.0, windowed).verdict == "wait"
    late = assess(faint, 100.0 + RULE.give_up_s + 0.1, windowed)
    assert late.verdict == "discard" and "score 0.45 below 0.6" in late.reason, late
    every = sightings(seconds=2.0, score=0.45)
    flicker = evidence_of(every[::4])
    flicker.frames = len(every)
    found = assess(flicker, 102.0, windowed)
    assert found.verdict == "discard" and "seen in 26 % of frames" in found.reason, found


def measured_in_first(count: int | None, **figure):
    """The standing person's sightings (box 0.6 m), ``figure`` (a :class:`Sighting` field and
    its value) measured in the first ``count`` of them (None: all)."""
    return [
        dataclasses.replace(s, **figure) if count is None or i < count else s
        for i, s in enumerate(sightings())
    ]


def measured(extent, count: int | None = None):
    """The object's extent measured in the first ``count`` sightings (None: all)."""
    return measured_in_first(count, extent_m=extent)


def test_an_object_larger_than_its_box_is_discarded_by_its_extent():
    rule = dataclasses.replace(RULE, max_extent_m=3.0)
    boat = assess(evidence_of(measured(4.2)), 101.5, rule)
    assert boat.verdict == "discard", boat
    assert boat.reason == "4.2 m across against its surroundings is no person (at most 3 m)"
    assert "extent 4.2 m" in boat.summary()
    # a person with a shadow or splash: larger than its box, within the limit
    assert assess(evidence_of(measured(3.0)), 101.5, rule).verdict == "confirm"
    # three measurements are enough to judge; two are not
    assert assess(evidence_of(measured(4.2, count=3)), 101.5, rule).verdict == "discard"
    few = assess(evidence_of(measured(4.2, count=2)), 101.5, rule)
    assert few.verdict == "confirm" and few.extent_m is None, few
    # 0: not measured, whatever the sightings carry
    off = dataclasses.replace(RULE, max_extent_m=0.0)
    assert assess(evidence_of(measured(4.2)), 101.5, off).verdict == "confirm"


def looked(change, count: int | None = None):
    """The look change measured in the first ``count`` sightings (None: all)."""
    return measured_in_first(count, look_change=change)


def test_a_steady_look_waits_when_the_rule_asks_for_a_changing_one():
    rule = dataclasses.replace(RULE, min_look_change=0.15)
    steady = assess(evidence_of(looked(0.05)), 101.5, rule)
    assert steady.verdict == "wait", steady
    assert steady.reason == "look steady over a second (change 0.05 < 0.15)"
    assert "look change 0.05" in steady.summary()
    assert assess(evidence_of(looked(0.4)), 101.5, rule).verdict == "confirm"
    # it may still change: it waits until the rule gives up, then is discarded with the reason
    late = assess(evidence_of(looked(0.05)), 100.0 + rule.give_up_s + 0.1, rule)
    assert late.verdict == "discard" and "look steady" in late.reason, late
    # three measurements are enough to judge; two are not
    assert assess(evidence_of(looked(0.05, count=3)), 101.5, rule).verdict == "wait"
    few = assess(evidence_of(looked(0.05, count=2)), 101.5, rule)
    assert few.verdict == "wait" and few.look_change is None, few
    assert few.reason == "look change not measured yet"
    assert assess(evidence_of(looked(0.4, count=3)), 101.5, rule).verdict == "confirm"
    # 0: not asked, whatever the sightings carry
    assert assess(evidence_of(looked(0.05)), 101.5, RULE).verdict == "confirm"
    # the other rules come first: a steady speck is discarded for its size, not kept waiting
    speck = [dataclasses.replace(s, size_m=0.05) for s in looked(0.05)]
    assert assess(evidence_of(speck), 101.5, rule).verdict == "discard"


def test_the_sightings_figures_are_fitted_once_per_change(monkeypatch):
    """A candidate is assessed every frame: its drift is fitted again only when its sightings
    changed, while the frames and the clock still decide on their own."""
    import sarmission.mission.confirmation as confirmation

    fits = []
    real = confirmation.drift_speed
    monkeypatch.setattr(confirmation, "drift_speed", lambda s: fits.append(len(s)) or real(s))
    items = [dataclasses.replace(s, track_id=1) for s in sightings(seconds=0.5)]
    ev = evidence_of(items)
    for frame in range(5):
        ev.frames = len(items) + frame
        assert assess(ev, 100.6 + frame / 30, RULE).verdict == "wait"
    assert fits == [len(items)]
    # with no new sighting, the clock alone gives it up
    assert assess(ev, 100.0 + RULE.give_up_s + 1.0, RULE).verdict == "discard"
    assert fits == [len(items)]
    later = dataclasses.replace(items[-1], t=items[-1].t + 0.1, track_id=2)
    ev.add(later)
    assess(ev, 100.7, RULE)
    assert fits == [len(items), len(items) + 1]
    ev.forget(2)
    found = assess(ev, 100.7, RULE)
    assert fits == [len(items), len(items) + 1, len(items)]
    assert found.sightings == len(items)
