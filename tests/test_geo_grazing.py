"""Geolocation at grazing angles: the error estimate against hand-computed values, and fixes
refused near the horizon, beyond a maximum off-nadir angle or above a maximum error."""

import math

import pytest

from sarmission.geo.camera import CameraIntrinsics
from sarmission.geo.geolocate import FixLimits, PlatformPose, geolocate

INTR = CameraIntrinsics.from_hfov(1920, 1080, 70.0)
CENTRE = (INTR.cx, INTR.cy)
SIGMA_A = math.radians(0.5)


def looking_down(depression_deg: float, height_m: float = 100.0) -> PlatformPose:
    """Level drone, earth-frame gimbal: the centre pixel's ray is ``depression_deg`` below the
    horizon. No GNSS error, 1 m of altitude error, 0.5 degree of pointing error."""
    return PlatformPose(
        47.67,
        9.27,
        height_m,
        0.0,
        0.0,
        0.0,
        gimbal_rpy=(0.0, -math.radians(depression_deg), 0.0),
        gimbal_frame="earth",
        gnss_sigma_m=0.0,
        alt_sigma_m=1.0,
        attitude_sigma_rad=SIGMA_A,
    )


def hand_error(depression_deg: float, height_m: float = 100.0) -> float:
    """DRMS written out: slant range t = h / sin(d); along the ray's ground track the pointing
    error moves the point sigma_a t / sin(d) and the altitude error sigma_h / tan(d); across it
    the pointing error moves it sigma_a t."""
    d = math.radians(depression_deg)
    t = height_m / math.sin(d)
    along_pointing = SIGMA_A * t / math.sin(d)
    along_height = 1.0 / math.tan(d)
    across = SIGMA_A * t
    return math.sqrt(along_pointing**2 + along_height**2 + across**2)


@pytest.mark.parametrize(
    ("depression_deg", "expected_m"),
    [
        # (d, DRMS by hand): 30 deg: t = 200 m, 3.491 along, 1.732 height, 1.745 across -> 4.270
        (30.0, 4.270),
        # 10 deg: t = 575.9 m, 28.94 along, 5.671 height, 5.026 across -> 29.92
        (10.0, 29.92),
        # 5 deg: t = 1147.4 m, 114.9 along, 11.43 height, 10.01 across -> 115.9
        (5.0, 115.9),
    ],
)
def test_error_estimate_matches_the_hand_computed_value(depression_deg, expected_m):
    fix = geolocate(CENTRE, INTR, looking_down(depression_deg))
    assert fix.ok, fix.note
    assert fix.depression_deg == pytest.approx(depression_deg, abs=1e-6)
    assert fix.error_m == pytest.approx(hand_error(depression_deg), rel=1e-6)
    assert fix.error_m == pytest.approx(expected_m, rel=2e-3)


def test_error_grows_towards_the_horizon():
    errors = [geolocate(CENTRE, INTR, looking_down(d)).error_m for d in (90, 60, 30, 15, 5, 2)]
    assert all(b > a for a, b in zip(errors, errors[1:], strict=False)), errors
    assert errors[-1] > 50 * errors[0]


def test_a_ray_within_three_pointing_sigmas_of_the_horizon_is_no_fix():
    fix = geolocate(CENTRE, INTR, looking_down(1.2))  # 3 x 0.5 deg = 1.5 deg
    assert not fix.ok and fix.error_m is None
    assert "within 3 pointing sigmas" in fix.note and "range unbounded" in fix.note
    assert geolocate(CENTRE, INTR, looking_down(1.6)).ok
    assert geolocate(CENTRE, INTR, looking_down(1.2), limits=FixLimits(horizon_sigmas=2.0)).ok


def test_maximum_off_nadir_angle():
    limits = FixLimits(max_off_nadir_deg=80.0)
    fix = geolocate(CENTRE, INTR, looking_down(9.0), limits=limits)  # 81 deg off nadir
    assert not fix.ok and fix.note.startswith(
        "ray 81.0 deg from straight down (a fix needs at most 80; error estimate"
    )
    assert geolocate(CENTRE, INTR, looking_down(11.0), limits=limits).ok


def test_maximum_error():
    limits = FixLimits(max_error_m=20.0)
    fix = geolocate(CENTRE, INTR, looking_down(10.0), limits=limits)  # 29.9 m by hand
    assert not fix.ok and fix.note.startswith("error estimate 30 m (a fix needs at most 20 m")
    assert geolocate(CENTRE, INTR, looking_down(30.0), limits=limits).ok  # 4.3 m
