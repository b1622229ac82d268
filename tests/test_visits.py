"""Move gate (bounded error, inside the area plus a margin) and the visit plan (one move per
interval, nearest first, neighbours covered). Distances here are built with pymap3d."""

import pymap3d
import pytest

from sarmission.mission.visits import MoveGate, VisitPlanner

ORIGIN = (43.0, 10.0)
AREA = [(0.0, 0.0), (0.0, 300.0), (300.0, 300.0), (300.0, 0.0)]  # north, east metres


def at(north: float, east: float) -> tuple[float, float]:
    lat, lon, _ = pymap3d.ned2geodetic(north, east, 0.0, *ORIGIN, 0.0)
    return float(lat), float(lon)


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


@pytest.mark.parametrize(
    ("position", "error", "refusal"),
    [
        (at(150, 150), 5.0, ""),
        (at(150, 330), 5.0, ""),  # 30 m outside, margin 50 m
        (at(150, 360), 5.0, "60 m outside the mission area"),
        (at(-23_500, 150), 1.0, "23500 m outside the mission area"),
        (at(150, 150), 41.0, "position error 41 m exceeds 40 m"),
        (at(150, 150), None, "position error unknown"),
        (at(150, 150), float("nan"), "position error unknown"),
        (None, 1.0, "no position"),
    ],
)
def test_move_gate(position, error, refusal):
    gate = MoveGate(AREA, ORIGIN, max_error_m=40.0, margin_m=50.0)
    got = gate.refusal(position, error)
    assert (got == "") == (refusal == "")
    assert refusal in got


def test_one_visit_per_interval_nearest_first_neighbours_covered():
    clock = Clock()
    plan = VisitPlanner(min_interval_s=60.0, group_radius_m=30.0, clock=clock)
    for target_id, ne in ((1, (200, 0)), (2, (50, 0)), (3, (60, 10)), (4, (400, 0))):
        assert plan.add(target_id, at(*ne))
    first = plan.next_visit(aircraft=at(0, 0))
    assert first.target_id == 2 and first.covered == (2, 3)  # 3 is 14 m from 2
    assert plan.next_visit(aircraft=at(0, 0)) is None  # too soon
    clock.t += 59.0
    assert plan.next_visit(aircraft=at(0, 0)) is None
    assert plan.seconds_to_next() == pytest.approx(1.0)
    clock.t += 1.0
    assert plan.next_visit(aircraft=at(500, 0)).target_id == 4  # nearest to where it is now
    assert not plan.add(2, at(51, 0))  # already visited
    clock.t += 60.0
    assert plan.next_visit(aircraft=None).target_id == 1
    assert plan.next_visit() is None and not plan.pending


def test_sixteen_alerts_in_ten_seconds_make_one_move():
    clock = Clock()
    plan = VisitPlanner(min_interval_s=60.0, clock=clock)
    moves = []
    for k in range(16):
        plan.add(k, at(10.0 * k, 0))
        clock.t += 10.0 / 16
        visit = plan.next_visit(at(0, 0))
        if visit is not None:
            moves.append(visit)
    assert len(moves) == 1


def test_tour_orders_every_pending_target_once_per_interval():
    clock = Clock()
    plan = VisitPlanner(min_interval_s=60.0, group_radius_m=5.0, clock=clock)
    for target_id, ne in ((1, (300, 0)), (2, (100, 0)), (3, (200, 0))):
        plan.add(target_id, at(*ne))
    tour = plan.tour(aircraft=at(0, 0))
    assert [v.target_id for v in tour] == [2, 3, 1]
    plan.add(9, at(0, 50))
    assert plan.tour(at(0, 0)) == []  # within the interval
    clock.t += 60.0
    assert [v.target_id for v in plan.tour(at(0, 0))] == [9]
