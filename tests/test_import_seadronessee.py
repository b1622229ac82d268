"""SeaDronesSee importer: the real validation annotations, and a fixture in the MOT layout."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import cv2
import numpy as np
import pytest

from sarmission.data.coco_video import read_coco_video, write_coco_video
from sarmission.data.importers import import_dataset
from sarmission.data.meta_conventions import dataset_conventions

REAL = Path(__file__).resolve().parents[2] / "shared" / "datasets" / "seadronessee"


@pytest.mark.skipif(not (REAL / "instances_val.json").is_file(), reason="no real SeaDronesSee file")
def test_real_validation_file(tmp_path):
    data = import_dataset("seadronessee", REAL / "instances_val.json", progress=False)
    names = {c.id: c.name for c in data.categories}
    assert len(data.images) == 1547
    assert Counter(names[a.category_id] for a in data.annotations) == {
        "swimmer": 6206,
        "boat": 2214,
        "buoy": 560,
        "life_saving_appliances": 330,
        "jetski": 320,
    }
    assert data.info["meta_conventions"] == {"gimbal_pitch": "depression"}
    assert data.info["images_not_found"] == 1547  # the images are published apart
    first = next(im for im in data.images if im.extra["seadronessee_id"] == 3464)
    video = next(v for v in data.videos if v.id == first.video_id)
    assert (video.name, first.frame_index) == ("DJI_0032/DJI_0032.MP4", 5415)
    assert first.telemetry.gimbal_pitch == pytest.approx(13.7)
    assert sum(not im.telemetry.is_empty() for im in data.images) == 1093
    out = tmp_path / "sds.json"
    write_coco_video(data, out)
    back = read_coco_video(out)
    conventions = dataset_conventions(back)
    assert conventions.pitch == "depression" and "stated" in conventions.how
    assert [a.bbox for a in back.annotations] == [a.bbox for a in data.annotations]


def test_mot_layout_with_floaters_ignored_regions_and_images(tmp_path):
    root = tmp_path / "SeaDronesSee_MOT"
    (root / "annotations").mkdir(parents=True)
    for name in ("0.png", "1.png"):
        (root / "images" / "train").mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(root / "images" / "train" / name), np.zeros((30, 40, 3), np.uint8))
    meta = {"gps_latitude": 47.67, "gps_longitude": 9.27, "altitude": 20.0, "gimbal_pitch": 45.0}
    doc = {
        "videos": [{"id": 7, "name": "DJI_0057"}],
        "images": [
            {
                "id": 10,
                "file_name": "0.png",
                "height": 30,
                "width": 40,
                "video_id": 7,
                "frame_index": 0,
                "meta": meta,
            },
            {
                "id": 11,
                "file_name": "1.png",
                "height": 30,
                "width": 40,
                "video_id": 7,
                "frame_index": 1,
                "meta": None,
            },
        ],
        "annotations": [
            {"id": 1, "image_id": 10, "bbox": [1, 2, 5, 6], "category_id": 2, "track_id": 4},
            {"id": 2, "image_id": 11, "bbox": [2, 2, 5, 6], "category_id": 2, "track_id": 4},
            {"id": 3, "image_id": 11, "bbox": [20, 10, 10, 10], "category_id": 0},
            {"id": 4, "image_id": 11, "bbox": [35, 25, 10, 10], "category_id": 1},
        ],
        "categories": [
            {"id": 0, "name": "ignored"},
            {"id": 1, "name": "swimmer"},
            {"id": 2, "name": "floater"},
        ],
    }
    (root / "annotations" / "instances_train_objects_in_water.json").write_text(json.dumps(doc))
    (root / "annotations" / "instances_val_objects_in_water.json").write_text(
        json.dumps(dict(doc, annotations=[]))
    )
    data = import_dataset("seadronessee", root, split="train", progress=False)
    names = {c.id: c.name for c in data.categories}
    assert [Path(im.file_name) for im in data.images] == [
        (root / "images" / "train" / n).resolve() for n in ("0.png", "1.png")
    ]
    assert "images_not_found" not in data.info
    assert [
        (v.name, [im.frame_index for im in data.images if im.video_id == v.id]) for v in data.videos
    ] == [("DJI_0057", [0, 1])]
    rows = [(names[a.category_id], a.bbox, a.iscrowd, a.track_id) for a in data.annotations]
    assert rows == [
        ("swimmer_with_life_jacket", (1.0, 2.0, 5.0, 6.0), 0, 4),
        ("swimmer_with_life_jacket", (2.0, 2.0, 5.0, 6.0), 0, 4),
        ("ignored", (20.0, 10.0, 10.0, 10.0), 1, None),
        ("swimmer", (35.0, 25.0, 5.0, 5.0), 0, None),  # clipped to the 40x30 image
    ]
    assert data.images[0].telemetry.altitude == 20.0
    both = import_dataset("seadronessee", root, progress=False)
    assert len(both.images) == 4
    # the MOT release labels the same frames twice (objects in water; swimmers alone):
    # imported together every frame came twice, with its swimmers' boxes doubled
    (root / "annotations" / "instances_train_swimmer.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"annotate the same images \(2 shared"):
        import_dataset("seadronessee", root, split="train", progress=False)
    one = import_dataset(
        "seadronessee", root / "annotations" / "instances_train_swimmer.json", progress=False
    )
    assert len(one.images) == 2
    with pytest.raises(ValueError, match="no instances_test"):
        import_dataset("seadronessee", root, split="test", progress=False)


def _pitched(path: Path, pitches: list[float], info: dict | None = None) -> Path:
    """A one-video SeaDronesSee file whose frames have ``pitches`` (no images needed)."""
    images = [
        {
            "id": i + 1,
            "file_name": f"{i}.png",
            "height": 30,
            "width": 40,
            "video_id": 1,
            "frame_index": i,
            "meta": {
                "gps_latitude": 47.6,
                "gps_longitude": 9.2,
                "altitude": 30.0,
                "gimbal_pitch": p,
            },
        }
        for i, p in enumerate(pitches)
    ]
    doc = {
        "videos": [{"id": 1, "name": "DJI_0001"}],
        "images": images,
        "annotations": [],
        "categories": [{"id": 1, "name": "swimmer"}],
        "info": info or {},
    }
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize(
    ("pitches", "info", "stated"),
    [
        ([45.0, 60.0], None, "depression"),  # the dataset's own convention
        ([-31.0, -34.0], None, "elevation"),  # as replay reads the raw file
        ([-31.0, -34.0], {"meta_conventions": {"gimbal_pitch": "elevation"}}, "elevation"),
        ([0.0, 0.0], None, "depression"),  # nothing to tell apart: the dataset's
    ],
)
def test_the_pitch_convention_stated_is_the_file_s_own(tmp_path, pitches, info, stated):
    """The import once stated 'depression' whatever the file said: a file stating elevation
    became one whose every frame looks above the horizon."""
    source = _pitched(tmp_path / "instances_val.json", pitches, info)
    data = import_dataset("seadronessee", source, progress=False)
    assert data.info["meta_conventions"] == {"gimbal_pitch": stated}
    assert dataset_conventions(data).pitch == stated
    if any(pitches):  # all 0 is the horizon either way: no convention to keep
        raw = dataset_conventions(read_coco_video(source)).pitch
        assert dataset_conventions(data).pitch == raw


def test_a_file_with_both_pitch_signs_is_refused_not_half_placed(tmp_path):
    source = _pitched(tmp_path / "instances_val.json", [45.0, 60.0, -45.0])
    with pytest.raises(ValueError, match="instances_val.json: gimbal pitch has both signs"):
        import_dataset("seadronessee", source, progress=False)


def test_frame_numbers_as_strings_are_kept_and_a_lost_one_is_said(tmp_path, caplog):
    """One frame_no given as "400" once renumbered the whole video 0, 1, 2, 3 in list order,
    without a word: the real frame numbers (the frames' times) were lost."""

    def doc(numbers):
        images = [
            {
                "id": i + 1,
                "file_name": f"{i}.jpg",
                "height": 30,
                "width": 40,
                "source": {"video": "DJI_0001.MP4", "frame_no": n},
            }
            for i, n in enumerate(numbers)
        ]
        return {"images": images, "annotations": [], "categories": [{"id": 1, "name": "swimmer"}]}

    path = tmp_path / "instances_val.json"
    path.write_text(json.dumps(doc([300, 100, 200, "400"])))
    data = import_dataset("seadronessee", path, progress=False)
    assert [im.frame_index for im in data.images] == [300, 100, 200, 400]
    assert "no frame number" not in caplog.text
    path.write_text(json.dumps(doc([300, 100, "last", 400])))
    data = import_dataset("seadronessee", path, progress=False)
    assert [im.frame_index for im in data.images] == [0, 1, 2, 3]
    assert "video DJI_0001.MP4: 1 of 4 frames have no frame number" in caplog.text


def test_a_file_of_one_split_is_not_imported_as_another(tmp_path):
    """`--split train` with instances_val.json imported the validation split as training."""
    source = _pitched(tmp_path / "instances_val.json", [45.0])
    with pytest.raises(ValueError, match="instances_val.json is the val split, not train"):
        import_dataset("seadronessee", source, split="train", progress=False)
    assert len(import_dataset("seadronessee", source, split="val", progress=False).images) == 1
