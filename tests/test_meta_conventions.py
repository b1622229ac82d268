"""Dataset meta read with its own conventions: the gimbal pitch's sign decided from the file
(statement, option or values, never guessed for a mixed file), frames that cannot place the
camera refused with one line, and `sarmission replay` placing a SeaDronesSee-style dataset."""

import logging
from pathlib import Path

import pytest
from test_replay import MISSION, write_clip

from sarmission.cli import main
from sarmission.data.coco_video import (
    Category,
    FrameTelemetry,
    ImageRecord,
    Video,
    VideoDataset,
    parse_telemetry,
    write_coco_video,
)
from sarmission.data.meta_conventions import (
    DEPRESSION,
    ELEVATION,
    ConventionError,
    MetaConventions,
    MetaPose,
    NoMetaPose,
    detect_conventions,
    meta_pose,
)


def frames(*pitches: float | None) -> list[FrameTelemetry]:
    return [FrameTelemetry(gimbal_pitch=p) for p in pitches]


def placed(**overrides: float | None) -> FrameTelemetry:
    values: dict[str, float | None] = dict(
        latitude=47.67,
        longitude=9.27,
        altitude=40.0,
        gimbal_pitch=30.0,
        compass_heading=120.0,
        gimbal_heading=100.0,
    )
    values.update(overrides)
    return FrameTelemetry(**values)


SEADRONESSEE = MetaConventions(DEPRESSION, "test")
DJI = MetaConventions(ELEVATION, "test")


def test_pitch_sign_from_the_values():
    assert detect_conventions(frames(90.0, 36.1, 0.0, None)).pitch == DEPRESSION
    assert detect_conventions(frames(-90.0, -12.0, 0.0)).pitch == ELEVATION


def test_both_signs_without_a_statement_is_a_mixed_file():
    with pytest.raises(ConventionError, match="both signs .1 frames positive, 2 negative"):
        detect_conventions(frames(45.0, -90.0, -30.0))


def test_a_statement_decides_and_must_agree():
    info = {"meta_conventions": {"gimbal_pitch": "depression"}}
    assert detect_conventions(frames(45.0, -5.0), info).pitch == DEPRESSION
    assert detect_conventions(frames(45.0, -5.0), None, "elevation").pitch == ELEVATION
    with pytest.raises(ConventionError, match="mixed conventions"):
        detect_conventions(frames(45.0), info, "elevation")
    with pytest.raises(ConventionError, match="must be one of"):
        detect_conventions(frames(45.0), {"meta_conventions": {"gimbal_pitch": "up"}})
    with pytest.raises(ConventionError, match="must be auto"):
        detect_conventions(frames(45.0), None, "sideways")


def test_a_pose_in_the_geolocation_conventions():
    pose = meta_pose(placed(gimbal_pitch=30.0, compass_heading=-10.0), SEADRONESSEE)
    assert isinstance(pose, MetaPose)
    assert (pose.gimbal_pitch_deg, pose.heading_deg, pose.gimbal_heading_deg) == (
        -30.0,
        350.0,
        100.0,
    )
    assert (pose.latitude, pose.longitude, pose.height_m) == (47.67, 9.27, 40.0)
    same = meta_pose(placed(gimbal_pitch=-30.0, compass_heading=350.0), DJI)
    assert isinstance(same, MetaPose) and same.gimbal_pitch_deg == -30.0
    filled = meta_pose(placed(gimbal_heading=None), SEADRONESSEE)
    assert isinstance(filled, MetaPose) and filled.gimbal_heading_deg == 120.0
    assert filled.notes


@pytest.mark.parametrize(
    ("overrides", "conventions", "reason"),
    [
        (dict(latitude=None), SEADRONESSEE, "meta lacks latitude"),
        (
            dict(altitude=None, gimbal_pitch=None),
            SEADRONESSEE,
            "meta lacks height above take-off, gimbal pitch",
        ),
        (dict(compass_heading=None, gimbal_heading=None), SEADRONESSEE, "meta lacks heading"),
        (dict(altitude=0.0), SEADRONESSEE, "height above take-off 0 m: not in the air"),
        (dict(altitude=-3.0), SEADRONESSEE, "height above take-off -3 m: not in the air"),
        (dict(gimbal_pitch=-5.0), SEADRONESSEE, "gimbal pitch -5 (depression) looks above"),
        (dict(gimbal_pitch=5.0), DJI, "gimbal pitch 5 (elevation) looks above"),
        (dict(gimbal_pitch=120.0), SEADRONESSEE, "gimbal pitch 120 out of range"),
        (dict(latitude=95.0), SEADRONESSEE, "position 95.0, 9.27 out of range"),
        (dict(latitude=0.0, longitude=0.0), SEADRONESSEE, "position 0, 0 (no GNSS fix)"),
    ],
)
def test_frames_that_cannot_place_the_camera_say_why(overrides, conventions, reason):
    pose = meta_pose(placed(**overrides), conventions)
    assert isinstance(pose, NoMetaPose)
    assert pose.reason.startswith(reason), pose.reason


def test_two_keys_of_one_name_that_disagree_are_dropped(caplog):
    with caplog.at_level(logging.WARNING):
        t = parse_telemetry(
            {
                "gimbal_pitch": 45.0,
                "gimbal_pitch(degrees)": -45.0,
                "altitude": 30,
                "Altitude": "30.0",
            }
        )
    assert t.gimbal_pitch is None and t.altitude == 30.0
    assert "disagree" in caplog.text


def write_dataset(folder: Path, pitches: list[float], info: dict | None = None) -> Path:
    """The replay clip as a SeaDronesSee MOT-style dataset (v1 keys) with these pitches."""
    paths = write_clip(folder / "images")
    images = [
        ImageRecord(
            i + 1,
            p.name,
            180,
            320,
            video_id=1,
            frame_index=i,
            meta={
                "gps_latitude": 47.67,
                "gps_longitude": 9.27 + 1e-5 * i,
                "altitude": 60.0,
                "gimbal_pitch": pitches[i % len(pitches)],
                "compass_heading": 90.0,
                "gimbal_heading": 90.0,
            },
        )
        for i, p in enumerate(paths)
    ]
    path = folder / "annotations.json"
    write_coco_video(
        VideoDataset([Video(1, "clip")], images, [], [Category(1, "swimmer")], info=info or {}),
        path,
    )
    return path


def alert_lines(out: str) -> list[str]:
    return [
        line
        for line in out.splitlines()
        if line.split()[:1] == ["CANDIDATE"] or line.split()[:1] == ["ALERT"]
    ]


def replay(path: Path, *extra: str) -> None:
    assert (
        main(["replay", str(path), "--mission", str(MISSION), "--fps", "10", "--ds", "1", *extra])
        == 0
    )


def test_replay_places_a_seadronessee_dataset_looking_straight_down(tmp_path, capsys):
    replay(write_dataset(tmp_path, [90.0]))
    out = capsys.readouterr().out
    assert "meta read as: gimbal pitch positive below the horizon" in out
    alerts = alert_lines(out)
    assert alerts, out
    assert all("position unknown" not in line and "±" in line for line in alerts), out


def test_replay_refuses_a_file_with_mixed_pitch_signs(tmp_path, capsys):
    replay(write_dataset(tmp_path, [90.0, -90.0]))
    out = capsys.readouterr().out
    assert "telemetry: none: dataset meta not used: gimbal pitch has both signs" in out
    alerts = alert_lines(out)
    assert alerts, out
    assert all("position unknown: dataset meta in mixed conventions" in line for line in alerts), (
        out
    )


def test_replay_gives_no_position_to_a_frame_looking_above_the_horizon(tmp_path, capsys):
    # Stated as SeaDronesSee, so -5 means 5 degrees above the horizon on every third frame.
    replay(write_dataset(tmp_path, [90.0, 90.0, -5.0]), "--meta-pitch", "depression")
    out = capsys.readouterr().out
    assert "as stated by the option" in out
    alerts = alert_lines(out)
    assert alerts, out
    # Frame 2 (t=0.2 s) looked up: its alerts carry its own reason, not a neighbour's pose.
    above = [line for line in alerts if "(frame 2," in line]
    assert above and all(
        "position unknown: dataset meta: gimbal pitch -5 (depression) looks "
        "above the horizon" in line
        for line in above
    ), out


def test_replay_refuses_positions_beyond_the_missions_off_nadir_limit(tmp_path, capsys):
    # The centre looks 60 degrees off nadir; the 70-degree lens sees 43 degrees from top to
    # bottom of the 320x180 frame, so no pixel lies within 38 degrees of nadir: the mission
    # allows 35 (whatever the head detects, nothing gets a fix), then 89.
    path = write_dataset(tmp_path, [30.0])
    replay(path, "--set", "geolocation.max_off_nadir_deg=35")
    out = capsys.readouterr().out
    alerts = alert_lines(out)
    assert alerts, out
    assert all(
        "position unknown: no ground fix: ray" in line
        and "from straight down (a fix needs at most 35" in line
        for line in alerts
    ), out
    replay(path, "--set", "geolocation.max_off_nadir_deg=89")
    alerts = alert_lines(capsys.readouterr().out)
    assert alerts and all("±" in line for line in alerts), alerts
