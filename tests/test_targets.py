"""Target registry: one target per person, merging tracks in ground space."""

import math

import pytest

from sarmission.geo.geolocate import GeoFix
from sarmission.geo.wgs84 import ned_to_geodetic
from sarmission.mission.targets import TargetRegistry, distance_m

HOME = (54.178, 7.892)


def fix_at(north: float, east: float, error: float = 2.0) -> GeoFix:
    lat, lon, _ = ned_to_geodetic(north, east, 0.0, HOME[0], HOME[1], 0.0)
    return GeoFix(float(lat), float(lon), error, 70.0, 80.0, "ground plane at home altitude")


def ll(north: float, east: float) -> tuple[float, float]:
    lat, lon, _ = ned_to_geodetic(north, east, 0.0, HOME[0], HOME[1], 0.0)
    return float(lat), float(lon)


def test_tracks_within_radius_merge_into_one_target():
    reg = TargetRegistry(merge_radius_m=5.0)
    a, new_a = reg.observe(1, 0, 0.8, 10.0, fix_at(50, 20))
    b, new_b = reg.observe(2, 1, 0.9, 12.0, fix_at(53, 21))
    assert new_a and not new_b
    assert a is b and len(reg) == 1
    assert a.track_ids == {1, 2}
    assert a.best_score == pytest.approx(0.9)
    assert (a.first_seen, a.last_seen) == (10.0, 12.0)
    # equal errors: the mean lies halfway
    assert distance_m(a.position, ll(51.5, 20.5)) < 0.05
    assert a.error_m == pytest.approx(2.0)


def test_error_weighted_mean_favours_the_better_fix():
    reg = TargetRegistry(merge_radius_m=10.0)
    t, _ = reg.observe(1, 0, 0.8, 0.0, fix_at(0, 0, error=1.0))
    reg.observe(2, 0, 0.8, 1.0, fix_at(6, 0, error=3.0))
    # weights 1 and 1/9: north = 6 * (1/9) / (1 + 1/9) = 0.6
    assert distance_m(t.position, ll(0.6, 0.0)) < 0.05
    # fully correlated errors: (1 * 1 + 3 / 9) / (1 + 1 / 9) = 1.2, not the better fix's 1.0
    assert t.error_m == pytest.approx(1.2)


def test_targets_beyond_radius_stay_separate():
    reg = TargetRegistry(merge_radius_m=5.0)
    a, _ = reg.observe(1, 0, 0.8, 0.0, fix_at(0, 0, error=1.0))
    b, new_b = reg.observe(2, 0, 0.8, 0.0, fix_at(0, 12, error=1.0))
    assert new_b and a is not b and len(reg) == 2
    assert a.target_id != b.target_id


def test_large_errors_widen_the_merge_gate():
    reg = TargetRegistry(merge_radius_m=5.0)
    a, _ = reg.observe(1, 0, 0.8, 0.0, fix_at(0, 0, error=6.0))
    b, new_b = reg.observe(2, 0, 0.8, 0.0, fix_at(0, 8, error=6.0))  # hypot(6, 6) = 8.5 m
    assert not new_b and a is b


def test_nearest_target_wins():
    reg = TargetRegistry(merge_radius_m=6.0)
    far, _ = reg.observe(1, 0, 0.8, 0.0, fix_at(0, 0, error=0.5))
    near, _ = reg.observe(2, 0, 0.8, 0.0, fix_at(0, 10, error=0.5))
    joined, new = reg.observe(3, 0, 0.8, 10.0, fix_at(0, 6, error=0.5))
    assert not new and joined is near and joined is not far


def test_two_people_in_view_a_few_metres_apart_stay_two_targets():
    """Both seen in the same frames, 6 m apart with 1 m fixes: the statistical gate (2.8 m)
    rules, not the 8 m radius, which is for a person found again after a while."""
    reg = TargetRegistry(merge_radius_m=8.0)
    first, _ = reg.observe(1, 0, 0.8, 0.0, fix_at(0, 0, error=1.0))
    second, new = reg.observe(2, 0, 0.8, 0.0, fix_at(0, 6, error=1.0))
    assert new and second is not first
    reg.observe(1, 0, 0.8, 0.5, fix_at(0, 0, error=1.0))
    # a third track half a second later, 4 m from the first: 2.8 m + 2 m/s x 0.5 s = 3.8 m
    third, new = reg.observe(3, 0, 0.8, 1.0, fix_at(-4, 0, error=1.0))
    assert new and len(reg) == 3
    # a track on the first person again, 5 s after it was last seen there, 6 m on: joins
    again, new = reg.observe(4, 0, 0.8, 5.5, fix_at(6, -1, error=1.0))
    assert not new and again is first


def test_a_drifting_person_found_again_joins_at_their_latest_fix():
    """A swimmer drifting east at 0.5 m/s, tracked for 20 s: the mean of their fixes lies 5 m
    behind them. A new track on them just after (the first one lost them), or 7 s later 3.5 m
    on (8.4 m from the mean), joins the target by its latest fix; someone 6.5 m from that fix
    in the same instant does not."""
    reg = TargetRegistry(merge_radius_m=8.0)
    for k in range(21):
        swimmer, _ = reg.observe(1, 0, 0.9, float(k), fix_at(0, 0.5 * k, error=1.0))
    assert distance_m(swimmer.position, ll(0, 5)) < 0.05
    again, new = reg.observe(2, 0, 0.9, 20.2, fix_at(0, 10.1, error=1.0))
    assert again is swimmer and not new
    later, new = reg.observe(3, 0, 0.9, 27.2, fix_at(0, 13.6, error=1.0))
    assert later is swimmer and not new
    assert distance_m(swimmer.position, ll(0, 13.6)) > 8.0  # the mean alone would not admit it
    other, new = reg.observe(4, 0, 0.9, 27.2, fix_at(6, 16.0, error=1.0))
    assert new and other is not swimmer


def test_a_track_keeps_its_target_and_one_person_is_one_target():
    reg = TargetRegistry(merge_radius_m=5.0)
    first, _ = reg.observe(7, 1, 0.6, 0.0, fix_at(100, -40))
    # the same track drifting (current) and being seen again: same target, no new one
    for k in range(1, 10):
        target, new = reg.observe(7, 1, 0.6, float(k), fix_at(100 + 0.3 * k, -40))
        assert target is first and not new
    # the person leaves the frame and a new track picks them up on the next leg
    again, new = reg.observe(31, 0, 0.7, 40.0, fix_at(103.5, -39))
    assert again is first and not new
    assert len(reg) == 1 and first.track_ids == {7, 31}
    assert first.class_id == 1  # 10 votes for class 1, one for class 0
    assert reg.target_of(31) is first


def test_no_position_target_without_a_box_has_the_reason_and_is_never_merged():
    reg = TargetRegistry(merge_radius_m=5.0)
    placed, _ = reg.observe(1, 0, 0.8, 0.0, fix_at(0, 0))
    blind, new = reg.observe(2, 0, 0.8, 1.0, None, "telemetry stale: no position for 3.0 s")
    assert new and blind is not placed
    assert blind.position is None and blind.error_m is None
    assert "no position for 3.0 s" in blind.note
    unplaced = GeoFix(None, None, None, None, -5.0, "ray at or above the horizon")
    other, new = reg.observe(3, 0, 0.8, 2.0, unplaced)
    assert new and other.note == "ray at or above the horizon"
    # once its telemetry recovers, the track's own target gets the position
    same, new = reg.observe(2, 0, 0.8, 3.0, fix_at(30, 30))
    assert same is blind and not new and blind.position is not None
    assert len(reg) == 3


def test_seeding_from_known_targets_prevents_re_announcing():
    reg = TargetRegistry(merge_radius_m=5.0)
    reg.seed({1: ll(20, 20), 4: ll(-50, 10), 5: None})
    assert len(reg) == 3 and all(t.announced for t in reg.targets.values())
    seen, new = reg.observe(1, 0, 0.8, 0.0, fix_at(22, 19))  # track 1 of the new run
    assert not new and seen.target_id == 1
    fresh, new = reg.observe(2, 0, 0.8, 0.0, fix_at(200, 200))
    assert new and fresh.target_id == 6 and not fresh.announced
    assert math.isfinite(seen.first_seen)


def box_at(cx: float, cy: float, side: float = 12.0) -> tuple[float, float, float, float]:
    return cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2


STALE = "telemetry stale: no position for 3.0 s"


def test_reborn_track_without_position_joins_the_recent_target_in_the_image():
    reg = TargetRegistry(merge_radius_m=5.0, merge_window_s=5.0, merge_gate_px=64.0)
    first, new = reg.observe(1, 0, 0.8, 10.0, None, STALE, box=box_at(500, 300))
    assert new and first.position is None
    # the same track drifts on: its target follows the box
    reg.observe(1, 0, 0.8, 11.0, None, STALE, box=box_at(510, 302))
    # track 1 is lost; track 2 picks the person up 3 s later, 50 px from where 1 was last seen
    again, new = reg.observe(2, 1, 0.7, 14.0, None, STALE, box=box_at(545, 330))
    assert again is first and not new
    assert len(reg) == 1 and first.track_ids == {1, 2}
    assert first.box == pytest.approx(box_at(545, 330)) and first.box_time == 14.0
    assert first.position is None and first.note == STALE


def test_second_lock_on_the_same_person_in_the_same_frame_joins():
    reg = TargetRegistry()
    a, _ = reg.observe(1, 0, 0.8, 5.0, None, STALE, box=box_at(200, 200))
    b, new = reg.observe(2, 0, 0.8, 5.0, None, STALE, box=box_at(208, 196))
    assert b is a and not new and len(reg) == 1


def test_people_in_view_together_are_told_apart_in_the_image():
    """Fixes 3 m apart at +-3 m each lie within the statistical gate, but both people are in
    view in the same frame, 80 px apart: the image says two people. A second track on the
    first person (its box 5 px off) joins it."""
    reg = TargetRegistry()
    first, _ = reg.observe(1, 0, 0.8, 0.0, fix_at(0, 0, error=3.0), box=box_at(500, 300))
    second, new = reg.observe(2, 0, 0.8, 0.0, fix_at(0, 3, error=3.0), box=box_at(580, 300))
    assert new and second is not first
    duplicate, new = reg.observe(3, 0, 0.8, 0.1, fix_at(0, 0.2, error=3.0), box=box_at(505, 300))
    assert not new and duplicate is first
    # seconds later the image no longer speaks for the present: the ground decides
    later, new = reg.observe(4, 0, 0.8, 3.0, fix_at(0, 1, error=3.0), box=box_at(700, 300))
    assert not new and later is first


def test_a_person_swept_across_the_image_by_a_turn_is_one_target():
    """The drone turns towards a person: their 5 px dot crosses the image at 128 px/s, the
    tracker loses it and a new track locks 0.2 s later, 26 px on, its fix 2.3 m from the
    target's. Pending while the old box is recent; once no other track sees the person, the
    ground decides: the same person."""
    reg = TargetRegistry()
    person, _ = reg.observe(1, 0, 0.9, 0.0, fix_at(0, 0, error=1.0), box=box_at(180, 80, 5))
    reg.observe(1, 0, 0.9, 1 / 15, fix_at(0, 0, error=1.0), box=box_at(188.5, 75, 5))
    for t, x in ((0.27, 211.0), (0.33, 219.0), (0.53, 245.0)):
        assert reg.observe(2, 0, 0.9, t, fix_at(1, 2, error=1.0), box=box_at(x, 61, 5)) == (
            None,
            False,
        )
    assert reg.target_of(2) is None and person.track_ids == {1} and person.last_seen < 0.1
    again, new = reg.observe(2, 0, 0.9, 0.6, fix_at(1, 2, error=1.0), box=box_at(253, 57, 5))
    assert again is person and not new and len(reg) == 1 and person.track_ids == {1, 2}


def test_a_person_seen_just_before_elsewhere_is_another_once_seen_together():
    """The first person's track missed the frame in which a second track locks 26 px away
    (fixes 2.2 m apart): pending; in the next frame both are seen apart: two people."""
    reg = TargetRegistry()
    first, _ = reg.observe(1, 0, 0.9, 0.0, fix_at(0, 0, error=1.0), box=box_at(180, 80, 5))
    pending = reg.observe(2, 0, 0.9, 0.2, fix_at(1, 2, error=1.0), box=box_at(206, 80, 5))
    assert pending == (None, False)
    reg.observe(1, 0, 0.9, 0.27, fix_at(0, 0, error=1.0), box=box_at(180, 80, 5))
    second, new = reg.observe(2, 0, 0.9, 0.27, fix_at(1, 2, error=1.0), box=box_at(206, 80, 5))
    assert new and second is not first and len(reg) == 2


def test_without_telemetry_people_in_view_together_stay_apart_too():
    """Telemetry out: two people 40 px apart in the same frame are two targets, though 40 px
    is within the 64 px image gate for a person found again."""
    reg = TargetRegistry(merge_gate_px=64.0)
    left, _ = reg.observe(1, 0, 0.8, 0.0, None, STALE, box=box_at(100, 100))
    right, new = reg.observe(2, 0, 0.8, 0.0, None, STALE, box=box_at(140, 100))
    assert new and right is not left
    # left's track is lost; a new track 15 px on, 2 s later, is left found again
    again, new = reg.observe(3, 0, 0.8, 2.0, None, STALE, box=box_at(115, 100))
    assert not new and again is left


def test_image_merge_needs_proximity_and_a_recent_box():
    reg = TargetRegistry(merge_window_s=5.0, merge_gate_px=64.0)
    a, _ = reg.observe(1, 0, 0.8, 0.0, None, STALE, box=box_at(500, 300))
    far, new_far = reg.observe(2, 0, 0.8, 1.0, None, STALE, box=box_at(500 + 70, 300))
    assert new_far and far is not a  # 70 px > 64 px gate, and both boxes are 12 px
    late, new_late = reg.observe(3, 0, 0.8, 5.5, None, STALE, box=box_at(505, 300))
    assert new_late and late is not a  # a's box is 5.5 s old, far's 65 px away
    assert len(reg) == 3


def test_image_gate_grows_with_the_box_and_the_nearest_target_wins():
    reg = TargetRegistry(merge_gate_px=64.0)
    big, _ = reg.observe(1, 0, 0.8, 0.0, None, STALE, box=box_at(1000, 1000, side=120))
    joined, new = reg.observe(2, 0, 0.8, 1.0, None, STALE, box=box_at(1100, 1000, side=20))
    assert joined is big and not new  # 100 px apart, within the 120 px box
    left, _ = reg.observe(3, 0, 0.8, 0.0, None, STALE, box=box_at(100, 100))
    right, _ = reg.observe(4, 0, 0.8, 0.0, None, STALE, box=box_at(200, 100))
    assert left is not right
    nearest, new = reg.observe(5, 0, 0.8, 1.0, None, STALE, box=box_at(160, 100))
    assert nearest is right and not new


def test_later_fix_gives_the_unplaced_target_its_position():
    reg = TargetRegistry(merge_radius_m=5.0)
    blind, _ = reg.observe(1, 0, 0.8, 0.0, None, STALE, box=box_at(400, 400))
    placed, _ = reg.observe(2, 0, 0.8, 0.5, fix_at(500, 500), box=box_at(900, 400))
    # telemetry back: a new track on the first person, with a fix nowhere near target 2
    seen, new = reg.observe(3, 0, 0.8, 2.0, fix_at(20, 30), box=box_at(410, 395))
    assert seen is blind and not new and len(reg) == 2
    assert distance_m(blind.position, ll(20, 30)) < 0.05
    assert blind.note == "ground plane at home altitude"
    assert placed.track_ids == {2}


def test_a_fix_is_not_merged_in_the_image_with_a_target_placed_elsewhere():
    reg = TargetRegistry(merge_radius_m=5.0)
    a, _ = reg.observe(1, 0, 0.8, 0.0, fix_at(0, 0), box=box_at(400, 400))
    b, new = reg.observe(2, 0, 0.8, 1.0, fix_at(0, 30), box=box_at(410, 400))
    assert new and b is not a  # the ground says 30 m apart, whatever the image says


def test_track_without_position_joins_a_placed_target_seen_there_just_before():
    reg = TargetRegistry()
    a, _ = reg.observe(1, 0, 0.8, 0.0, fix_at(10, 10), box=box_at(400, 400))
    b, new = reg.observe(2, 0, 0.8, 2.0, None, STALE, box=box_at(420, 410))
    assert b is a and not new
    assert distance_m(a.position, ll(10, 10)) < 0.05 and a.note != STALE


@pytest.mark.parametrize(
    "kwargs", [{"merge_radius_m": -1.0}, {"merge_window_s": -0.1}, {"merge_gate_px": float("nan")}]
)
def test_negative_or_nan_settings_are_refused(kwargs):
    with pytest.raises(ValueError):
        TargetRegistry(**kwargs)


def test_a_restart_matches_known_targets_by_their_stored_error_not_a_fixed_radius():
    from sarmission.mission.targets import KnownTarget

    reg = TargetRegistry(merge_radius_m=8.0)
    reg.seed({4: KnownTarget(ll(0, 0), error_m=4.0), 5: KnownTarget(ll(200, 0), error_m=0.5)})
    # 9 m from a target stored at +-4 m, fix at +-3 m: within 2 * hypot(4, 3) = 10 m
    same, new = reg.observe(1, 0, 0.8, 0.0, fix_at(9, 0, error=3.0))
    assert not new and same.target_id == 4
    # 11 m from it: a different person
    other, new = reg.observe(2, 0, 0.8, 0.0, fix_at(0, 11, error=3.0))
    assert new and other.target_id == 6
    # a precise stored fix keeps the floor: 9 m from +-0.5 m with a +-0.5 m fix is someone else
    third, new = reg.observe(3, 0, 0.8, 0.0, fix_at(209, 0, error=0.5))
    assert new and third.target_id == 7


def test_a_known_target_without_a_stored_error_counts_as_poorly_placed():
    reg = TargetRegistry(merge_radius_m=8.0)
    reg.seed({2: ll(0, 0)})  # a bare position: error unknown
    assert reg.targets[2].error_m == pytest.approx(10.0)
    joined, new = reg.observe(1, 0, 0.8, 0.0, fix_at(15, 0, error=2.0))  # 2 * hypot(10, 2)
    assert not new and joined.target_id == 2


def test_a_track_joined_by_the_re_find_radius_yields_to_a_better_one_in_the_same_frame():
    """A person seen 20 s ago; on the next pass a sun glint 6 m off locks first and joins them
    by the 8 m re-find radius (beyond the 3.7 m statistical gate of two 1.3 m fixes); the
    person's own track locks a frame later 1.5 m from their position, 100 px from the glint's
    box. The person's track takes the target over; the glint's track leaves it (the target's
    position, latest fix and votes are the person's again) and is compared as a new track at
    its next sighting: a target of its own."""
    reg = TargetRegistry(merge_radius_m=8.0)
    for k in range(3):
        person, _ = reg.observe(1, 0, 0.9, 0.1 * k, fix_at(0, 0, 1.3), box=box_at(500, 300))
    glint, new = reg.observe(2, 1, 0.7, 20.0, fix_at(0, 6, 1.3), box=box_at(600, 300))
    assert glint is person and not new
    assert distance_m(person.position, ll(0, 0)) > 1.0  # the glint's fix pulled it
    reg.observe(2, 1, 0.7, 20.1, fix_at(0, 6, 1.3), box=box_at(600, 300))
    taker, new = reg.observe(3, 0, 0.9, 20.1, fix_at(0, 1.5, 1.3), box=box_at(515, 300))
    assert taker is person and not new
    assert reg.target_of(2) is None and reg.detached == {2: person.target_id}
    assert person.track_ids == {1, 3}
    assert distance_m(person.position, ll(0, 0.375)) < 0.05  # fixes 0, 0, 0 and 1.5
    assert person.class_votes == {0: 4} and person.best_score == pytest.approx(0.9)
    assert distance_m(person.last_fix[:2], ll(0, 1.5)) < 0.05
    again, new = reg.observe(2, 1, 0.7, 20.2, fix_at(0, 6, 1.3), box=box_at(600, 300))
    assert new and again is not person and reg.target_of(2) is again


def test_a_track_joined_within_the_statistical_gate_keeps_its_target():
    """Two people 3 m apart (within the 3.7 m gate) both in view: the one whose track locked
    first keeps the target, the other is a target of its own, however close to the first
    fix; and a track joined by the re-find radius longer ago than YIELD_S keeps it too."""
    reg = TargetRegistry(merge_radius_m=8.0)
    person, _ = reg.observe(1, 0, 0.9, 0.0, fix_at(0, 0, 1.3), box=box_at(500, 300))
    near, _ = reg.observe(2, 0, 0.9, 20.0, fix_at(0, 3, 1.3), box=box_at(560, 300))
    assert near is person
    other, new = reg.observe(3, 0, 0.9, 20.0, fix_at(0, 0.5, 1.3), box=box_at(505, 380))
    assert new and other is not person and reg.target_of(2) is person

    reg = TargetRegistry(merge_radius_m=8.0)
    person, _ = reg.observe(1, 0, 0.9, 0.0, fix_at(0, 0, 1.3), box=box_at(500, 300))
    for k in range(30):  # joined loosely, then its own for 3 s
        reg.observe(2, 0, 0.9, 20.0 + 0.1 * k, fix_at(0, 6, 1.3), box=box_at(600, 300))
    late, new = reg.observe(3, 0, 0.9, 22.9, fix_at(0, 1.0, 1.3), box=box_at(500, 300))
    assert new and late is not person and reg.target_of(2) is person


def test_a_known_targets_stored_position_is_averaged_with_new_fixes_not_replaced():
    """After a restart the stored position counts as one fix of its stored error: the first
    new fix moves the target halfway (equal errors), a better fix pulls it further, and a track
    taken back out leaves the stored position and its error as they were."""
    from sarmission.mission.targets import KnownTarget

    reg = TargetRegistry(merge_radius_m=8.0)
    reg.seed({3: KnownTarget(ll(0, 0), error_m=2.0)})
    assert distance_m(reg.targets[3].position, ll(0, 0)) < 0.01
    joined, new = reg.observe(1, 0, 0.8, 0.0, fix_at(4, 0, error=2.0))
    assert not new and joined.target_id == 3
    assert distance_m(joined.position, ll(2, 0)) < 0.05
    assert joined.error_m == pytest.approx(2.0)
    reg.observe(1, 0, 0.8, 0.1, fix_at(4, 0, error=1.0))  # weights 1/4, 1/4, 1
    assert distance_m(joined.position, ll(20 / 6, 0)) < 0.05
    assert joined.error_m == pytest.approx((0.5 + 0.5 + 1.0) / 1.5)  # weighted mean error
    joined.detach(1)
    assert distance_m(joined.position, ll(0, 0)) < 0.05
    assert joined.error_m == pytest.approx(2.0)  # the stored error again, not the track's
