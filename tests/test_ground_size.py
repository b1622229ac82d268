"""How large a box's object is. At nadir both measures are pixels x (height / focal length),
computed here by hand. Obliquely the ground extent stretches the along-ray side by
1 / sin(depression), while the size across the line of sight gives back a standing pole's
height and a flat disc's width, both drawn into the image through the camera model."""

import math

import numpy as np
import pytest

from sarmission.geo.camera import CameraIntrinsics, project_points
from sarmission.geo.geolocate import PlatformPose
from sarmission.geo.ground_size import apparent_size_m, ground_extent_m

INTR = CameraIntrinsics.from_hfov(960, 540, 35.0)
F = 480.0 / math.tan(math.radians(17.5))  # focal length in pixels


def pose(height: float, gimbal_pitch_deg: float = -90.0) -> PlatformPose:
    return PlatformPose(
        54.17,
        7.89,
        height,
        0.0,
        0.0,
        0.0,
        gimbal_rpy=(0.0, math.radians(gimbal_pitch_deg), 0.0),
        gimbal_frame="earth",
    )


def box_around(points_ned: np.ndarray, platform: PlatformPose) -> tuple[float, ...]:
    """The image box around NED points seen from ``platform`` (ground plane at home)."""
    uv, in_front = project_points(INTR, platform.camera_pose(platform.rel_alt_m), points_ned)
    assert in_front.all()
    return (*uv.min(axis=0), *uv.max(axis=0))


def test_nadir_sizes_are_pixels_times_height_over_focal_length():
    box = (470.0, 260.0, 490.0, 272.0)  # 20 x 12 px at the image centre
    for measure in (ground_extent_m, apparent_size_m):
        assert measure(box, INTR, pose(70.0)) == pytest.approx(20 * 70.0 / F, rel=1e-3)
        assert measure(box, INTR, pose(35.0)) == pytest.approx(20 * 35.0 / F, rel=1e-3)


def test_oblique_view_stretches_the_along_ray_side_on_the_ground_only():
    box = (475.0, 260.0, 485.0, 280.0)  # 10 x 20 px at the centre, camera 30 deg below horizon
    slant = 70.0 / math.sin(math.radians(30.0))
    extent = ground_extent_m(box, INTR, pose(70.0, -30.0))
    assert extent == pytest.approx(20 * slant / F / math.sin(math.radians(30.0)), rel=0.02)
    assert apparent_size_m(box, INTR, pose(70.0, -30.0)) == pytest.approx(20 * slant / F, rel=0.01)


@pytest.mark.parametrize("depression_deg", [15.0, 30.0, 60.0, 90.0])
def test_a_standing_person_is_as_large_as_they_face_the_camera(depression_deg):
    height, tall, wide = 40.0, 1.8, 0.5  # a 0.5 x 0.5 x 1.8 m block standing on the ground
    ahead = height / math.tan(math.radians(depression_deg))  # on the optical axis, north
    person = np.array(
        [[ahead + n, e, -up] for n in (0.0, wide) for e in (0.0, wide) for up in (0.0, tall)]
    )
    platform = pose(height, -depression_deg)
    box = box_around(person, platform)
    dep = math.radians(depression_deg)
    facing = max(wide, tall * math.cos(dep) + wide * math.sin(dep))
    size = apparent_size_m(box, INTR, platform)
    assert size == pytest.approx(facing, rel=0.05)
    assert 0.15 <= size <= 2.5  # the mission's default person sizes
    if depression_deg <= 30.0:  # the ground extent calls the same person no person
        assert ground_extent_m(box, INTR, platform) > 2.5


@pytest.mark.parametrize("depression_deg", [20.0, 45.0, 90.0])
def test_a_flat_ring_on_the_water_is_its_width(depression_deg):
    height, across = 30.0, 0.8
    ahead = height / math.tan(math.radians(depression_deg))
    angles = np.linspace(0.0, 2.0 * math.pi, 72, endpoint=False)
    ring = np.stack(
        [ahead + across / 2 * np.cos(angles), across / 2 * np.sin(angles), np.zeros_like(angles)],
        axis=1,
    )
    platform = pose(height, -depression_deg)
    assert apparent_size_m(box_around(ring, platform), INTR, platform) == pytest.approx(
        across, rel=0.05
    )


def test_no_size_without_a_ground_fix_at_the_centre():
    assert ground_extent_m((470.0, 0.0, 490.0, 20.0), INTR, pose(70.0, 0.0)) is None
    assert apparent_size_m((470.0, 0.0, 490.0, 20.0), INTR, pose(70.0, 0.0)) is None
    # the top edge above the horizon, the centre below it: a size, no ground extent
    straddling = (470.0, 100.0, 490.0, 300.0)
    assert ground_extent_m(straddling, INTR, pose(70.0, -5.0)) is None
    assert apparent_size_m(straddling, INTR, pose(70.0, -5.0)) > 100.0


@pytest.mark.parametrize("box", [(math.nan, 0.0, 10.0, 10.0), (0.0, 0.0, math.inf, 10.0), (1.0,)])
def test_no_size_for_a_box_that_is_not_four_finite_numbers(box):
    assert apparent_size_m(box, INTR, pose(70.0)) is None
