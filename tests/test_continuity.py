"""A track that joined a target after it was out of sight places it only once it has evidence
of its own, and how far its fixes lie from the target's trajectory stays in the target's error."""

import pytest

from sarmission.geo.geolocate import GeoFix
from sarmission.geo.wgs84 import ned_to_geodetic
from sarmission.mission import continuity
from sarmission.mission.confirmation import Sighting
from sarmission.mission.targets import TargetRegistry

ORIGIN = (54.17, 7.89)
ERROR_M = 1.5
RATE_HZ = 10.0


def at(north: float, east: float) -> tuple[float, float]:
    lat, lon, _ = ned_to_geodetic(north, east, 0.0, *ORIGIN, 0.0)
    return float(lat), float(lon)


def sightings(track: int, t0: float, seconds: float, north, east=lambda t: 0.0) -> list[Sighting]:
    """A track's fixes at :data:`RATE_HZ` from ``t0``; ``north``/``east`` are metres as
    functions of time."""
    out = []
    for i in range(int(seconds * RATE_HZ)):
        t = t0 + i / RATE_HZ
        lat, lon = at(north(t), east(t))
        out.append(Sighting(t, lat, lon, ERROR_M, 0.5, 0.9, "swimmer", track))
    return out


def registered(*tracks: list[Sighting]) -> tuple[TargetRegistry, list[Sighting]]:
    """The tracks' sightings through a registry, in time order, as the controller feeds it."""
    registry = TargetRegistry()
    merged = sorted((s for track in tracks for s in track), key=lambda s: s.t)
    for s in merged:
        fix = GeoFix(s.lat, s.lon, s.error_m, 70.0, 90.0, "ground plane")
        registry.observe(s.track_id, 0, s.score, s.t, fix)
    return registry, merged


def test_the_track_that_starts_a_target_and_one_seen_moments_later_continue_it():
    registry, seen = registered(
        sightings(1, 0.0, 3.0, lambda t: 0.0),
        sightings(2, 3.2, 0.3, lambda t: 0.3),  # re-locked 0.2 s after the first was lost
    )
    (target,) = registry.targets.values()
    assert all(continuity.continues(s) for s in target.shares.values())
    assert continuity.placing(target, seen) == seen
    assert continuity.ambiguity_m(target) == 0.0


def test_a_track_after_a_gap_places_nothing_until_it_has_evidence_of_its_own():
    """Found again 5 s later 1 m away: its first second counts for nothing, then it continues
    the target (the same person: no jump)."""
    first = sightings(1, 0.0, 3.0, lambda t: 0.0)
    again = sightings(2, 8.0, 3.0, lambda t: 1.0)
    registry, seen = registered(first, again)
    (target,) = registry.targets.values()
    share = target.shares[2]
    assert share.gap_s == pytest.approx(5.1) and share.fixes == len(again)
    assert not continuity.continues(share)
    assert continuity.placing(target, seen) == first
    # not yet: 20 fixes are needed over 2 s
    assert continuity.check(target, 2, seen, min_fixes=40, min_span_s=2.0) is None
    assert share.jump_m is None
    assert continuity.check(target, 2, seen, min_fixes=20, min_span_s=2.0) == 0.0
    assert continuity.continues(share) and continuity.ambiguity_m(target) == 0.0
    assert continuity.placing(target, seen) == seen
    # done once
    assert continuity.check(target, 2, seen, min_fixes=20, min_span_s=2.0) is None


def test_a_second_person_where_a_drifting_one_was_last_seen_stays_in_the_error():
    """The first drifts north at 0.5 m/s for 20 s and is lost; 16 s later a still person sits
    where the first was last seen: the registry joins them (within its gate of the latest
    fix). The first, had they kept drifting, would be 9 m further north, farther than the
    drift's uncertainty carries: the track's fixes lie that far from the target's trajectory,
    and the target's positions carry it."""
    drifting = sightings(1, 0.0, 20.0, lambda t: 0.5 * t)
    still = sightings(2, 36.0, 4.0, lambda t: 10.0)
    registry, seen = registered(drifting, still)
    (target,) = registry.targets.values()
    assert not target.shares[2].loose
    jump = continuity.check(target, 2, seen, min_fixes=20, min_span_s=1.9)
    # by the end of the track's first 20 fixes (37.9 s) the first would be at 18.95 m
    assert jump == pytest.approx(18.95 - 10.0, abs=0.3)
    assert continuity.ambiguity_m(target) == jump
    assert continuity.continues(target.shares[2])


def test_a_drift_followed_across_the_gap_is_no_jump():
    drifting = sightings(1, 0.0, 20.0, lambda t: 0.5 * t)
    again = sightings(2, 26.0, 4.0, lambda t: 0.5 * t)
    registry, seen = registered(drifting, again)
    (target,) = registry.targets.values()
    assert continuity.check(target, 2, seen, min_fixes=20, min_span_s=1.9) == 0.0


def test_a_person_short_of_where_the_drift_points_stays_in_the_error():
    """A drift of 0.5 m/s fitted over 20 s of 1.5 m fixes, carried 18 s past the last: a
    track 4 m short of where it points fits the drift's uncertainty, but lies beyond its own
    fixes' gate (3 m): the same person slowed, or someone else; the 4 m stay in the error."""
    drifting = sightings(1, 0.0, 20.0, lambda t: 0.5 * t)
    short = sightings(2, 36.0, 4.0, lambda t: 0.5 * t - 4.0)
    registry, seen = registered(drifting, short)
    (target,) = registry.targets.values()
    # its own first 2 s are too short to follow its drift: their mean lags it by 0.5 m
    assert continuity.check(target, 2, seen, min_fixes=20, min_span_s=1.9) == pytest.approx(
        4.5, abs=0.2
    )


def test_only_continuing_tracks_count_as_the_target_before_a_join():
    """A glint joined after a gap and was never confirmed by evidence of its own: the next
    track is compared with the person's fixes, not with the glint's."""
    person = sightings(1, 0.0, 4.0, lambda t: 0.0)
    glint = sightings(2, 6.0, 0.5, lambda t: 3.0)
    again = sightings(3, 9.0, 3.0, lambda t: 0.0)
    registry, seen = registered(person, glint, again)
    (target,) = registry.targets.values()
    assert set(target.shares) == {1, 2, 3}
    assert continuity.check(target, 2, seen, min_fixes=20, min_span_s=2.0) is None
    assert continuity.check(target, 3, seen, min_fixes=20, min_span_s=2.0) == 0.0
    assert continuity.placing(target, seen) == person + again


def test_a_loose_join_never_places_the_target():
    person = sightings(1, 0.0, 3.0, lambda t: 0.0)
    # 7 m away 3 s later: beyond the statistical gate, within the re-find radius
    loose = sightings(2, 6.0, 4.0, lambda t: 7.0)
    registry, seen = registered(person, loose)
    (target,) = registry.targets.values()
    assert target.shares[2].loose
    assert continuity.check(target, 2, seen, min_fixes=20, min_span_s=2.0) is None
    assert not continuity.continues(target.shares[2])
    assert continuity.placing(target, seen) == person


def test_jump_without_fixes_on_either_side_is_none_found():
    track = sightings(1, 0.0, 3.0, lambda t: 0.0)
    assert continuity.jump_m([], track, 20, 2.0) == 0.0
    assert continuity.jump_m(track, [], 20, 2.0) == 0.0
    far = sightings(2, 5.0, 3.0, lambda t: 10.0)
    assert continuity.jump_m(track, far, 20, 2.0) == pytest.approx(10.0, abs=1e-6)
    near = sightings(2, 5.0, 3.0, lambda t: 2.0 * ERROR_M - 0.1)
    assert continuity.jump_m(track, near, 20, 2.0) == 0.0
    beyond = sightings(2, 5.0, 3.0, lambda t: 2.0 * ERROR_M + 0.1)
    assert continuity.jump_m(track, beyond, 20, 2.0) == pytest.approx(2.0 * ERROR_M + 0.1)
