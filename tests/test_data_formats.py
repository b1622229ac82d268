"""COCO video (SeaDronesSee) reading/writing with telemetry, MOT and YOLO text round trips."""

import json
import logging
import shutil
from pathlib import Path

import numpy as np
import pytest

from sarmission.data import (
    DatasetFormatError,
    FrameTelemetry,
    MotRow,
    YoloBox,
    parse_telemetry,
    read_coco_video,
    read_mot,
    read_yolo,
    write_coco_video,
    write_mot,
    write_yolo,
    xyxy_to_yolo,
    yolo_to_xyxy,
)

FIXTURE = Path(__file__).parent / "fixtures" / "seadronessee_sample.json"


def test_sample_structure():
    ds = read_coco_video(FIXTURE)
    assert [v.name for v in ds.videos] == ["DJI_0001", "DJI_0002"]
    assert ds.videos[0].extra == {"width": 3840, "height": 2160}
    assert [im.id for im in ds.video_images(1)] == [10, 11]
    assert [c.name for c in ds.categories] == ["swimmer", "boat"]
    assert ds.categories[0].supercategory == "person" and ds.categories[1].supercategory is None
    first = ds.annotations[0]
    assert first.bbox == (100.0, 200.0, 12.0, 10.0) and first.track_id == 1
    assert (first.gt_lat, first.gt_lon) == (47.6711, 9.2699)
    assert ds.annotations[2].extra == {"occluded": False}
    assert ds.annotations[3].area == 400.0  # computed from bbox when absent
    assert ds.images[3].extra == {"source": "drone-2"}
    assert {k: len(v) for k, v in ds.annotations_by_image().items()} == {10: 1, 11: 2, 20: 0, 21: 1}


def test_sample_telemetry_mot_keys():
    t = read_coco_video(FIXTURE).image(10).telemetry
    assert (t.latitude, t.longitude, t.altitude) == (47.671044, 9.269786, 8.3)
    assert (t.gimbal_pitch, t.compass_heading, t.gimbal_heading) == (43.9, 137.7, 137.5)
    assert t.speed == 2.5  # numeric string parsed
    assert (t.xspeed, t.yspeed, t.zspeed) == (1.5, -2.0, 0.0)
    assert t.gimbal_roll is None
    assert t.time == 1598360394.0  # 2020-08-25T12:59:54 UTC


def test_sample_telemetry_null_and_missing_meta():
    ds = read_coco_video(FIXTURE)
    assert ds.image(11).meta is None and ds.image(11).telemetry == FrameTelemetry()
    assert ds.image(20).meta is None and ds.image(20).telemetry.is_empty()


def test_sample_telemetry_v2_unit_keys(caplog):
    with caplog.at_level(logging.WARNING):
        t = read_coco_video(FIXTURE).image(21).telemetry
    assert (t.latitude, t.longitude) == (47.6805, 9.2791)
    assert t.altitude == 52.4  # height_above_takeoff, not altitude above sea level
    assert (t.gimbal_pitch, t.gimbal_roll, t.gimbal_heading) == (90.0, 0.0, 12.0)
    assert (t.compass_heading, t.speed, t.xspeed, t.zspeed) == (11.8, 4.2, 0.5, -0.1)
    assert t.yspeed is None  # "n/a" -> None with a warning
    assert "ySpeed(m/s)" in caplog.text
    assert t.time == 1615112130.0  # 2021-03-07 10:15:30 UTC


def test_parse_telemetry_variants(caplog):
    t = parse_telemetry(
        {
            "GPS_LATITUDE": "12.5",
            "gps_latitude_ref": "S",
            "gps_longitude": 3,
            "gps_longitude_ref": "W",
            "time(ms)": 1500,
            "Gimbal Pitch (deg)": None,
            "speed": [1, 2],
            "altitude": float("nan"),
        }
    )
    assert (t.latitude, t.longitude, t.time) == (-12.5, -3.0, 1.5)
    assert t.gimbal_pitch is None and t.speed is None and t.altitude is None
    assert parse_telemetry({"date_time": "2020:08:25 12:59:54"}).time == 1598360394.0
    assert parse_telemetry({"date_time": "garbage"}).time is None
    assert parse_telemetry({}) == FrameTelemetry() == parse_telemetry(None)


def test_coco_round_trip(tmp_path):
    ds = read_coco_video(FIXTURE)
    out = tmp_path / "out.json"
    write_coco_video(ds, out)
    again = read_coco_video(out)
    assert again == ds
    write_coco_video(again, tmp_path / "out2.json")
    assert (tmp_path / "out2.json").read_text() == out.read_text()


def test_image_paths(tmp_path):
    shutil.copy(FIXTURE, tmp_path / "ann.json")
    ds = read_coco_video(tmp_path / "ann.json")
    image = ds.image(10)
    assert ds.image_path(image) == tmp_path / "images" / "DJI_0001/000000.png"
    (tmp_path / "DJI_0001").mkdir()
    (tmp_path / "DJI_0001" / "000000.png").write_bytes(b"")
    assert ds.image_path(image) == tmp_path / "DJI_0001" / "000000.png"
    assert ds.image_path(image, root="/data") == Path("/data/DJI_0001/000000.png")


def _broken(tmp_path, mutate):
    doc = json.loads(FIXTURE.read_text())
    mutate(doc)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda d: d.pop("images"), "missing required top-level key 'images'"),
        (lambda d: d["images"][1].pop("file_name"), "images[1] (id=11) is missing required key"),
        (lambda d: d["annotations"][0].pop("bbox"), "'bbox'"),
        (lambda d: d["annotations"][0].update(bbox=[1, 2, 3]), "must be 4 numbers"),
        (lambda d: d["annotations"][0].update(image_id=999), "unknown image_id 999"),
        (lambda d: d["categories"].append({"id": 1, "name": "dup"}), "duplicate id 1"),
        (lambda d: d["images"][0].update(height="tall"), "'height' must be an integer"),
        (lambda d: d.update(annotations={}), "'annotations' must be a list"),
    ],
)
def test_malformed_files(tmp_path, mutate, message):
    path = _broken(tmp_path, mutate)
    with pytest.raises(DatasetFormatError) as info:
        read_coco_video(path)
    assert message in str(info.value) and str(path) in str(info.value)


def test_invalid_json_and_missing_file(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"images": [')
    with pytest.raises(DatasetFormatError, match="not valid JSON"):
        read_coco_video(bad)
    with pytest.raises(DatasetFormatError, match="cannot read"):
        read_coco_video(tmp_path / "none.json")
    assert issubclass(DatasetFormatError, ValueError)
    null_width = tmp_path / "null_width.json"
    image = {"id": 1, "file_name": "a.jpg", "height": 30, "width": None}
    null_width.write_text(json.dumps({"images": [image], "annotations": [], "categories": []}))
    with pytest.raises(DatasetFormatError, match=r"'width' must be an integer, got null"):
        read_coco_video(null_width)  # once a TypeError in the importers


def test_mot_round_trip(tmp_path):
    rows = [
        MotRow(1, 3, (10.0, 20.5, 8.0, 6.25), 0.875, 1, 1.0),
        MotRow(2, 3, (11.0, 21.0, 8.0, 6.0), 1.0, 1, 0.5),
        MotRow(2, 4, (0.1, 0.2, 0.3, 0.4), -1.0, -1, 1.0),
    ]
    path = tmp_path / "gt.txt"
    write_mot(rows, path)
    assert path.read_text().splitlines()[0] == "1,3,10,20.5,8,6.25,0.875,1,1"
    assert read_mot(path) == rows


def test_mot_short_lines_and_errors(tmp_path):
    path = tmp_path / "det.txt"
    path.write_text("1,-1,5,6,7,8\n\n2,1,5,6,7,8,0.5\n")
    assert read_mot(path) == [
        MotRow(1, -1, (5.0, 6.0, 7.0, 8.0)),
        MotRow(2, 1, (5.0, 6.0, 7.0, 8.0), 0.5),
    ]
    path.write_text("1,1,5,6\n")
    with pytest.raises(DatasetFormatError, match=r"det.txt:1: expected at least 6"):
        read_mot(path)
    path.write_text("1,1,5,6,7,8\n0,1,5,6,7,8\n")
    with pytest.raises(DatasetFormatError, match=r":2: frames are 1-based"):
        read_mot(path)
    path.write_text("1.5,1,5,6,7,8\n")
    with pytest.raises(DatasetFormatError, match=r":1: bad value"):
        read_mot(path)


def test_yolo_round_trip_and_conversion(tmp_path):
    boxes = [YoloBox(0, 0.5, 0.25, 0.1, 0.2), YoloBox(3, 0.123456789, 0.9, 0.01, 0.02, 0.75)]
    path = tmp_path / "img.txt"
    write_yolo(boxes, path)
    assert read_yolo(path) == boxes
    xyxy, classes = yolo_to_xyxy(boxes[:1], width=200, height=100)
    np.testing.assert_allclose(xyxy, [[90.0, 15.0, 110.0, 35.0]])
    assert classes.tolist() == [0]
    assert xyxy_to_yolo(xyxy, classes, 200, 100) == [YoloBox(0, 0.5, 0.25, 0.1, 0.2)]
    empty = tmp_path / "empty.txt"
    write_yolo([], empty)
    assert read_yolo(empty) == []
    path.write_text("0 0.5 0.5 0.1\n")
    with pytest.raises(DatasetFormatError, match="img.txt:1"):
        read_yolo(path)


def test_a_failed_write_leaves_the_old_file_whole(tmp_path, monkeypatch):
    ds = read_coco_video(FIXTURE)
    out = tmp_path / "ann.json"
    write_coco_video(ds, out)
    before = out.read_bytes()
    real_write = Path.write_text

    def disk_full(self, data, *args, **kwargs):  # half the text, then the disk is full
        real_write(self, data[: len(data) // 2], *args, **kwargs)
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Path, "write_text", disk_full)
    with pytest.raises(OSError, match="No space left"):
        write_coco_video(ds, out)
    monkeypatch.undo()
    assert out.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["ann.json"]  # no partial file left
