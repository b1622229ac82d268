"""Alert scoring's limits probed at their boundary: the pixel match radius (box centres in pixel
coordinates, half a pixel in from the edges' mean), the position match's gate (3 x the alert's
error when larger than 5 m) and its window on both sides of the lock, the gap that still
continues a stretch in view, and the least time in view. Frames are 0.25 s apart, so the times
and their differences are exact."""

import pytest
from test_alert_scoring import Alert, Ann, Frame, at

from sarmission.evaluation.alert_scoring import score_flight

STEP = 0.25
#: Box whose centre is pixel (100, 100): edges' mean 100.5, less half a pixel.
BOX = (95, 95, 106, 106)


def flight(visible, seconds=8.0, place=(10.0, 0.0)) -> list[Frame]:
    """Frames every 0.25 s with person 1 (box BOX, ``place`` north/east metres) wherever
    ``visible(t)``."""
    out = []
    for k in range(int(seconds / STEP)):
        t = k * STEP
        targets = [Ann(1, "swimmer", BOX, *at(*place))] if visible(t) else []
        out.append(Frame(k, t, targets, []))
    return out


def always(t):
    return True


@pytest.mark.parametrize(("u", "found"), [(124.0, 1), (124.5, 0), (76.0, 1), (75.5, 0)])
def test_pixel_match_radius_is_inclusive_from_the_true_centre(u, found):
    s = score_flight(flight(always), [(Alert(8, [(8, u, 100.0)], None), 8, 2.0)])
    assert (s.found, s.false_alerts) == (found, 1 - found)


@pytest.mark.parametrize(("error", "found"), [(3.0, 1), (2.5, 0), (1.0, 0)])
def test_position_match_gate_grows_with_the_alert_error(error, found):
    # pixel far from the person; the fix 8 m south of them: within 3 x 3 m, not 3 x 2.5 m
    alert = Alert(8, [(8, 600.0, 400.0)], at(2.0, 0.0), error_m=error)
    s = score_flight(flight(always), [(alert, 8, 2.0)])
    assert (s.found, s.false_alerts) == (found, 1 - found)


@pytest.mark.parametrize(("last_seen", "found"), [(1.5, 1), (1.25, 0)])
def test_position_match_looks_back_within_the_window(last_seen, found):
    # lock at 3.5 s; the person was last in a frame at ``last_seen``; the window reaches 1.5 s
    alert = Alert(14, [(14, 600.0, 400.0)], at(10.0, 0.0))
    s = score_flight(flight(lambda t: t <= last_seen), [(alert, 14, 3.5)])
    assert (s.found + s.found_briefly_seen, s.false_alerts) == (found, 1 - found)


@pytest.mark.parametrize(("first_seen", "found"), [(5.5, 1), (5.75, 0)])
def test_position_match_looks_ahead_within_the_window(first_seen, found):
    alert = Alert(14, [(14, 600.0, 400.0)], at(10.0, 0.0))
    s = score_flight(flight(lambda t: t >= first_seen), [(alert, 14, 3.5)])
    assert (s.found + s.found_briefly_seen, s.false_alerts) == (found, 1 - found)


@pytest.mark.parametrize(("gap_from", "gap_to", "in_view"), [(1.5, 2.0, 1), (1.5, 2.25, 0)])
def test_a_gap_of_max_gap_s_continues_the_stretch(gap_from, gap_to, in_view):
    # seen 0-1.5 s and from ``gap_to`` to 3.5 s; a gap of exactly 0.5 s keeps one 3.5 s stretch
    s = score_flight(flight(lambda t: t <= gap_from or gap_to <= t <= 3.5), [])
    assert s.people_in_view == in_view


@pytest.mark.parametrize(("until", "in_view"), [(3.0, 1), (2.75, 0)])
def test_in_view_for_exactly_min_view_s_counts(until, in_view):
    s = score_flight(flight(lambda t: t <= until), [])
    assert s.people_in_view == in_view
