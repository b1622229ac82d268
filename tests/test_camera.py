"""Camera model: projection and back-projection round trips, homography, hand-computed cases."""

import math

import numpy as np
import pytest

from sarmission.geo import frames, wgs84
from sarmission.geo.camera import (
    CameraIntrinsics,
    CameraPose,
    ground_to_image_homography,
    intersect_ground,
    pixel_rays,
    project_points,
    rotation_ned_from_camera,
)

DISTORTION = (-0.12, 0.03, 0.001, -0.0008, -0.004)
VEHICLE = (math.radians(4.0), math.radians(-3.0), math.radians(37.0))


def _intr(distorted: bool) -> CameraIntrinsics:
    base = CameraIntrinsics.from_hfov(3840, 2160, 70.0)
    if not distorted:
        return base
    return CameraIntrinsics(
        base.width, base.height, base.fx, base.fy * 1.01, 1925.0, 1075.0, DISTORTION
    )


def _grid_pixels(intr: CameraIntrinsics, n: int = 7) -> np.ndarray:
    us = np.linspace(5, intr.width - 6, n)
    vs = np.linspace(5, intr.height - 6, n)
    return np.array([(u, v) for u in us for v in vs])


@pytest.mark.parametrize("distorted", [False, True])
@pytest.mark.parametrize("frame", ["body", "vehicle", "earth"])
@pytest.mark.parametrize("gimbal_pitch_deg", [-90.0, -45.0, -30.0])
def test_pixel_ground_pixel_round_trip(distorted, frame, gimbal_pitch_deg):
    intr = _intr(distorted)
    gimbal = (math.radians(1.5), math.radians(gimbal_pitch_deg), math.radians(-10.0))
    pose = CameraPose.from_attitudes(np.array([12.0, -40.0, -75.0]), VEHICLE, gimbal, frame)
    uv = _grid_pixels(intr)
    rays = pixel_rays(intr, pose, uv)
    ground, valid = intersect_ground(pose, rays, ground_down=2.0)
    # Oblique views see the sky at the top of the image: only rays that meet the ground count.
    assert valid.sum() >= uv.shape[0] // 3
    uv_back, in_front = project_points(intr, pose, ground[valid])
    assert in_front.all()
    np.testing.assert_allclose(uv_back, uv[valid], atol=1e-6)
    np.testing.assert_allclose(ground[valid][:, 2], 2.0, atol=1e-9)


@pytest.mark.parametrize("distorted", [False, True])
@pytest.mark.parametrize("frame", ["body", "earth"])
@pytest.mark.parametrize("gimbal_pitch_deg", [-90.0, -45.0, -30.0])
def test_ground_pixel_ground_round_trip_centimetres(distorted, frame, gimbal_pitch_deg):
    intr = _intr(distorted)
    gimbal = (0.0, math.radians(gimbal_pitch_deg), 0.0)
    pose = CameraPose.from_attitudes(np.array([0.0, 0.0, -80.0]), VEHICLE, gimbal, frame)
    # Ground points around the camera footprint centre.
    centre, ok = intersect_ground(pose, pose.optical_axis_ned[None, :])
    assert ok[0]
    rng = np.random.default_rng(3)
    pts = centre + np.column_stack([rng.uniform(-15, 15, (50, 2)), np.zeros(50)])
    uv, in_front = project_points(intr, pose, pts)
    assert in_front.all()
    back, valid = intersect_ground(pose, pixel_rays(intr, pose, uv))
    assert valid.all()
    assert np.max(np.linalg.norm(back - pts, axis=1)) < 0.03


def test_nadir_hand_computed_right_edge_is_altitude_east():
    # Nadir at 100 m, HFOV 90 deg, yaw 0: tan(45 deg) = 1, so the right image edge (u = W - 0.5)
    # sees the ground 100 m east; the top edge (v = -0.5) sees north by 100 * (H/W) m.
    intr = CameraIntrinsics.from_hfov(4000, 2000, 90.0)
    assert intr.fx == pytest.approx(2000.0)
    pose = CameraPose.from_attitudes(np.array([0.0, 0.0, -100.0]), (0, 0, 0), (0, -math.pi / 2, 0))
    pix = np.array([[intr.width - 0.5, intr.cy], [intr.cx, -0.5], [intr.cx, intr.cy]])
    g, valid = intersect_ground(pose, pixel_rays(intr, pose, pix))
    assert valid.all()
    np.testing.assert_allclose(g[0], [0.0, 100.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(g[1], [50.0, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(g[2], [0.0, 0.0, 0.0], atol=1e-9)
    # Yaw 90 deg (heading east): image up is east, image right is south.
    pose_e = CameraPose.from_attitudes(
        np.array([0.0, 0.0, -100.0]), (0, 0, math.pi / 2), (0, -math.pi / 2, 0)
    )
    g, _ = intersect_ground(pose_e, pixel_rays(intr, pose_e, pix[:2]))
    np.testing.assert_allclose(g[0], [-100.0, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(g[1], [0.0, 50.0, 0.0], atol=1e-9)


def test_forward_camera_hand_computed():
    # Gimbal level (pitch 0), vehicle yaw 0: the optical axis is north, image right is east.
    intr = CameraIntrinsics.from_hfov(640, 480, 90.0)
    pose = CameraPose.from_attitudes(np.zeros(3), (0, 0, 0), (0, 0, 0))
    uv, front = project_points(intr, pose, np.array([[10.0, 10.0, 0.0], [10.0, 0.0, -10.0]]))
    assert front.all()
    np.testing.assert_allclose(uv[0], [intr.width - 0.5, intr.cy])
    np.testing.assert_allclose(uv[1], [intr.cx, intr.cy - intr.fy])


def test_point_behind_camera_is_flagged():
    intr = _intr(False)
    pose = CameraPose.from_attitudes(np.array([0.0, 0.0, -50.0]), (0, 0, 0), (0, -math.pi / 2, 0))
    uv, front = project_points(intr, pose, np.array([[0.0, 0.0, -100.0], [1.0, 2.0, 0.0]]))
    assert not front[0] and front[1]
    assert np.isnan(uv[0]).all() and np.isfinite(uv[1]).all()
    # A ray pointing up never meets the ground.
    _, valid = intersect_ground(pose, np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]))
    assert not valid.any()


@pytest.mark.parametrize("gimbal_pitch_deg", [-90.0, -45.0, -30.0])
def test_homography_agrees_with_projection(gimbal_pitch_deg):
    intr = _intr(False)
    pose = CameraPose.from_attitudes(
        np.array([5.0, 7.0, -70.0]), VEHICLE, (0.0, math.radians(gimbal_pitch_deg), 0.3), "body"
    )
    h = ground_to_image_homography(intr, pose, ground_down=3.0)
    rng = np.random.default_rng(0)
    ne = rng.uniform(-60, 60, (40, 2))
    pts = np.column_stack([ne, np.full(40, 3.0)])
    uv, front = project_points(intr, pose, pts)
    hom = np.column_stack([ne, np.ones(40)]) @ h.T
    assert np.array_equal(hom[:, 2] > 0, front)
    np.testing.assert_allclose(hom[front, :2] / hom[front, 2:], uv[front], rtol=1e-9, atol=1e-6)


def test_earth_and_vehicle_frames_ignore_vehicle_tilt():
    g = (0.0, math.radians(-60), math.radians(20))
    a = rotation_ned_from_camera((0.2, -0.1, 0.0), g, "earth")
    b = rotation_ned_from_camera((0.0, 0.0, 1.0), g, "earth")
    np.testing.assert_allclose(a, b)
    v = rotation_ned_from_camera((0.2, -0.1, 0.5), (0.0, math.radians(-60), 0.0), "vehicle")
    e = rotation_ned_from_camera((0.0, 0.0, 0.0), (0.0, math.radians(-60), 0.5), "earth")
    np.testing.assert_allclose(v, e, atol=1e-12)
    with pytest.raises(ValueError):
        rotation_ned_from_camera((0, 0, 0), (0, 0, 0), "bogus")


def test_quaternion_euler_round_trip_and_flags():
    rpy = (0.1, -0.7, 2.5)
    q = frames.euler_to_quaternion(*rpy)
    np.testing.assert_allclose(frames.quaternion_to_euler(q), rpy, atol=1e-12)
    np.testing.assert_allclose(
        frames.quaternion_to_matrix(q), frames.euler_to_matrix(*rpy), atol=1e-12
    )
    assert frames.gimbal_frame_from_flags(frames.GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME) == "earth"
    assert frames.gimbal_frame_from_flags(frames.GIMBAL_DEVICE_FLAGS_YAW_LOCK) == "earth"
    assert (
        frames.gimbal_frame_from_flags(
            frames.GIMBAL_DEVICE_FLAGS_YAW_LOCK | frames.GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME
        )
        == "vehicle"
    )
    assert frames.gimbal_frame_from_flags(0) == "vehicle"


def test_intrinsics_from_hfov_and_validation():
    intr = CameraIntrinsics.from_hfov(3840, 2160, 70.0)
    assert intr.hfov_deg == pytest.approx(70.0)
    np.testing.assert_allclose(intr.matrix()[0, 2], 1919.5)
    half = intr.scaled(1920, 1080)
    assert half.hfov_deg == pytest.approx(70.0)
    assert half.cx == pytest.approx(959.5)
    with pytest.raises(ValueError):
        CameraIntrinsics(10, 10, 5.0, 5.0, 5.0, 5.0, (0.1, 0.2))


def test_frames_of_another_shape_keep_the_horizontal_view_and_square_pixels():
    """A 16:9 camera's frames at 4:3 (photo mode on the same sensor) see the same rays through
    the same columns; rows move by half the added height, and pixels stay square."""
    intr = CameraIntrinsics.from_hfov(3840, 2160, 70.0)
    assert intr.for_frames(1920, 1080) == intr.scaled(1920, 1080)
    assert intr.same_shape(1920, 1081) and not intr.same_shape(3840, 2880)
    photo = intr.for_frames(3840, 2880)
    assert photo.fx == pytest.approx(photo.fy) and photo.hfov_deg == pytest.approx(70.0)
    assert (photo.cx, photo.cy) == pytest.approx((1919.5, 1439.5))
    for u, v in [(0.0, 0.0), (3000.0, 2000.0), (1919.5, 1079.5)]:
        ray = ((u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy)
        moved = ((u - photo.cx) / photo.fx, (v + 360.0 - photo.cy) / photo.fy)
        assert moved == pytest.approx(ray)
    small = intr.for_frames(640, 480)  # another shape and size at once
    assert small.fx == pytest.approx(intr.fx / 6) and small.cy == pytest.approx(239.5)


def test_wgs84_round_trip_vectorised():
    n = np.array([0.0, 100.0, -250.0])
    e = np.array([0.0, 50.0, 30.0])
    d = np.array([0.0, -10.0, 2.0])
    lat, lon, h = wgs84.ned_to_geodetic(n, e, d, 54.17, 7.89, 3.0)
    assert lat.shape == (3,)
    assert lat[1] > 54.17 and lon[1] > 7.89
    n2, e2, d2 = wgs84.geodetic_to_ned(lat, lon, h, 54.17, 7.89, 3.0)
    np.testing.assert_allclose(np.column_stack([n2, e2, d2]), np.column_stack([n, e, d]), atol=1e-6)
