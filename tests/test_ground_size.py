"""A box's size on the ground: at nadir pixels x (height / focal length), computed here by hand;
obliquely the along-ray side grows by 1 / sin(depression)."""

import math

import pytest

from sarmission.geo.camera import CameraIntrinsics
from sarmission.geo.geolocate import PlatformPose
from sarmission.geo.ground_size import ground_extent_m

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


def test_nadir_extent_is_pixels_times_height_over_focal_length():
    box = (470.0, 260.0, 490.0, 272.0)  # 20 x 12 px at the image centre
    assert ground_extent_m(box, INTR, pose(70.0)) == pytest.approx(20 * 70.0 / F, rel=1e-3)
    assert ground_extent_m(box, INTR, pose(35.0)) == pytest.approx(20 * 35.0 / F, rel=1e-3)


def test_oblique_view_stretches_the_along_ray_side():
    box = (475.0, 260.0, 485.0, 280.0)  # 10 x 20 px at the centre, camera 30 deg below horizon
    size = ground_extent_m(box, INTR, pose(70.0, -30.0))
    slant = 70.0 / math.sin(math.radians(30.0))
    assert size == pytest.approx(20 * slant / F / math.sin(math.radians(30.0)), rel=0.02)


def test_no_extent_when_an_edge_is_above_the_horizon():
    assert ground_extent_m((470.0, 0.0, 490.0, 20.0), INTR, pose(70.0, 0.0)) is None
