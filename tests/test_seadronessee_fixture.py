"""The hand-written SeaDronesSee sample in tests/fixtures reads in one convention (pitch
positive below the horizon, as the real file and its README have it), and replays with
positions: its placed frames' centre rays land where the geometry says, and the replay's
candidates carry positions within each frame's footprint."""

from __future__ import annotations

import math
import re
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from conftest import FIXTURES_DIR

from sarmission.cli import main
from sarmission.data.coco_video import read_coco_video
from sarmission.data.meta_conventions import (
    DEPRESSION,
    MetaPose,
    NoMetaPose,
    dataset_conventions,
    meta_pose,
)
from sarmission.geo.camera import CameraIntrinsics
from sarmission.geo.geolocate import geolocate
from sarmission.geo.wgs84 import geodetic_to_ned
from sarmission.mavlink.telemetry import TelemetryBuffer
from sarmission.mission.replay_telemetry import push_frame_telemetry

FIXTURE = FIXTURES_DIR / "seadronessee_sample.json"
INTR = CameraIntrinsics.from_hfov(3840, 2160, 70.0)


def test_the_sample_is_in_seadronessees_convention():
    dataset = read_coco_video(FIXTURE)
    conventions = dataset_conventions(dataset)
    assert conventions.pitch == DEPRESSION
    poses = {im.id: meta_pose(im.telemetry, conventions) for im in dataset.images}
    assert isinstance(poses[10], MetaPose) and isinstance(poses[21], MetaPose)
    assert poses[10].gimbal_pitch_deg == pytest.approx(-43.9)
    assert poses[21].gimbal_pitch_deg == pytest.approx(-90.0)
    assert isinstance(poses[11], NoMetaPose) and isinstance(poses[20], NoMetaPose)


@pytest.mark.parametrize(
    ("image_id", "ground_m", "bearing_deg"),
    [
        (10, 8.3 / math.tan(math.radians(43.9)), 137.5),  # 43.9 deg down from 8.3 m, heading 137.5
        (21, 0.0, 0.0),
    ],
)  # straight down: the centre is below the drone
def test_placed_frames_centre_rays_land_where_the_geometry_says(image_id, ground_m, bearing_deg):
    dataset = read_coco_video(FIXTURE)
    pose = meta_pose(dataset.image(image_id).telemetry, dataset_conventions(dataset))
    assert isinstance(pose, MetaPose)
    buffer = TelemetryBuffer(require_gps_fix=False)
    push_frame_telemetry(buffer, 0.0, pose)
    platform = buffer.lookup(0.0)
    fix = geolocate((INTR.cx, INTR.cy), INTR, platform)
    assert fix.ok, fix.note
    north, east, _ = geodetic_to_ned(fix.lat, fix.lon, 0.0, pose.latitude, pose.longitude, 0.0)
    assert math.hypot(north, east) == pytest.approx(ground_m, abs=0.05)
    if ground_m > 0:
        assert math.degrees(math.atan2(east, north)) % 360 == pytest.approx(bearing_deg, abs=0.5)


def write_frames(folder: Path) -> Path:
    """The sample beside 320x180 frames for its file names: a grey sea with a bright dot."""
    shutil.copy(FIXTURE, folder / FIXTURE.name)
    for name in (
        "DJI_0001/000000.png",
        "DJI_0001/000001.png",
        "DJI_0002/000000.png",
        "DJI_0002/000001.png",
    ):
        (folder / name).parent.mkdir(exist_ok=True)
        image = np.full((180, 320, 3), 90, np.uint8)
        cv2.circle(image, (100, 90), 3, (240, 240, 250), -1)
        cv2.imwrite(str(folder / name), image)
    return folder / FIXTURE.name


@pytest.mark.parametrize(
    ("video", "drone", "reach_m"),
    [
        ("1", (47.671044, 9.269786), 40.0),  # 8.3 m up, 43.9 deg down: the frame spans < 40 m
        ("2", (47.6805, 9.2791), 40.0),
    ],
)  # 52.4 m up looking down, 70 deg lens: 37 m half width
def test_the_sample_replays_with_positions(tmp_path, capsys, video, drone, reach_m):
    path = write_frames(tmp_path)
    # Two frames a video: every detection is a candidate (lock 1 of 1) so positions show.
    assert (
        main(
            [
                "replay",
                str(path),
                "--video-id",
                video,
                "--fps",
                "0.5",
                "--set",
                "lock.m=1",
                "--set",
                "lock.k=1",
                "--no-progress",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "meta read as: gimbal pitch positive below the horizon" in out
    assert "mixed" not in out
    # Video 2's first frame has no meta: its candidates come without a position, and get one
    # (a POSITION line) from the second frame.
    places = re.findall(
        r"(?:CANDIDATE|POSITION) target \d+: \w+ (?:[\d.]+ )?at "
        r"(-?[\d.]+),(-?[\d.]+) ±",
        out,
    )
    assert places, out
    for lat, lon in places:
        north, east, _ = geodetic_to_ned(float(lat), float(lon), 0.0, *drone, 0.0)
        assert math.hypot(north, east) < reach_m
