"""``sarmission replay``: offline runs of the mission controller with the real MITE-Net, writing
a rerun recording, with synthetic (sim, only when asked), dataset (meta), flight-log or no
telemetry, and the post-flight report."""

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import rerun.chunk
from flightlog_fixtures import START_UTC, write_mp4, write_tlog

from sarmission.cli import main
from sarmission.data.coco_video import Category, ImageRecord, Video, VideoDataset, write_coco_video

MISSION = Path(__file__).resolve().parents[1] / "missions" / "maritime_demo.toml"
N_FRAMES = 12


def write_clip(folder: Path) -> list[Path]:
    """320x180 frames of a textured sea with a bright dot moving right, then one corrupt file."""
    folder.mkdir(parents=True)
    rng = np.random.default_rng(0)
    sea = cv2.GaussianBlur(rng.random((180, 320)).astype(np.float32), (0, 0), 3.0)
    sea = (90 + 60 * (sea - sea.mean()) / sea.std()).clip(0, 255)
    paths = []
    for i in range(N_FRAMES):
        img = np.repeat(sea[..., None], 3, axis=2).astype(np.uint8)
        cv2.circle(img, (60 + 4 * i, 90), 3, (240, 240, 250), -1)
        paths.append(folder / f"f{i:03d}.png")
        cv2.imwrite(str(paths[-1]), img)
    (folder / f"f{N_FRAMES:03d}.png").write_bytes(b"not a png")
    return paths


def entity_paths(rrd: Path) -> str:
    return str(rerun.chunk.RrdReader(rrd).store().schema())


def test_replay_of_a_frames_folder_with_flight_telemetry_writes_a_recording(tmp_path, capsys):
    write_clip(tmp_path / "clip")
    rrd = tmp_path / "out.rrd"
    code = main(
        [
            "replay",
            str(tmp_path / "clip"),
            "--mission",
            str(MISSION),
            "--fps",
            "10",
            "--telemetry",
            "sim",
            "--rerun",
            "save",
            str(rrd),
            "--alerts-db",
            str(tmp_path / "alerts.db"),
            "--ds",
            "1",
        ]
    )
    out = capsys.readouterr().out
    assert code == 0, out
    assert "telemetry: simulated flight of the mission (positions are the simulator's" in out
    assert f"frames processed: {N_FRAMES}" in out
    assert "unreadable frames skipped by the reader: 1" in out
    assert "targets:" in out and f"wrote {rrd}" in out
    assert rrd.stat().st_size > 10_000
    schema = entity_paths(rrd)
    for entity in (
        "/camera/frame",
        "/camera/proposals",
        "/camera/detections",
        "/camera/tracks",
        "/telemetry/altitude_m",
        "/telemetry/stage_ms/vstmd",
        "/map/drone",
    ):
        assert entity in schema, entity


def test_replay_of_a_coco_dataset_uses_its_meta_telemetry(tmp_path, capsys):
    paths = write_clip(tmp_path / "images")
    images = [
        ImageRecord(
            i + 1,
            p.name,
            180,
            320,
            video_id=1,
            frame_index=i,
            meta={
                "gps_latitude": 54.178,
                "gps_longitude": 7.892 + 1e-5 * i,
                "altitude": 60.0,
                "gimbal_pitch": -90.0,
                "compass_heading": 90.0,
            },
        )
        for i, p in enumerate(paths)
    ]
    dataset = VideoDataset([Video(1, "clip")], images, [], [Category(1, "swimmer")])
    ann = tmp_path / "annotations.json"
    write_coco_video(dataset, ann)
    code = main(
        [
            "replay",
            str(ann),
            "--fps",
            "10",
            "--rerun",
            "save",
            str(tmp_path / "d.rrd"),
            "--max-frames",
            "8",
        ]
    )
    out = capsys.readouterr().out
    assert code == 0, out
    assert "telemetry: dataset meta" in out
    assert "frames processed: 8" in out
    assert "/map/drone" in entity_paths(tmp_path / "d.rrd")


def test_replay_refuses_meta_telemetry_that_is_not_there(tmp_path, capsys):
    paths = write_clip(tmp_path / "images")
    images = [
        ImageRecord(i + 1, p.name, 180, 320, video_id=1, frame_index=i) for i, p in enumerate(paths)
    ]
    ann = tmp_path / "annotations.json"
    write_coco_video(VideoDataset([Video(1, "clip")], images, [], [Category(1, "swimmer")]), ann)
    assert main(["replay", str(ann), "--telemetry", "meta"]) == 2
    assert "no per-frame telemetry" in capsys.readouterr().err


@pytest.mark.parametrize("rerun_args", [["save"], ["record", "x.rrd"]])
def test_replay_rejects_bad_rerun_options(tmp_path, capsys, rerun_args):
    write_clip(tmp_path / "clip")
    assert main(["replay", str(tmp_path / "clip"), "--rerun", *rerun_args]) == 2
    assert "--rerun expects" in capsys.readouterr().err


def test_replay_without_telemetry_invents_no_position(tmp_path, capsys):
    write_clip(tmp_path / "clip")
    code = main(
        [
            "replay",
            str(tmp_path / "clip"),
            "--mission",
            str(MISSION),
            "--fps",
            "10",
            "--ds",
            "1",
            "--report",
            str(tmp_path / "report"),
        ]
    )
    out = capsys.readouterr().out
    assert code == 0, out
    assert "telemetry: none given" in out and "simulated" not in out
    alerts = [
        line
        for line in out.splitlines()
        if "target" in line and "score" not in line and line.split()[0] in ("ALERT", "CANDIDATE")
    ]
    assert alerts, out
    assert all("position unknown: no telemetry" in line and "±" not in line for line in alerts)
    rows = (tmp_path / "report" / "alerts.csv").read_text().splitlines()
    assert len(rows) == len(alerts) + 1
    assert all(",,," in r and "position unknown: no telemetry" in r for r in rows[1:])


def test_replay_of_a_video_without_a_frame_count_ends_with_its_summary(tmp_path, capsys):
    """A Matroska recording (no frame count in the container) is replayed to the end, its
    summary printed and the report written, with no traceback."""
    frames = [cv2.imread(str(p)) for p in write_clip(tmp_path / "clip")]
    path = tmp_path / "clip.mkv"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (320, 180))
    for frame in frames:
        writer.write(frame)
    writer.release()
    code = main(
        [
            "replay",
            str(path),
            "--mission",
            str(MISSION),
            "--ds",
            "1",
            "--no-progress",
            "--report",
            str(tmp_path / "report"),
        ]
    )
    out = capsys.readouterr().out
    assert code == 0, out
    assert "clip.mkv (? frames)" in out
    assert (tmp_path / "report" / "alerts.csv").is_file()


def test_replay_with_a_tlog_aligned_by_offset_writes_the_report(tmp_path, capsys):
    write_clip(tmp_path / "clip")
    write_tlog(tmp_path / "flight.tlog", seconds=10.0, pitch_deg=-90.0)
    code = main(
        [
            "replay",
            str(tmp_path / "clip"),
            "--mission",
            str(MISSION),
            "--fps",
            "10",
            "--ds",
            "1",
            "--telemetry",
            str(tmp_path / "flight.tlog"),
            "--time-offset",
            "102",
            "--report",
            str(tmp_path / "report"),
        ]
    )
    out = capsys.readouterr().out
    assert code == 0, out
    assert "telemetry: MAVLink tlog flight.tlog" in out
    assert "alignment: given offset: image 1 at log time 102.000 s" in out
    for name in ("report.html", "alerts.kml", "alerts.geojson", "alerts.csv"):
        assert (tmp_path / "report" / name).stat().st_size > 0
    geo = json.loads((tmp_path / "report" / "alerts.geojson").read_text())
    track = [f for f in geo["features"] if f["id"] == "flight-track"]
    assert track and len(track[0]["geometry"]["coordinates"]) >= 2
    placed = [f for f in geo["features"] if f["id"] != "flight-track" and f["geometry"]]
    assert placed, out  # the hover places what it sees, with the log's accuracy
    assert all(f["properties"]["error_m"] >= 1.5 for f in placed)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--telemetry", "flight.tlg"], "--telemetry flight.tlg: no such file"),
        (["--time-offset", "nan"], "--time-offset must be a number of seconds, got nan"),
    ],
)
def test_replay_refuses_a_missing_log_or_a_bad_offset_before_any_frame(
    tmp_path, capsys, monkeypatch, extra, message
):
    """A typo in the log's name once cost a whole replay without positions (exit 0)."""
    write_clip(tmp_path / "clip")
    monkeypatch.chdir(tmp_path)
    code = main(["replay", str(tmp_path / "clip"), "--mission", str(MISSION), *extra])
    captured = capsys.readouterr()
    assert code == 2
    assert message in captured.err and len(captured.err.strip().splitlines()) == 1
    assert "frames processed" not in captured.out


def test_replay_of_nothing_readable_is_an_error_not_a_success(tmp_path, capsys):
    """Every frame unreadable once ended 'frames processed: 0' with exit 0, as a replay that
    found nothing would."""
    (tmp_path / "clip").mkdir()
    (tmp_path / "clip" / "f000.png").write_bytes(b"not a png")
    code = main(["replay", str(tmp_path / "clip"), "--mission", str(MISSION), "--no-progress"])
    captured = capsys.readouterr()
    assert code == 2
    assert "frames processed: 0" in captured.out
    assert "no frame could be processed (all 1 unreadable)" in captured.err


def test_replay_whose_every_frame_was_rejected_says_how_many_and_why(tmp_path, capsys):
    """Frames found but all rejected by the controller were reported as 'none found'."""
    (tmp_path / "clip").mkdir()
    for i in range(3):
        cv2.imwrite(str(tmp_path / "clip" / f"f{i}.png"), np.full((8, 8, 3), 90, np.uint8))
    code = main(["replay", str(tmp_path / "clip"), "--mission", str(MISSION), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2
    assert "no frame could be processed (3 found, all rejected: 3 image too small)" in err


def test_replay_refuses_a_log_of_another_day(tmp_path, capsys):
    write_mp4(tmp_path / "clip.mp4", frames=8, created=START_UTC + 3 * 86400)
    write_tlog(tmp_path / "flight.tlog", seconds=10.0)
    code = main(
        [
            "replay",
            str(tmp_path / "clip.mp4"),
            "--mission",
            str(MISSION),
            "--ds",
            "1",
            "--telemetry",
            str(tmp_path / "flight.tlog"),
        ]
    )
    out = capsys.readouterr().out
    assert code == 0, out
    assert "telemetry: none: the video was recorded 2024-05-04" in out
    assert "not the same flight; no positions" in out
    assert "frames processed: 8" in out


def test_replay_reads_a_video_file_as_detect_does(tmp_path):
    """The desk replay takes a video's decoder planes, as `detect` and `run --video` do, so one
    file gives the same detections everywhere; the controller gets the planes unconverted."""
    from sarmission.commands.replay import _file_frames
    from sarmission.data.frames import open_frame_source
    from sarmission.yuv import YuvImage

    write_mp4(tmp_path / "clip.mp4", frames=6)
    frames, count, _ = _file_frames(tmp_path / "clip.mp4", 10.0)
    pictures = [image for _, _, image, _ in frames]
    assert count == 6 and len(pictures) == 6
    assert all(isinstance(p, YuvImage) for p in pictures)
    as_detect = [f.image for f in open_frame_source(tmp_path / "clip.mp4", yuv=True)]
    assert all(np.array_equal(a.y, b.y) for a, b in zip(pictures, as_detect, strict=True))
    # grey level 10 k in every frame: the planes are the file's pictures, in order
    assert [int(np.median(p.to_gray(p.y))) for p in pictures] == pytest.approx(
        [10 * k for k in range(6)], abs=3
    )
