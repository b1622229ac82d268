"""Oblique views in the simulator: the sky above the horizon where the geometry puts it, sea
below, and targets whose pixel size follows their distance; the oblique presets fly the views
they name."""

import math

import numpy as np
import pytest

from sarmission.geo.camera import CameraIntrinsics, CameraPose
from sarmission.geo.frames import rotation_ned_from_camera
from sim.render import SceneRenderer
from sim.scenarios import oblique_view_m, preset
from sim.sea import SKY_BGR

INTR = CameraIntrinsics.from_hfov(480, 270, 70.0)


def render(depression_deg: float, height_m: float, east_m: float = 20.0):
    chosen = preset("maritime_oblique_low")
    renderer = SceneRenderer(chosen.scenario, INTR)
    n0, e0, n1, e1 = chosen.scenario.area_ne
    rotation = rotation_ned_from_camera(
        (0.0, 0.0, 0.0), (0.0, -math.radians(depression_deg), 0.0), "earth"
    )
    position = np.array([(n0 + n1) / 2, e0 + east_m, -height_m])
    pose = CameraPose(position, rotation)
    frame, annotations = renderer.render(3.0, pose)
    return frame.astype(float), annotations, position


@pytest.mark.parametrize("depression_deg", [11.0, 25.0])
def test_sky_above_the_horizon_and_sea_below(depression_deg):
    frame, _, _ = render(depression_deg, 10.0)
    horizon_row = INTR.cy - INTR.fy * math.tan(math.radians(depression_deg))  # by hand
    sky = frame[: max(int(horizon_row) - 4, 0)]
    sea = frame[int(horizon_row) + 20 :]
    if depression_deg < 35.0 * 9 / 16:  # the horizon is inside the frame
        assert sky.size and np.abs(sky.mean(axis=(0, 1)) - SKY_BGR).max() < 12.0
    else:
        assert horizon_row < 0
    assert np.abs(sea.mean(axis=(0, 1)) - SKY_BGR).max() > 40.0


def test_a_nadir_view_shows_no_sky():
    frame, _, _ = render(90.0, 10.0)
    rows = frame.mean(axis=(1, 2))
    assert np.abs(frame[:10].mean(axis=(0, 1)) - SKY_BGR).max() > 40.0
    assert rows.max() - rows.min() < 40.0


def test_target_sizes_follow_the_distance():
    widths, ranges = [], []
    for east in (20.0, 100.0, 180.0, 260.0, 340.0):
        _, annotations, position = render(11.0, 10.0, east)
        for a in annotations:
            if a.is_target and a.visibility > 0.5 and a.bbox_xyxy[2] - a.bbox_xyxy[0] > 1.5:
                widths.append(a.bbox_xyxy[2] - a.bbox_xyxy[0])
                ranges.append(np.linalg.norm(np.array(a.position_ned) - position))
    assert len(widths) >= 3
    # Pixel width times distance over the focal length is the object's width in metres: a
    # person's size (0.15-2.5 m) whether near or far, while the pixel widths differ widely.
    widths, ranges = np.array(widths), np.array(ranges)
    metres = widths * ranges / INTR.fx
    assert np.all((metres > 0.15) & (metres < 2.5)), metres
    assert ranges.max() > 2 * ranges.min() and widths.max() > 2 * widths.min()
    assert np.corrcoef(widths, 1.0 / ranges)[0, 1] > 0.5  # nearer is bigger


@pytest.mark.parametrize(
    ("name", "height", "pitch"),
    [
        ("maritime_oblique_low", 10.0, -11.0),
        ("maritime_oblique_mid", 36.0, -36.0),
        ("maritime_oblique_high", 60.0, -71.0),
    ],
)
def test_oblique_presets_fly_their_views(name, height, pitch):
    chosen = preset(name)
    assert chosen.mission.flight.altitude_m == height
    assert chosen.mission.camera.mount_pitch_deg == pitch and chosen.mission.camera.gimbal
    near, far, area = oblique_view_m(height, 70.0, pitch)
    half_v = math.degrees(math.atan(math.tan(math.radians(35.0)) * 9 / 16))
    assert (
        near == pytest.approx(height / math.tan(math.radians(-pitch + half_v)), rel=1e-6)
        if -pitch + half_v < 90
        else near < 0
    )
    assert far <= 200.0 and area > 0
    n0, e0, n1, e1 = chosen.scenario.area_ne
    legs = chosen.mission.area.rectangle_m
    reach = min(e1 - legs[3], legs[1] - e0, n1 - legs[2], legs[0] - n0)
    # Objects all round the legs, as far as real footage shows them (tens of metres, not the
    # whole view out to the horizon), and standing up out of the water.
    assert 50.0 <= reach <= 110.0
    assert chosen.scenario.figures == "upright"
