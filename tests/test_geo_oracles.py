"""Geolocation against truths that do not come from ``sarmission.geo``.

Three kinds: cases worked by hand (a camera looking east at 45 degrees from 100 m sees the
ground 100 m east), a ray-trace written here from first principles (axis rotations by
Rodrigues' formula, the plane met by similar triangles) over many poses in every gimbal frame,
and pymap3d's own geodetic transforms for the metres between two positions. The simulator's
truth geometry (``sim.truth_frames``) is checked against the same ray-trace.
"""

from __future__ import annotations

import math

import numpy as np
import pymap3d
import pytest

from sarmission.geo.camera import CameraIntrinsics
from sarmission.geo.geolocate import PlatformPose, geolocate
from sim.truth_frames import camera_rotation

LAT0, LON0 = -35.3632, 149.1652
INTR = CameraIntrinsics(width=1000, height=800, fx=800.0, fy=800.0, cx=500.0, cy=400.0)
NADIR = (0.0, -math.pi / 2, 0.0)


def rodrigues(axis, angle: float) -> np.ndarray:
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    cross = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * cross + (1.0 - math.cos(angle)) * cross @ cross


def frd_to_ned(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Turn about down by yaw, then about the new right axis by pitch, then about the new
    forward axis by roll (intrinsic rotations compose to the right)."""
    return rodrigues((0, 0, 1), yaw) @ rodrigues((0, 1, 0), pitch) @ rodrigues((1, 0, 0), roll)


def ray_ned(u: float, v: float, vehicle_rpy, gimbal_rpy, frame: str) -> np.ndarray:
    """The pixel's ray in NED: image right is the gimbal's right, image down its down, the
    optical axis its forward."""
    x, y = (u - INTR.cx) / INTR.fx, (v - INTR.cy) / INTR.fy
    in_gimbal = np.array([1.0, x, y])  # forward, right, down
    gimbal = frd_to_ned(*gimbal_rpy)
    if frame == "body":
        gimbal = frd_to_ned(*vehicle_rpy) @ gimbal
    elif frame == "vehicle":
        gimbal = rodrigues((0, 0, 1), vehicle_rpy[2]) @ gimbal
    return gimbal @ in_gimbal


def ground_offset(u, v, vehicle_rpy, gimbal_rpy, frame, height: float) -> tuple[float, float]:
    """North/east metres from the drone to where the ray meets the plane ``height`` below."""
    d = ray_ned(u, v, vehicle_rpy, gimbal_rpy, frame)
    assert d[2] > 0
    return height * d[0] / d[2], height * d[1] / d[2]


def fix_offset(fix) -> tuple[float, float]:
    """North/east metres from the drone to the fix, by pymap3d."""
    n, e, _ = pymap3d.geodetic2ned(fix.lat, fix.lon, 0.0, LAT0, LON0, 0.0)
    return float(n), float(e)


def pose(
    rel_alt: float, vehicle_rpy=(0.0, 0.0, 0.0), gimbal_rpy=NADIR, frame="body", **sigmas
) -> PlatformPose:
    return PlatformPose(
        LAT0, LON0, rel_alt, *vehicle_rpy, gimbal_rpy=gimbal_rpy, gimbal_frame=frame, **sigmas
    )


@pytest.mark.parametrize(
    ("case", "pixel", "vehicle", "gimbal", "frame", "north", "east"),
    [
        ("nadir, image centre: below the drone", (500, 400), (0, 0, 0.7), NADIR, "body", 0.0, 0.0),
        (
            "looking east, 45 deg down",
            (500, 400),
            (0, 0, 0),
            (0, -math.pi / 4, math.pi / 2),
            "earth",
            0.0,
            100.0,
        ),
        (
            "heading 90 deg, gimbal 45 deg down on the body",
            (500, 400),
            (0, 0, math.pi / 2),
            (0, -math.pi / 4, 0),
            "body",
            0.0,
            100.0,
        ),
        (
            "heading 90 deg, gimbal yaw 0 relative to it",
            (500, 400),
            (0.1, 0.05, math.pi / 2),
            (0, -math.pi / 4, 0),
            "vehicle",
            0.0,
            100.0,
        ),
        (
            "heading -30 deg, 60 deg down: 57.7 m away",
            (500, 400),
            (0, 0, -math.pi / 6),
            (0, -math.pi / 3, 0),
            "body",
            100 / math.sqrt(3) * math.cos(math.pi / 6),
            -100 / math.sqrt(3) * math.sin(math.pi / 6),
        ),
        (
            "right wing down 10 deg, nadir on the body: left",
            (500, 400),
            (math.radians(10), 0, 0),
            NADIR,
            "body",
            0.0,
            -100 * math.tan(math.radians(10)),
        ),
        (
            "nose up 10 deg, nadir on the body: ahead",
            (500, 400),
            (0, math.radians(10), 0),
            NADIR,
            "body",
            100 * math.tan(math.radians(10)),
            0.0,
        ),
        (
            "200 px right of centre, heading north: east",
            (700, 400),
            (0, 0, 0),
            NADIR,
            "body",
            0.0,
            100 * 200 / 800,
        ),
        (
            "200 px below centre, heading north: south",
            (500, 600),
            (0, 0, 0),
            NADIR,
            "body",
            -100 * 200 / 800,
            0.0,
        ),
        (
            "200 px right, heading east: south",
            (700, 400),
            (0, 0, math.pi / 2),
            NADIR,
            "body",
            -100 * 200 / 800,
            0.0,
        ),
    ],
)
def test_hand_computed_cases(case, pixel, vehicle, gimbal, frame, north, east):
    fix = geolocate(pixel, INTR, pose(100.0, vehicle, gimbal, frame))
    assert fix.ok, (case, fix.note)
    assert fix_offset(fix) == pytest.approx((north, east), abs=0.01), case
    assert ground_offset(*pixel, vehicle, gimbal, frame, 100.0) == pytest.approx(
        (north, east), abs=1e-9
    ), case  # the ray-trace agrees with the hand


def random_poses(frame: str, n: int, seed: int):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        vehicle = (rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-math.pi, math.pi))
        gimbal = (rng.uniform(-0.2, 0.2), rng.uniform(-1.55, -0.6), rng.uniform(-math.pi, math.pi))
        pixel = (rng.uniform(0, INTR.width), rng.uniform(0, INTR.height))
        d = ray_ned(*pixel, vehicle, gimbal, frame)
        if d[2] / np.linalg.norm(d) > math.sin(math.radians(20)):  # well below the horizon
            out.append((pixel, vehicle, gimbal))
    return out


@pytest.mark.parametrize("frame", ["body", "vehicle", "earth"])
def test_ray_trace_from_first_principles(frame):
    for pixel, vehicle, gimbal in random_poses(frame, 25, seed=len(frame)):
        fix = geolocate(pixel, INTR, pose(80.0, vehicle, gimbal, frame))
        assert fix.ok, fix.note
        expected = ground_offset(*pixel, vehicle, gimbal, frame, 80.0)
        assert fix_offset(fix) == pytest.approx(expected, abs=0.02), (pixel, vehicle, gimbal)
        assert fix.range_m == pytest.approx(math.hypot(*expected, 80.0), rel=1e-6)


def test_plane_below_home_lengthens_the_ray():
    """The ground 20 m below home, the drone 80 m above home: 100 m of height."""
    fix = geolocate(
        (500, 400),
        INTR,
        pose(80.0, (0, 0, 0), (0, -math.pi / 4, 0), "earth"),
        ground_below_home_m=20.0,
    )
    assert fix_offset(fix) == pytest.approx((100.0, 0.0), abs=0.01)


@pytest.mark.parametrize("pixel", [(500, 400), (740, 400), (500, 160)])
def test_ground_height_uncertainty_slides_the_point_along_the_ray(pixel):
    """A plane whose height is known to sigma g moves the point by g * tan(off-nadir angle)
    along the ray's horizontal direction: the variance grows by exactly that squared (none at
    nadir)."""
    p = pose(100.0, gnss_sigma_m=1.0, alt_sigma_m=1.0, attitude_sigma_rad=math.radians(0.5))
    without = geolocate(pixel, INTR, p)
    with_ground = geolocate(pixel, INTR, p, ground_sigma_m=3.0)
    tan_off_nadir = math.hypot(pixel[0] - INTR.cx, pixel[1] - INTR.cy) / INTR.fx
    assert with_ground.error_m**2 - without.error_m**2 == pytest.approx(
        (3.0 * tan_off_nadir) ** 2, rel=1e-6, abs=1e-9
    )
    assert (with_ground.lat, with_ground.lon) == (without.lat, without.lon)


def test_gnss_error_alone_at_nadir():
    """No attitude or height error, looking straight down: the fix is as good as the GNSS,
    sigma per axis in two axes: sqrt(2) sigma DRMS."""
    fix = geolocate(
        (500, 400), INTR, pose(100.0, gnss_sigma_m=2.0, alt_sigma_m=0.0, attitude_sigma_rad=0.0)
    )
    assert fix.error_m == pytest.approx(2.0 * math.sqrt(2.0))


@pytest.mark.parametrize("frame", ["body", "vehicle", "earth"])
def test_simulator_truth_geometry_matches_the_ray_trace(frame):
    for pixel, vehicle, gimbal in random_poses(frame, 10, seed=7):
        x, y = (pixel[0] - INTR.cx) / INTR.fx, (pixel[1] - INTR.cy) / INTR.fy
        d_sim = camera_rotation(vehicle, gimbal, frame) @ np.array([x, y, 1.0])
        np.testing.assert_allclose(d_sim, ray_ned(*pixel, vehicle, gimbal, frame), atol=1e-12)
