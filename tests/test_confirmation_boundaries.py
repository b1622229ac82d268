"""Each confirmation rule probed at its boundary (:mod:`sarmission.mission.confirmation`), and the
dismissed zones just inside and outside their radius.

Sightings are exact: binary-exact times 0.25 s apart, fixes on a straight line made with pymap3d.
For five such fixes the times' spread about their mean is sum(dt^2) = 0.625 s^2, so a fit without
residuals has a velocity standard error of (fix error / sqrt 2) / sqrt(0.625) per axis, and the
speed's error sqrt 2 times that: a fix error of 0.25 * sqrt(0.625) m makes it 0.25 m/s, and the
gate "speed - 2 standard errors > limit" moves the limit up by exactly 0.5 m/s.
"""

import math

import pymap3d
import pytest

from sarmission.mission.candidates import CandidateBook
from sarmission.mission.config import ConfirmConfig
from sarmission.mission.confirmation import Sighting, TargetEvidence, assess, frames_seen

ORIGIN = (54.17, 7.89)
RULE = ConfirmConfig(
    min_seen_s=1.0,
    min_sightings=5,
    min_seen_share=0.5,
    max_speed_m_s=1.0,
    min_size_m=0.25,
    max_size_m=2.0,
    min_score=0.5,
    give_up_s=20.0,
)
#: A fix error that makes the drift speed's standard error exactly 0.25 m/s (module docstring).
ERROR_FOR_QUARTER = 0.25 * math.sqrt(0.625)


def evidence(
    times=(0.0, 0.25, 0.5, 0.75, 1.0), sizes=0.6, scores=0.8, north_m_s=0.0, error=1.0, frames=None
) -> TargetEvidence:
    """Sightings at ``100 + times``, moving north at ``north_m_s``; ``frames`` processed."""
    ev = TargetEvidence()
    n = len(times)
    sizes = [sizes] * n if not isinstance(sizes, list) else sizes
    scores = [scores] * n if not isinstance(scores, list) else scores
    for t, size, score in zip(times, sizes, scores, strict=True):
        lat, lon, _ = pymap3d.ned2geodetic(north_m_s * t, 0.0, 0.0, *ORIGIN, 0.0)
        ev.add(Sighting(100.0 + t, float(lat), float(lon), error, size, score))
    for _ in range(frames or 0):
        frames_seen(ev)
    return ev


def verdict(ev: TargetEvidence, now: float = 101.0) -> str:
    return assess(ev, now, RULE).verdict


def test_min_sightings_and_min_seen_s_at_their_boundary():
    assert verdict(evidence()) == "confirm"  # 5 sightings over exactly 1.0 s
    assert verdict(evidence(times=(0.0, 0.25, 0.5, 1.0))) == "wait"  # 4 sightings
    assert verdict(evidence(times=(0.0, 0.125, 0.25, 0.5, 0.75)), 101.0) == "wait"  # 0.75 s


@pytest.mark.parametrize(
    ("size", "expected"),
    [(2.0, "confirm"), (2.01, "discard"), (0.25, "confirm"), (0.24, "discard")],
)
def test_size_limits_are_inclusive(size, expected):
    assert verdict(evidence(sizes=size)) == expected


def test_size_is_the_median_of_the_sightings():
    # one box of a wave crest 10 m long among four of a person
    assert verdict(evidence(sizes=[0.5, 0.5, 10.0, 0.5, 0.5])) == "confirm"
    assert verdict(evidence(sizes=[0.5, 3.0, 10.0, 0.5, 3.0])) == "discard"


@pytest.mark.parametrize(("score", "expected"), [(0.5, "confirm"), (0.49, "discard")])
def test_min_score_is_inclusive(score, expected):
    assert verdict(evidence(scores=score)) == expected


@pytest.mark.parametrize(("frames", "expected"), [(10, "confirm"), (11, "discard")])
def test_seen_share_at_the_boundary(frames, expected):
    # 5 sightings in 10 frames: exactly the 50 % needed
    ev = evidence(frames=frames)
    assert ev.seen_share == 5 / frames
    assert verdict(ev) == expected


def test_give_up_after_not_at_give_up_s():
    ev = evidence(times=(0.0, 0.25))
    assert verdict(ev, 120.0) == "wait"
    assert verdict(ev, 120.25) == "discard"


@pytest.mark.parametrize(
    ("speed", "expected"), [(0.0, "confirm"), (0.6, "confirm"), (1.4, "confirm"), (1.6, "discard")]
)
def test_speed_gate_allows_two_standard_errors(speed, expected):
    # standard error 0.25 m/s: discarded only above 1.0 + 2 x 0.25 = 1.5 m/s
    found = assess(evidence(north_m_s=speed, error=ERROR_FOR_QUARTER), 101.0, RULE)
    assert found.speed_m_s == pytest.approx(speed, abs=1e-6)
    assert found.verdict == expected, found


def test_a_straight_line_of_few_fixes_keeps_the_fix_error():
    # the fit has no residuals; the fixes' own error (1 m) still bounds the velocity's error:
    # 1 / sqrt(0.625) = 1.26 m/s, so 3 m/s - 2.53 m/s is within the 1 m/s limit
    found = assess(evidence(north_m_s=3.0, error=1.0), 101.0, RULE)
    assert found.verdict == "confirm", found


class _Store:
    """What CandidateBook reads from a store when it starts."""

    def __init__(self, zones):
        self.zones = zones

    def dismissed_zones(self, mission_id):
        return list(self.zones)

    def pending_candidates(self, mission_id):
        return []

    def last_event_seq(self):
        return 0


def offset(north_m: float, east_m: float) -> tuple[float, float]:
    lat, lon, _ = pymap3d.ned2geodetic(north_m, east_m, 0.0, *ORIGIN, 0.0)
    return float(lat), float(lon)


@pytest.mark.parametrize(
    ("north", "east", "inside"),
    [
        (19.0, 0.0, True),
        (21.0, 0.0, False),
        (0.0, 19.0, True),
        (0.0, 21.0, False),
        (-13.0, -13.0, True),
        (-15.0, -15.0, False),
        (6.0, 0.0, True),
    ],
)
def test_a_dismissed_zone_suppresses_within_its_radius(north, east, inside):
    book = CandidateBook(_Store([(*ORIGIN, 20.0)]), "m", RULE)
    zone = book.suppressing(offset(north, east))
    assert (zone is not None) is inside
    assert book.suppressing(None) is None
