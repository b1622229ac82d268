"""TinyPerson importer: a ``tiny_set`` folder written in TinyPerson's own layout, imported,
written as COCO video and read back."""

import json
import logging
from pathlib import Path

import cv2
import numpy as np
import pytest

from sarmission.data.coco_video import (
    DatasetFormatError,
    VideoDataset,
    read_coco_video,
    write_coco_video,
)
from sarmission.data.importers import import_dataset
from sarmission.data.importers.tinyperson import import_tinyperson, video_frame

CATEGORIES = [
    {"id": 1, "name": "sea_person", "supercategory": "person"},
    {"id": 2, "name": "earth_person", "supercategory": "person"},
]


def box(ann_id, image_id, category, bbox, **flags):
    """One annotation as TinyPerson writes it."""
    return {
        "segmentation": [[]],
        "area": bbox[2] * bbox[3],
        "iscrowd": 0,
        "image_id": image_id,
        "bbox": bbox,
        "category_id": category,
        "id": ann_id,
        "ignore": flags.get("ignore", False),
        "uncertain": flags.get("uncertain", False),
        "logo": flags.get("logo", False),
        "in_dense_image": flags.get("in_dense_image", False),
    }


def tiny_set(root: Path) -> Path:
    """``root/tiny_set`` with a train part (two frames of video V0032) and a test part (a frame
    of V0005, an image of no video and an image whose file is missing). The JSON sizes
    (640x480) differ from the files' (64x48): the importer must not read the images."""
    folder = root / "tiny_set"
    (folder / "annotations").mkdir(parents=True)
    train = {
        "type": "instance",
        "images": [
            {
                "file_name": "labeled_images/bb_V0032_I0001680.jpg",
                "height": 480,
                "width": 640,
                "id": 0,
            },
            {
                "file_name": "labeled_images/bb_V0032_I0001640.jpg",
                "height": 480,
                "width": 640,
                "id": 1,
            },
        ],
        "annotations": [
            box(0, 1, 1, [10, 20, 4, 6]),
            box(1, 1, 2, [30, 30, 5, 8]),
            box(2, 1, 1, [50, 50, 3, 3], uncertain=True),
            box(3, 0, 2, [60, 60, 4, 4], in_dense_image=True),
            box(4, 0, 1, [70, 70, 2, 2], ignore=True),
            box(5, 0, 2, [80, 80, 6, 6], logo=True),
        ],
        "categories": CATEGORIES,
    }
    test = {
        "type": "instance",
        "images": [
            {
                "file_name": "labeled_images/bb_V0005_I0000320.jpg",
                "height": 480,
                "width": 640,
                "id": 0,
            },
            {"file_name": "labeled_images/beach_0001.jpg", "height": 300, "width": 400, "id": 1},
            {
                "file_name": "labeled_images/bb_V0005_I0000360.jpg",
                "height": 480,
                "width": 640,
                "id": 2,
            },
        ],
        "annotations": [
            box(0, 0, 1, [1, 1, 2, 2]),
            box(1, 1, 2, [5, 5, 3, 3]),
            box(2, 2, 2, [5, 5, 3, 3]),
        ],
        "categories": CATEGORIES,
    }
    (folder / "annotations" / "tiny_set_train.json").write_text(json.dumps(train))
    (folder / "annotations" / "tiny_set_test.json").write_text(json.dumps(test))
    pixels = np.full((48, 64, 3), 120, np.uint8)
    for name in (
        "train/labeled_images/bb_V0032_I0001640.jpg",
        "train/labeled_images/bb_V0032_I0001680.jpg",
        "test/labeled_images/bb_V0005_I0000320.jpg",
        "test/labeled_images/beach_0001.jpg",
    ):
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        assert cv2.imwrite(str(folder / name), pixels)
    return folder


def round_trip(dataset: VideoDataset, tmp_path: Path) -> VideoDataset:
    path = tmp_path / "out.json"
    write_coco_video(dataset, path)
    back = read_coco_video(path)
    assert back == dataset
    return back


def test_both_splits_from_the_parent_folder(tmp_path, caplog):
    folder = tiny_set(tmp_path).resolve()
    with caplog.at_level(logging.WARNING):
        data = round_trip(import_tinyperson(tmp_path, progress=False), tmp_path)
    videos = {v.id: v.name for v in data.videos}
    assert list(videos.values()) == ["V0032", "V0005"]
    images = [
        (
            Path(im.file_name),
            videos.get(im.video_id),
            im.frame_index,
            im.width,
            im.height,
            im.extra,
        )
        for im in data.images
    ]
    assert images == [
        (
            folder / "train/labeled_images/bb_V0032_I0001680.jpg",
            "V0032",
            1680,
            640,
            480,
            {"split": "train"},
        ),
        (
            folder / "train/labeled_images/bb_V0032_I0001640.jpg",
            "V0032",
            1640,
            640,
            480,
            {"split": "train"},
        ),
        (
            folder / "test/labeled_images/bb_V0005_I0000320.jpg",
            "V0005",
            320,
            640,
            480,
            {"split": "test"},
        ),
        (folder / "test/labeled_images/beach_0001.jpg", None, None, 400, 300, {"split": "test"}),
    ]
    assert [im.id for im in data.video_images(1)] == [2, 1]  # frame order
    names = {c.id: c.name for c in data.categories}
    assert {c.name: c.supercategory for c in data.categories} == {
        "swimmer": "person",
        "person": "person",
    }
    boxes = [(a.image_id, names[a.category_id], a.bbox, a.iscrowd) for a in data.annotations]
    assert boxes == [
        (1, "person", (60.0, 60.0, 4.0, 4.0), 1),
        (1, "swimmer", (70.0, 70.0, 2.0, 2.0), 1),
        (2, "swimmer", (10.0, 20.0, 4.0, 6.0), 0),
        (2, "person", (30.0, 30.0, 5.0, 8.0), 0),
        (2, "swimmer", (50.0, 50.0, 3.0, 3.0), 1),
        (3, "swimmer", (1.0, 1.0, 2.0, 2.0), 0),
        (4, "person", (5.0, 5.0, 3.0, 3.0), 0),
    ]
    assert data.annotations[0].extra == {
        "tinyperson_category": "earth_person",
        "ignore": False,
        "uncertain": False,
        "in_dense_image": True,
    }
    assert all(a.track_id is None for a in data.annotations)
    assert data.info["skipped"] == {"logo": 1, "no image file": 1}
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and "bb_V0005_I0000360.jpg" in warnings[0]


def test_one_split_from_the_tiny_set_folder(tmp_path):
    folder = tiny_set(tmp_path)
    train = import_tinyperson(folder, split="train", progress=False)
    assert [Path(im.file_name).name for im in train.images] == [
        "bb_V0032_I0001680.jpg",
        "bb_V0032_I0001640.jpg",
    ]
    assert len(train.annotations) == 5 and train.info["skipped"] == {"logo": 1}
    test = import_dataset("tinyperson", folder, split="TEST", progress=False)
    assert [v.name for v in test.videos] == ["V0005"] and len(test.images) == 2
    with pytest.raises(DatasetFormatError, match=r"no split 'val' \(only train, test\)"):
        import_tinyperson(folder, split="val", progress=False)
    (folder / "annotations" / "tiny_set_test.json").unlink()
    with pytest.raises(DatasetFormatError, match=r"no tiny_set_test\.json"):
        import_tinyperson(folder, split="test", progress=False)
    assert len(import_tinyperson(folder, progress=False).images) == 2


def test_video_frame_names():
    assert video_frame("labeled_images/bb_V0032_I0001640.jpg") == ("V0032", 1640)
    assert video_frame("labeled_images/bb_V0032_I0001640_1.jpg") is None
    assert video_frame("pure_bg_images/IMG_0001.jpg") is None


def test_missing_folders_are_refused(tmp_path):
    with pytest.raises(DatasetFormatError, match="not a folder"):
        import_tinyperson(tmp_path / "nowhere", progress=False)
    with pytest.raises(DatasetFormatError, match="no TinyPerson annotations"):
        import_tinyperson(tmp_path, progress=False)


def test_invalid_json_names_the_file(tmp_path):
    folder = tiny_set(tmp_path)
    (folder / "annotations" / "tiny_set_train.json").write_text('{"images": [')
    with pytest.raises(DatasetFormatError, match=r"tiny_set_train\.json: not a readable JSON"):
        import_tinyperson(folder, progress=False)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda doc: doc.pop("categories"), r"no list 'categories'"),
        (lambda doc: doc["annotations"][2].pop("bbox"), r"annotations\[2\] lacks bbox"),
        (lambda doc: doc["images"][1].pop("width"), r"images\[1\] lacks width"),
        (lambda doc: doc["annotations"][0].update(category_id=7), r"unknown category 7"),
        (lambda doc: doc["annotations"][0].update(image_id=9), r"unknown image 9"),
        (lambda doc: doc["annotations"][0].update(bbox=[1, 2]), r"bbox \[1, 2\] is not 4 numbers"),
        # once a traceback, and boxes copied onto another image
        (lambda doc: doc["annotations"][0].update(image_id=[0]), r"unknown image \[0\]"),
        (lambda doc: doc["images"][1].update(id=0), r"image id 0 is used twice"),
    ],
)
def test_missing_keys_name_the_file(tmp_path, change, message):
    folder = tiny_set(tmp_path)
    path = folder / "annotations" / "tiny_set_train.json"
    doc = json.loads(path.read_text())
    change(doc)
    path.write_text(json.dumps(doc))
    with pytest.raises(DatasetFormatError, match=r"tiny_set_train\.json: .*" + message):
        import_tinyperson(folder, split="train", progress=False)
