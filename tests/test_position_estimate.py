"""Where a target is as of its latest fix: still people at the mean of the recent fixes,
drifting people followed along their drift, fixes that jump faster than a person moves not
taken for a drift, and an error that holds the truth as often as it says."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from sarmission.geo.wgs84 import ned_to_geodetic
from sarmission.mission.position_estimate import WINDOW_S, latest_position
from sarmission.mission.targets import distance_m

ORIGIN = (54.17, 7.89)
HZ = 30.0


@dataclass(frozen=True)
class Fix:
    t: float
    lat: float
    lon: float
    error_m: float


def at(north: float, east: float) -> tuple[float, float]:
    lat, lon, _ = ned_to_geodetic(north, east, 0.0, *ORIGIN, 0.0)
    return float(lat), float(lon)


def fixes(truth_ne, noise_ne, seconds: float, error_m: float = 1.5) -> list[Fix]:
    """One fix per frame: ``truth_ne(t)`` plus ``noise_ne[k]`` (metres)."""
    t = np.arange(int(seconds * HZ)) / HZ
    ne = np.array([truth_ne(x) for x in t], float) + noise_ne[: len(t)]
    lat, lon, _ = ned_to_geodetic(ne[:, 0], ne[:, 1], 0.0, *ORIGIN, 0.0)
    return [Fix(float(a), float(b), float(c), error_m) for a, b, c in zip(t, lat, lon, strict=True)]


def test_a_still_person_is_at_the_mean_of_the_recent_fixes_only():
    rng = np.random.default_rng(1)
    noise = rng.normal(0.0, 1.0, (1200, 2))
    noise[: int((40 - WINDOW_S - 1) * HZ)] += (30.0, 0.0)  # old fixes, 30 m off: out of the window
    est = latest_position(fixes(lambda t: (5.0, -3.0), noise, 40.0))
    assert est is not None and not est.drifting
    assert distance_m(est.position, at(5.0, -3.0)) < 0.3
    assert est.t == pytest.approx(1199 / HZ)
    # never below the fixes' own error: they share the pose's, which averaging cannot remove
    assert est.error_m >= 1.5


def test_a_drifting_person_is_followed_to_where_they_are_now():
    """0.5 m/s east for 60 s: the estimate is at the latest fix's true place; the window's mean
    lies 5 m behind it, the whole flight's 15 m."""
    rng = np.random.default_rng(2)
    noise = rng.normal(0.0, 1.0, (1800, 2))
    est = latest_position(fixes(lambda t: (0.0, 0.5 * t), noise, 60.0))
    assert est is not None and est.drifting
    now = 0.5 * 1799 / HZ
    assert distance_m(est.position, at(0.0, now)) < 0.6
    assert est.velocity_ne == pytest.approx((0.0, 0.5), abs=0.05)
    assert distance_m(est.position, at(0.0, now)) <= 2.0 * est.error_m


def test_fixes_that_move_faster_than_a_person_are_no_drift():
    """Fixes sliding east at 4 m/s for 20 s (a pose error, not a swimmer): no drift is
    followed; the target is taken as still, with their scatter (23 m) as its error."""
    est = latest_position(fixes(lambda t: (0.0, 4.0 * t), np.zeros((600, 2)), 20.0))
    assert est is not None and not est.drifting
    assert est.error_m == pytest.approx(4.0 * 20.0 / np.sqrt(12), rel=0.05)


def test_a_jump_of_the_fixes_widens_the_error_to_cover_it():
    """Every fix 12 m east in the window's last 2 s (a GNSS jump): the line through the window
    takes it for a slow drift, and its error still holds the truth within twice itself."""
    noise = np.zeros((600, 2))
    noise[540:] += (0.0, 12.0)
    est = latest_position(fixes(lambda t: (0.0, 0.0), noise, 20.0))
    assert est is not None and est.error_m >= 3.0
    assert distance_m(est.position, at(0.0, 0.0)) <= 2.0 * est.error_m


def test_few_fixes_give_the_latest_one():
    assert latest_position([]) is None
    one = [Fix(0.0, *at(1.0, 1.0), 2.0), Fix(0.1, *at(2.0, 2.0), 3.0)]
    est = latest_position(one)
    assert est.position == at(2.0, 2.0) and est.error_m == pytest.approx(2.5)


def test_the_error_holds_the_truth_with_wandering_pose_errors():
    """Fixes whose error wanders with the pose (Gauss-Markov, 1.5 m per axis, 2 s), some of the
    people drifting at up to 0.6 m/s: the truth lies within twice the stated error in at least
    90 % of 200 estimates, and the stated error is no wider than needed (the median error is
    under 1.2 of the stated)."""
    rng = np.random.default_rng(3)
    within, ratio = 0, []
    phi = np.exp(-1 / (HZ * 2.0))
    for trial in range(200):
        seconds = rng.uniform(3.0, 40.0)
        n = int(seconds * HZ)
        noise = np.zeros((n, 2))
        noise[0] = rng.normal(0, 1.5, 2)
        for k in range(1, n):
            noise[k] = phi * noise[k - 1] + rng.normal(0, 1.5 * np.sqrt(1 - phi**2), 2)
        v = rng.uniform(-0.6, 0.6, 2) if trial % 2 else np.zeros(2)
        est = latest_position(fixes(lambda t, v=v: v * t, noise, seconds, error_m=2.1))
        truth = at(*(v * (n - 1) / HZ))
        err = distance_m(est.position, truth)
        within += err <= 2.0 * est.error_m
        ratio.append(err / est.error_m)
    assert within >= 180
    assert np.median(ratio) < 1.2
