"""The simulator's own pinhole camera (``sim.truth_camera``) against hand-worked cases and
against ``sarmission.geo.camera``, which it must agree with without sharing its code."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sarmission.geo.camera import (
    CameraIntrinsics,
    CameraPose,
    ground_to_image_homography,
    pixel_rays,
    project_points,
)
from sim.billboard import billboard_for, billboard_homography
from sim.truth_camera import (
    camera_coordinates,
    ground_homography,
    intrinsic_matrix,
    plane_homography,
    project,
    rays,
)

INTR = CameraIntrinsics(width=1920, height=1080, fx=1000.0, fy=1000.0, cx=959.5, cy=539.5)
#: Nadir camera 100 m above home, image right = east, image down = south, optical axis = down.
NADIR_AXES = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
NADIR = CameraPose(np.array([0.0, 0.0, -100.0]), NADIR_AXES)


def _apply(h: np.ndarray, ab: np.ndarray) -> np.ndarray:
    p = h @ np.array([ab[0], ab[1], 1.0])
    return p[:2] / p[2]


# -- worked by hand ------------------------------------------------------------------------------


def test_nadir_point_by_hand():
    # 10 m north, 20 m east of home on the ground: 20 m right of and 10 m above the image centre
    # at 100 m depth, so 1000 * 20 / 100 = 200 px right and 100 px up.
    uv, in_front = project(INTR, NADIR, np.array([[10.0, 20.0, 0.0]]))
    assert in_front.tolist() == [True]
    np.testing.assert_allclose(uv, [[1159.5, 439.5]], atol=1e-12)
    np.testing.assert_allclose(
        camera_coordinates(NADIR, [[10.0, 20.0, 0.0]]), [[20.0, -10.0, 100.0]], atol=1e-12
    )


def test_nadir_ray_and_ground_homography_by_hand():
    d = rays(INTR, NADIR, np.array([[1159.5, 439.5], [959.5, 539.5]]))
    np.testing.assert_allclose(d[0], np.array([10.0, 20.0, 100.0]) / math.sqrt(10500.0), atol=1e-12)
    np.testing.assert_allclose(d[1], [0.0, 0.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(
        _apply(ground_homography(INTR, NADIR), np.array([10.0, 20.0])), [1159.5, 439.5], atol=1e-9
    )
    # The plane 40 m below the camera (down = -60): 20 m east is now 1000 * 20 / 40 = 500 px right.
    np.testing.assert_allclose(
        _apply(ground_homography(INTR, NADIR, ground_down=-60.0), np.array([0.0, 20.0])),
        [1459.5, 539.5],
        atol=1e-9,
    )


def test_oblique_point_by_hand():
    # Camera at 100 m looking east, 45 degrees down; image right is south. The ground point
    # 100 m east lies on the optical axis; 100 m east and 10 m south lies 10 m to the right at
    # a depth of 100 * sqrt(2): u = cx + 1000 * 10 / (100 sqrt 2).
    s = math.sqrt(0.5)
    axes = np.column_stack([[-1.0, 0.0, 0.0], [0.0, -s, s], [0.0, s, s]])
    pose = CameraPose(np.array([0.0, 0.0, -100.0]), axes)
    uv, _ = project(INTR, pose, np.array([[0.0, 100.0, 0.0], [-10.0, 100.0, 0.0]]))
    np.testing.assert_allclose(
        uv, [[959.5, 539.5], [959.5 + 50.0 * math.sqrt(2.0), 539.5]], atol=1e-9
    )


def test_behind_the_camera_is_nan():
    uv, in_front = project(
        INTR, NADIR, np.array([[0.0, 0.0, -200.0], [0.0, 0.0, -100.0], [1.0, 1.0, 0.0]])
    )
    assert in_front.tolist() == [False, False, True]
    assert np.isnan(uv[:2]).all() and np.isfinite(uv[2]).all()


def test_intrinsic_matrix_and_distortion_refused():
    np.testing.assert_array_equal(
        intrinsic_matrix(INTR), [[1000.0, 0.0, 959.5], [0.0, 1000.0, 539.5], [0.0, 0.0, 1.0]]
    )
    bent = CameraIntrinsics(
        width=100, height=100, fx=90.0, fy=90.0, cx=49.5, cy=49.5, distortion=(-0.1, 0.01, 0.0, 0.0)
    )
    with pytest.raises(ValueError, match="distortion"):
        project(bent, NADIR, np.zeros((1, 3)))
    with pytest.raises(ValueError, match="distortion"):
        rays(bent, NADIR, np.zeros((1, 2)))


# -- agreement with sarmission.geo.camera on random poses -------------------------------------


def _random_case(rng: np.random.Generator) -> tuple[CameraIntrinsics, CameraPose]:
    w, h = int(rng.integers(320, 4000)), int(rng.integers(240, 3000))
    f = float(rng.uniform(0.4, 3.0)) * w
    intr = CameraIntrinsics(
        width=w,
        height=h,
        fx=f,
        fy=f * float(rng.uniform(0.9, 1.1)),
        cx=(w - 1) / 2 + float(rng.normal(0, 5)),
        cy=(h - 1) / 2 + float(rng.normal(0, 5)),
    )
    rot = Rotation.random(random_state=int(rng.integers(2**31))).as_matrix()
    pose = CameraPose(rng.uniform(-500, 500, 3) - np.array([0.0, 0.0, 300.0]), rot)
    return intr, pose


@pytest.mark.parametrize("seed", range(20))
def test_projection_agrees_with_sarmission(seed):
    rng = np.random.default_rng(seed)
    intr, pose = _random_case(rng)
    pts = pose.position_ned + rng.uniform(-400, 400, (200, 3))
    uv, front = project(intr, pose, pts)
    uv_ref, front_ref = project_points(intr, pose, pts)
    np.testing.assert_array_equal(front, front_ref)
    assert front.any() and not front.all()
    np.testing.assert_allclose(uv[front], uv_ref[front], rtol=0, atol=1e-6)
    assert np.isnan(uv[~front]).all() and np.isnan(uv_ref[~front]).all()


@pytest.mark.parametrize("seed", range(20))
def test_rays_agree_with_sarmission(seed):
    rng = np.random.default_rng(100 + seed)
    intr, pose = _random_case(rng)
    uv = np.column_stack(
        [rng.uniform(-0.5, intr.width - 0.5, 200), rng.uniform(-0.5, intr.height - 0.5, 200)]
    )
    d = rays(intr, pose, uv)
    np.testing.assert_allclose(d, pixel_rays(intr, pose, uv), rtol=0, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    # Round trip: a point along each ray projects back onto its pixel.
    back, front = project(intr, pose, pose.position_ned + 37.0 * d)
    assert front.all()
    np.testing.assert_allclose(back, uv, rtol=0, atol=1e-6)


@pytest.mark.parametrize("seed", range(20))
def test_homographies_agree_with_sarmission(seed):
    rng = np.random.default_rng(200 + seed)
    intr, pose = _random_case(rng)
    ground_down = float(rng.uniform(-50, 50))
    h = ground_homography(intr, pose, ground_down=ground_down)
    h_ref = ground_to_image_homography(intr, pose, ground_down=ground_down)
    np.testing.assert_allclose(h / np.abs(h).max(), h_ref / np.abs(h_ref).max(), rtol=0, atol=1e-9)
    ne = rng.uniform(-300, 300, (50, 2))
    pts = np.column_stack([ne, np.full(len(ne), ground_down)])
    uv_ref, front = project_points(intr, pose, pts)
    mapped = np.array([_apply(h, p) for p in ne])
    np.testing.assert_allclose(mapped[front], uv_ref[front], rtol=0, atol=1e-6)


@pytest.mark.parametrize("seed", range(10))
def test_billboard_homography_agrees_with_sarmission(seed):
    rng = np.random.default_rng(300 + seed)
    intr, pose = _random_case(rng)
    board = billboard_for(
        pose.position_ned,
        np.array([*rng.uniform(-300, 300, 2), 0.0]),
        float(rng.uniform(-math.pi, math.pi)),
    )
    assert board is not None
    h = billboard_homography(intr, pose, board)
    xy = rng.uniform(-2, 2, (30, 2))
    pts = board.centre_ned + xy[:, :1] * board.right_ned + xy[:, 1:] * board.up_ned
    uv_ref, front = project_points(intr, pose, pts)
    mapped = np.array([_apply(h, p) for p in xy])
    np.testing.assert_allclose(mapped[front], uv_ref[front], rtol=0, atol=1e-6)
    np.testing.assert_allclose(
        plane_homography(intr, pose, board.centre_ned, board.right_ned, board.up_ned), h
    )
