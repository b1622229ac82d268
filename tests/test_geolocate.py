"""Pixel -> lat/lon against the simulator's exact camera geometry, and the error model."""

import math

import numpy as np
import pytest

from sarmission.geo.camera import CameraIntrinsics, CameraPose, project_points
from sarmission.geo.geolocate import PlatformPose, geolocate
from sarmission.geo.wgs84 import geodetic_to_ned, ned_to_geodetic
from sarmission.mission.config import load_mission
from sim.flight import Flight

HOME = (54.17, 7.89, 12.0)
INTR = CameraIntrinsics.from_hfov(3840, 2160, 70.0)
INTR_DISTORTED = CameraIntrinsics(
    3840, 2160, 2700.0, 2705.0, 1925.0, 1070.0, (-0.12, 0.03, 1e-4, -2e-4)
)


def pose_from_ned(position_ned, vehicle_rpy, gimbal_rpy, frame, **sigmas) -> PlatformPose:
    lat, lon, _ = ned_to_geodetic(*position_ned, *HOME)
    return PlatformPose(
        float(lat),
        float(lon),
        -float(position_ned[2]),
        *vehicle_rpy,
        gimbal_rpy=tuple(gimbal_rpy),
        gimbal_frame=frame,
        **sigmas,
    )


def ground_points_in_view(cam: CameraPose, intr: CameraIntrinsics, n: int, rng, ground_down=0.0):
    """Ground points (NED, on the plane) that project inside the image, with their pixels."""
    axis = cam.optical_axis_ned
    t = (ground_down - cam.position_ned[2]) / axis[2]
    centre = cam.position_ned + t * axis
    spread = 0.4 * t * math.tan(math.radians(intr.hfov_deg / 2))
    pts = centre + np.column_stack(
        [rng.uniform(-spread, spread, 4 * n), rng.uniform(-spread, spread, 4 * n), np.zeros(4 * n)]
    )
    pts[:, 2] = ground_down
    uv, front = project_points(intr, cam, pts)
    inside = (
        front
        & (uv[:, 0] > 0)
        & (uv[:, 0] < intr.width - 1)
        & (uv[:, 1] > 0)
        & (uv[:, 1] < intr.height - 1)
    )
    assert inside.sum() >= n
    return pts[inside][:n], uv[inside][:n]


def horizontal_error(fix, point_ned, ground_alt=None) -> float:
    n, e, _ = geodetic_to_ned(fix.lat, fix.lon, HOME[2], *HOME)
    return math.hypot(float(n) - point_ned[0], float(e) - point_ned[1])


EARTH_RADIUS_M = 6.371e6


def exact_tolerance(position_ned, point_ned) -> float:
    """1 mm plus what the truth's flat plane at home costs: geolocation works in the drone's
    own tangent plane, whose vertical is tilted by ``offset / R`` from home's, which moves the
    ground point by about ``height * offset / R`` (about 1-2 mm at 100-200 m from home)."""
    offset = math.hypot(position_ned[0], position_ned[1]) + math.hypot(
        point_ned[0] - position_ned[0], point_ned[1] - position_ned[1]
    )
    return 1e-3 + 2.0 * offset * abs(position_ned[2]) / EARTH_RADIUS_M


@pytest.mark.parametrize("frame", ["body", "vehicle", "earth"])
@pytest.mark.parametrize("gimbal_pitch_deg", [-90.0, -45.0, -30.0])
@pytest.mark.parametrize("intr", [INTR, INTR_DISTORTED], ids=["pinhole", "distorted"])
def test_exact_telemetry_is_sub_millimetre(frame, gimbal_pitch_deg, intr):
    rng = np.random.default_rng(1)
    position = np.array([35.0, -20.0, -80.0])
    vehicle_rpy = (math.radians(6.0), math.radians(-4.0), math.radians(125.0))
    gimbal_rpy = (math.radians(1.0), math.radians(gimbal_pitch_deg), math.radians(-20.0))
    cam = CameraPose.from_attitudes(position, vehicle_rpy, gimbal_rpy, frame)
    pose = pose_from_ned(position, vehicle_rpy, gimbal_rpy, frame)
    points, uv = ground_points_in_view(cam, intr, 15, rng)
    for p, pix in zip(points, uv, strict=True):
        fix = geolocate(pix, intr, pose)
        assert fix.ok, fix.note
        assert horizontal_error(fix, p) < exact_tolerance(position, p)
        assert fix.range_m == pytest.approx(np.linalg.norm(p - position), rel=1e-6)
        assert 0.0 < fix.depression_deg <= 90.0


def test_terrain_height_plane():
    rng = np.random.default_rng(2)
    position = np.array([0.0, 0.0, -60.0])
    rpy, g = (0.02, -0.03, 0.4), (0.0, math.radians(-50.0), 0.1)
    cam = CameraPose.from_attitudes(position, rpy, g, "vehicle")
    ground_alt = HOME[2] - 7.5  # terrain 7.5 m below home
    points, uv = ground_points_in_view(cam, INTR, 10, rng, ground_down=7.5)
    pose = pose_from_ned(position, rpy, g, "vehicle")
    for p, pix in zip(points, uv, strict=True):
        fix = geolocate(pix, INTR, pose, ground_below_home_m=HOME[2] - ground_alt)
        assert horizontal_error(fix, p) < 1e-3
        # the home-altitude plane would put it elsewhere
        assert horizontal_error(geolocate(pix, INTR, pose), p) > 0.5


@pytest.mark.parametrize("gimbal", [True, False])
def test_simulated_flight_truth(gimbal):
    mission = load_mission(
        overrides={
            "flight.takeoff": False,
            "camera.gimbal": gimbal,
            "camera.mount_pitch_deg": -90.0 if gimbal else -45.0,
            "area.home_alt_m": HOME[2],
            "area.home_lat": HOME[0],
            "area.home_lon": HOME[1],
        }
    )
    flight = Flight(mission, seed=3)
    intr = mission.camera.intrinsics()
    rng = np.random.default_rng(3)
    for t in (4.0, 17.3, 31.0, 55.5):  # straight legs and turns (banked)
        s = flight.state_at(t)
        cam = flight.camera_pose_at(t)
        pose = pose_from_ned(s.position_ned, s.vehicle_rpy, s.gimbal_rpy, s.gimbal_frame)
        points, uv = ground_points_in_view(cam, intr, 8, rng)
        for p, pix in zip(points, uv, strict=True):
            fix = geolocate(pix, intr, pose)
            assert horizontal_error(fix, p) < exact_tolerance(s.position_ned, p)


@pytest.mark.parametrize("gimbal_pitch_deg", [-90.0, -45.0, -30.0])
def test_error_estimate_matches_noisy_telemetry(gimbal_pitch_deg):
    """2 m GNSS, 1 m altitude, 1 deg per attitude angle: the actual error is within 3 sigma in
    >= 95 % of 200 trials, and its mean square is close to the predicted one."""
    rng = np.random.default_rng(4)
    gnss, alt, att = 2.0, 1.0, math.radians(1.0)
    position = np.array([10.0, 40.0, -70.0])
    vehicle_rpy = np.array([math.radians(3.0), math.radians(-5.0), math.radians(60.0)])
    gimbal_rpy = (0.0, math.radians(gimbal_pitch_deg), math.radians(15.0))
    cam = CameraPose.from_attitudes(position, tuple(vehicle_rpy), gimbal_rpy, "body")
    points, uv = ground_points_in_view(cam, INTR, 200, rng)
    errors, sigmas = [], []
    for p, pix in zip(points, uv, strict=True):
        noisy_pos = position + rng.normal(0.0, [gnss, gnss, alt])
        noisy_rpy = vehicle_rpy + rng.normal(0.0, att, 3)
        pose = pose_from_ned(
            noisy_pos,
            tuple(noisy_rpy),
            gimbal_rpy,
            "body",
            gnss_sigma_m=gnss,
            alt_sigma_m=alt,
            attitude_sigma_rad=att,
        )
        fix = geolocate(pix, INTR, pose)
        errors.append(horizontal_error(fix, p))
        sigmas.append(fix.error_m)
    errors, sigmas = np.array(errors), np.array(sigmas)
    assert np.mean(errors <= 3 * sigmas) >= 0.95
    ratio = np.mean(errors**2) / np.mean(sigmas**2)
    assert 0.5 < ratio < 1.5, ratio


def test_error_grows_with_obliqueness_and_height():
    def centre_sigma(pitch_deg, height):
        g = (0.0, math.radians(pitch_deg), 0.0)
        pose = pose_from_ned(np.array([0.0, 0.0, -height]), (0.0, 0.0, 0.0), g, "earth")
        return geolocate((1919.5, 1079.5), INTR, pose).error_m

    assert centre_sigma(-90, 70) < centre_sigma(-45, 70) < centre_sigma(-30, 70)
    assert centre_sigma(-45, 50) < centre_sigma(-45, 100)
    # nadir: GNSS sqrt(2) * 1 m and pointing sqrt(2) * h * 0.5 deg, nothing from the altitude
    expected = math.sqrt(2 * 1.0**2 + 2 * (70 * math.radians(0.5)) ** 2)
    assert centre_sigma(-90, 70) == pytest.approx(expected, rel=1e-6)


def test_ray_above_horizon_and_camera_below_ground():
    position = np.array([0.0, 0.0, -50.0])
    pose = pose_from_ned(position, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), "earth")  # at the horizon
    fix = geolocate((1919.5, 100.0), INTR, pose)  # upper half: above the horizon
    assert not fix.ok and fix.depression_deg < 0 and "horizon" in fix.note
    assert fix.error_m is None and fix.range_m is None
    below = geolocate((1919.5, 2000.0), INTR, pose)  # lower half: hits the ground
    assert below.ok and below.depression_deg > 0
    nadir = pose_from_ned(position, (0.0, 0.0, 0.0), (0.0, -math.pi / 2, 0.0), "earth")
    under = geolocate((1919.5, 1079.5), INTR, nadir, ground_below_home_m=-80.0)
    assert not under.ok and "below the ground plane" in under.note
