"""``tools/closer_look_study.py``: which classes it learns, the crops it cuts, its tallies and
its page."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from conftest import load_tool


@pytest.fixture(scope="module")
def tool():
    return load_tool("closer_look_study")


def test_classes_group_as_a_search_needs(tool) -> None:
    assert tool.group_of("Swimmer with life jacket") == "person"
    assert tool.group_of("person") == "person"
    assert tool.group_of("jetski") == "boat"
    assert tool.group_of("Life-saving appliances") == "life_ring"
    assert tool.group_of("log") == "clutter"
    assert tool.group_of("car") is None
    assert set(tool.GROUP.values()) < set(tool.CLASSES)


def test_a_crop_is_centred_on_the_box_with_three_times_its_side(tool) -> None:
    image = np.zeros((300, 400, 3), np.uint8)
    image[140:160, 190:210] = 255  # a 20-px square centred on (200, 150)
    crop = tool.cut_context_crop(image, 200.0, 150.0, 20.0)
    assert crop.shape == (tool.CROP, tool.CROP, 3)
    # a window of 60 px: the square covers its middle third
    third = tool.CROP // 3
    assert crop[third + 2 : -third - 2, third + 2 : -third - 2].min() > 200
    assert crop[: third - 2].max() < 30 and crop[:, -third + 2 :].max() < 30
    # a tiny box still sees MIN_WINDOW pixels: a 2-px box is a speck in the middle
    speck = np.zeros((300, 400, 3), np.uint8)
    speck[149:151, 199:201] = 255
    small = tool.cut_context_crop(speck, 200.0, 150.0, 2.0)
    assert small.max() > 0 and small[0].max() == 0
    # at the frame's corner the image is mirrored, never cut short
    assert tool.cut_context_crop(image, 0.0, 0.0, 30.0).shape == (tool.CROP, tool.CROP, 3)


def test_water_is_cut_only_clear_of_every_box(tool) -> None:
    boxes = [(100.0, 100.0, 10.0, 10.0)]
    assert not tool._clear_of(boxes, 105.0, 105.0, 8.0)
    assert not tool._clear_of(boxes, 120.0, 105.0, 8.0)  # its 24-px window reaches the box
    assert tool._clear_of(boxes, 140.0, 105.0, 8.0)


def _write_dataset(folder) -> object:
    (folder / "clip").mkdir()
    frame = np.full((200, 300, 3), 90, np.uint8)
    frame[50:60, 50:60] = (0, 0, 255)
    frame[120:140, 200:240] = (255, 255, 255)
    cv2.imwrite(str(folder / "clip" / "000000.jpg"), frame)
    doc = {
        "videos": [{"id": 1, "name": "clip", "width": 300, "height": 200, "fps": 1.0}],
        "categories": [
            {"id": 1, "name": "swimmer"},
            {"id": 2, "name": "boat"},
            {"id": 3, "name": "car"},
        ],
        "images": [
            {
                "id": 1,
                "file_name": "clip/000000.jpg",
                "width": 300,
                "height": 200,
                "video_id": 1,
                "frame_index": 0,
            }
        ],
        "annotations": [
            {"id": 1, "image_id": 1, "category_id": 1, "bbox": [50, 50, 10, 10], "area": 100},
            {"id": 2, "image_id": 1, "category_id": 2, "bbox": [200, 120, 40, 20], "area": 800},
            {"id": 3, "image_id": 1, "category_id": 3, "bbox": [10, 150, 8, 8], "area": 64},
        ],
    }
    path = folder / "data.json"
    path.write_text(json.dumps(doc))
    return path


def test_box_crops_label_every_grouped_box_and_some_water(tool, tmp_path) -> None:
    path = _write_dataset(tmp_path)
    rng = np.random.default_rng(0)
    crops, labels = tool.box_crops(path, rng, per_box=2, water_per_frame=3, jitter=False)
    classes = [tool.CLASSES[i] for i in labels]
    assert classes.count("person") == 2 and classes.count("boat") == 2  # the car has no class
    assert 1 <= classes.count("water") <= 3
    person = crops[classes.index("person")]
    assert person[tool.CROP // 2, tool.CROP // 2, 2] > 200  # the red square in the middle


def test_tallies_per_class(tool) -> None:
    classes = tool.CLASSES
    probabilities = np.zeros((4, len(classes)))
    probabilities[0, classes.index("person")] = 0.9  # a person called a person
    probabilities[1, classes.index("buoy")] = 0.6  # a person called a buoy
    probabilities[1, classes.index("person")] = 0.4
    probabilities[2, classes.index("person")] = 0.7  # a buoy called a person
    probabilities[3, classes.index("buoy")] = 1.0  # a buoy called a buoy
    labels = np.array([classes.index(c) for c in ("person", "person", "buoy", "buoy")])
    calls = tool.per_class_calls(probabilities, labels)
    assert set(calls) == {"person", "buoy"}
    assert calls["person"] == {"boxes": 2, "called_person": 0.5, "own_class": 0.5}
    assert calls["buoy"] == {"boxes": 2, "called_person": 0.5, "own_class": 0.5}


def test_the_page_shows_mean_and_range_over_seeds(tool) -> None:
    def run(person: float) -> dict:
        part = {
            "person": {"boxes": 10, "called_person": person, "own_class": person},
            "buoy": {"boxes": 4, "called_person": 0.25, "own_class": 0.5},
        }
        return {"sim_test": part, "heldout_val": part}

    results = {
        "command": "python tools/closer_look_study.py",
        "minutes": 1.5,
        "seeds": [0, 1],
        "train_boxes": 123,
        "variants": {"plain": {"0": run(0.4), "1": run(0.6)}},
    }
    page = tool.render_markdown(results)
    assert "123 crops" in page
    assert "| variant | person (10) | buoy (4) |" in page
    assert "| plain | 50 % (40-60) | 25 % (25-25) |" in page
    assert page.count("### ") == 4


def test_box_crops_read_video_clips_every_stride_frame(tool, tmp_path, monkeypatch) -> None:
    """A file whose videos name an MP4 (the alternative world's) is read from the video, every
    ``VIDEO_STRIDE``-th frame, with the boxes of those frames."""
    from altworld.generate import render_world

    path = render_world("sea", clips=1, frames=5, out=tmp_path, log=lambda _: None)
    monkeypatch.setattr(tool, "VIDEO_STRIDE", 2)
    frames = list(tool._frames(path))
    assert len(frames) == 3  # frames 0, 2 and 4
    doc = json.loads(path.read_text())
    by_frame: dict[int, int] = {}
    for a in doc["annotations"]:
        by_frame[a["image_id"]] = by_frame.get(a["image_id"], 0) + 1
    first_id = min(im["id"] for im in doc["images"])
    assert [len(boxes) for _, boxes in frames] == [by_frame.get(first_id + k, 0) for k in (0, 2, 4)]
    assert frames[0][0].shape == (1080, 1920, 3)
