"""VisDrone importer: DET and VID folders written in VisDrone's own layout, imported, written as
COCO video and read back."""

import logging
from pathlib import Path

import cv2
import numpy as np
import pytest

from sarmission.class_roles import role_of
from sarmission.data.coco_video import (
    DatasetFormatError,
    VideoDataset,
    read_coco_video,
    write_coco_video,
)
from sarmission.data.importers import import_dataset
from sarmission.data.importers.visdrone import import_visdrone

WIDTH, HEIGHT = 64, 48


def write_image(path: Path, width: int = WIDTH, height: int = HEIGHT) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), np.full((height, width, 3), 90, np.uint8))


def write_text(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def det_release(root: Path) -> Path:
    """A DET folder: two annotated images, an annotation without its image, an image without
    its annotation."""
    folder = root / "VisDrone2019-DET-train"
    write_image(folder / "images" / "0000002_00005_d_0000014.jpg")
    write_image(folder / "images" / "0000007_04999_d_0000036.jpg", 32, 24)
    write_image(folder / "images" / "9999999_00000_d_0000001.jpg")  # no annotation file
    write_text(
        folder / "annotations" / "0000002_00005_d_0000014.txt",
        "10,5,20,10,1,1,0,0\n"  # pedestrian
        "30,20,10,8,1,2,0,1,\n"  # people, trailing comma
        "\n"
        "0,0,16,12,0,0,0,0\n"  # ignored region
        "40,30,30,30,1,8,1,2\n"  # awning-tricycle, clipped to the image
        "5,5,4,4,0,4,0,0\n",  # a car not counted (score 0)
    )
    write_text(
        folder / "annotations" / "0000007_04999_d_0000036.txt",
        "1,2,3,4,1,11,0,0\n2,2,5,5,1,10,0,1\n",  # others, motor
    )
    write_text(folder / "annotations" / "0000404_00000_d_0000404.txt", "1,1,1,1,1,1,0,0\n")
    return folder


def vid_release(root: Path) -> Path:
    """A VID folder: one sequence of three frames, an annotation file without its sequence."""
    folder = root / "VisDrone2019-VID-val"
    for frame in (1, 2, 3):
        write_image(folder / "sequences" / "uav0000086_00000_v" / f"{frame:07d}.jpg")
    write_text(
        folder / "annotations" / "uav0000086_00000_v.txt",
        "1,1,10,10,8,8,1,4,0,0\n"
        "2,1,11,10,8,8,1,4,0,0\n"
        "3,2,20,20,5,10,1,1,0,1\n"
        "2,0,0,0,20,20,0,0,0,0\n"  # ignored region: no track
        "5,1,12,10,8,8,1,4,0,0\n",  # frame 5 has no image
    )
    write_text(folder / "annotations" / "uav0000999_00000_v.txt", "1,1,1,1,2,2,1,1,0,0\n")
    return folder


def round_trip(dataset: VideoDataset, tmp_path: Path) -> VideoDataset:
    path = tmp_path / "out.json"
    write_coco_video(dataset, path)
    back = read_coco_video(path)
    assert back == dataset
    return back


def category_names(dataset: VideoDataset) -> dict[int, str]:
    return {c.id: c.name for c in dataset.categories}


def test_det_images_boxes_categories_and_ignore_regions(tmp_path, caplog):
    folder = det_release(tmp_path)
    with caplog.at_level(logging.WARNING):
        data = round_trip(import_visdrone(folder, progress=False), tmp_path)
    names = category_names(data)
    assert [Path(im.file_name).name for im in data.images] == [
        "0000002_00005_d_0000014.jpg",
        "0000007_04999_d_0000036.jpg",
    ]
    assert all(Path(im.file_name).is_absolute() for im in data.images)
    assert [(im.width, im.height) for im in data.images] == [(64, 48), (32, 24)]
    assert data.videos == [] and all(im.video_id is None for im in data.images)
    boxes = [
        (a.image_id, names[a.category_id], a.bbox, a.iscrowd, a.track_id, a.extra)
        for a in data.annotations
    ]
    assert boxes == [
        (
            1,
            "person",
            (10.0, 5.0, 20.0, 10.0),
            0,
            None,
            {"truncation": 0, "occlusion": 0, "visdrone_category": "pedestrian"},
        ),
        (
            1,
            "person",
            (30.0, 20.0, 10.0, 8.0),
            0,
            None,
            {"truncation": 0, "occlusion": 1, "visdrone_category": "people"},
        ),
        (1, "ignored", (0.0, 0.0, 16.0, 12.0), 1, None, {"truncation": 0, "occlusion": 0}),
        (
            1,
            "awning_tricycle",
            (40.0, 30.0, 24.0, 18.0),
            0,
            None,
            {"truncation": 1, "occlusion": 2},
        ),
        (1, "car", (5.0, 5.0, 4.0, 4.0), 1, None, {"truncation": 0, "occlusion": 0}),
        (2, "others", (1.0, 2.0, 3.0, 4.0), 0, None, {"truncation": 0, "occlusion": 0}),
        (2, "motor", (2.0, 2.0, 5.0, 5.0), 0, None, {"truncation": 0, "occlusion": 1}),
    ]
    assert data.info["skipped"] == {"no image file": 1, "image without annotation file": 1}
    assert data.info["visdrone_layout"] == "DET"
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "0000404_00000_d_0000404.txt" in warnings[0]
    supers = {c.name: c.supercategory for c in data.categories}
    assert supers["person"] == "person" and supers["car"] is None


def test_vid_sequences_become_videos_with_tracks(tmp_path, caplog):
    folder = vid_release(tmp_path)
    with caplog.at_level(logging.WARNING):
        data = round_trip(import_visdrone(folder, progress=False), tmp_path)
    names = category_names(data)
    assert [v.name for v in data.videos] == ["uav0000086_00000_v"]
    assert [(Path(im.file_name).name, im.video_id, im.frame_index) for im in data.images] == [
        ("0000001.jpg", 1, 0),
        ("0000002.jpg", 1, 1),
        ("0000003.jpg", 1, 2),
    ]
    assert all((im.width, im.height) == (64, 48) for im in data.images)
    boxes = [
        (a.image_id, a.video_id, a.track_id, names[a.category_id], a.bbox, a.iscrowd)
        for a in data.annotations
    ]
    assert boxes == [
        (1, 1, 1, "car", (10.0, 10.0, 8.0, 8.0), 0),
        (2, 1, 1, "car", (11.0, 10.0, 8.0, 8.0), 0),
        (3, 1, 2, "person", (20.0, 20.0, 5.0, 10.0), 0),
        (2, 1, None, "ignored", (0.0, 0.0, 20.0, 20.0), 1),
    ]
    assert data.annotations[2].extra == {
        "truncation": 0,
        "occlusion": 1,
        "visdrone_category": "pedestrian",
    }
    assert data.info["skipped"] == {"box of a missing frame": 1, "no image file": 1}
    assert data.info["visdrone_layout"] == "VID"
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 2
    assert "uav0000999_00000_v" in warnings[1] and "1 box(es)" in warnings[0]


def test_split_picks_the_release_folder(tmp_path):
    det_release(tmp_path)
    vid_release(tmp_path)
    assert import_visdrone(tmp_path, split="train", progress=False).info["visdrone_layout"] == "DET"
    val = import_dataset("visdrone", tmp_path, split="VAL", progress=False)
    assert val.info["visdrone_layout"] == "VID" and len(val.images) == 3
    with pytest.raises(DatasetFormatError, match=r"no VisDrone layout.*-test.*DET-train"):
        import_visdrone(tmp_path, split="test", progress=False)
    with pytest.raises(DatasetFormatError, match="no VisDrone layout"):
        import_visdrone(tmp_path, progress=False)
    with pytest.raises(DatasetFormatError, match=r"the 'train' split, not 'val'"):
        import_visdrone(tmp_path / "VisDrone2019-DET-train", split="val", progress=False)


def test_two_folders_of_one_split_are_ambiguous(tmp_path):
    det_release(tmp_path)
    vid_release(tmp_path)
    (tmp_path / "VisDrone2019-VID-val").rename(tmp_path / "VisDrone2019-VID-train")
    with pytest.raises(DatasetFormatError, match="several VisDrone folders for split 'train'"):
        import_visdrone(tmp_path, split="train", progress=False)


def test_missing_folder_is_refused(tmp_path):
    with pytest.raises(DatasetFormatError, match="not a folder"):
        import_visdrone(tmp_path / "nowhere", progress=False)
    (tmp_path / "images").mkdir()
    with pytest.raises(DatasetFormatError, match="no VisDrone layout"):
        import_visdrone(tmp_path, progress=False)


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("1,2,3,4,1,1,0\n", r":2: 7 columns, expected 8"),
        ("1,2,3,4,1,x,0,0\n", r":2: not numbers"),
        ("1,2,nan,4,1,1,0,0\n", r":2: not numbers"),
        ("1,2,3,4,1,1,inf,0\n", r":2: not numbers"),
        ("1,2,3,4,1,12,0,0\n", r":2: unknown VisDrone category 12"),
    ],
)
def test_malformed_det_lines_name_file_and_line(tmp_path, line, message):
    folder = tmp_path / "VisDrone2019-DET-val"
    write_image(folder / "images" / "a.jpg")
    write_text(folder / "annotations" / "a.txt", "1,1,2,2,1,1,0,0\n" + line)
    with pytest.raises(DatasetFormatError, match=r"a\.txt" + message):
        import_visdrone(folder, progress=False)


def test_malformed_vid_line_names_file_and_line(tmp_path):
    folder = vid_release(tmp_path)
    write_text(folder / "annotations" / "uav0000086_00000_v.txt", "\n1,1,10,10,8,8,1,4,0\n")
    with pytest.raises(DatasetFormatError, match=r"uav0000086_00000_v\.txt:2: 9 columns"):
        import_visdrone(folder, progress=False)


def test_visdrone_vehicles_are_objects_and_people_people():
    vehicles = ["bicycle", "car", "van", "truck", "tricycle", "awning_tricycle", "bus", "motor"]
    assert [role_of(name) for name in vehicles] == ["object"] * len(vehicles)
    assert role_of("person") == "person"


def test_a_binary_annotation_file_is_named(tmp_path):
    folder = tmp_path / "VisDrone2019-DET-val"
    write_image(folder / "images" / "a.jpg")
    (folder / "annotations").mkdir(parents=True, exist_ok=True)
    (folder / "annotations" / "a.txt").write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(DatasetFormatError, match=r"a\.txt: not a text file"):
        import_visdrone(folder, progress=False)
