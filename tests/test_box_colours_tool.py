"""``tools/box_colours.py``: the colour and size of each class's boxes, per annotated source."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from conftest import load_tool

#: Hue (OpenCV 0-180), saturation, value of the painted objects.
ORANGE = (15, 200, 240)
GREY_BLUE = (105, 40, 90)


@pytest.fixture(scope="module")
def tool():
    return load_tool("box_colours")


def _bgr(hsv: tuple[int, int, int]) -> tuple[int, ...]:
    pixel = np.array([[hsv]], np.uint8)
    return tuple(int(v) for v in cv2.cvtColor(pixel, cv2.COLOR_HSV2BGR)[0, 0])


def _dataset(folder: Path) -> Path:
    """Two 80x60 PNG frames of grey-blue water: an orange 10x10 buoy on a 20x20 box of water
    (so its most saturated fifth is all buoy), a buoy cut off by the frame's edge, and a 3-px
    speck below the smallest side; all labelled ``buoy``."""
    folder.mkdir()
    images, annotations = [], []
    for k in range(2):
        frame = np.full((60, 80, 3), _bgr(GREY_BLUE), np.uint8)
        frame[25:35, 25:35] = _bgr(ORANGE)
        frame[0:8, 72:80] = _bgr(ORANGE)
        frame[50:53, 5:8] = _bgr(ORANGE)
        cv2.imwrite(str(folder / f"f{k}.png"), frame)
        images.append({"id": k + 1, "file_name": f"f{k}.png", "height": 60, "width": 80})
        boxes = ([20, 20, 20, 20], [70, -2, 12, 10], [5, 50, 3, 3])
        for j, box in enumerate(boxes):
            annotations.append(
                {"id": 3 * k + j + 1, "image_id": k + 1, "category_id": 1, "bbox": box}
            )
    path = folder / "annotations.json"
    categories = [{"id": 1, "name": "buoy"}, {"id": 2, "name": "swimmer"}]
    content = {"images": images, "annotations": annotations, "categories": categories}
    path.write_text(json.dumps(content))
    return path


def test_the_standing_out_colour_and_size_of_each_box(tool, tmp_path):
    measured = tool.measure(_dataset(tmp_path / "a"), {"buoy", "swimmer"}, 1, 4.0)
    assert list(measured) == ["buoy"]  # the speck and the cut-off buoy are left out
    rows = measured["buoy"]
    assert rows.shape == (2, 4)
    for hue, sat, val, side in rows:
        assert abs(hue - ORANGE[0]) <= 1 and abs(sat - ORANGE[1]) <= 3
        assert abs(val - ORANGE[2]) <= 3 and side == 20.0
    with_specks = tool.measure(_dataset(tmp_path / "b"), {"buoy"}, 1, 1.0)
    assert sorted(with_specks["buoy"][:, 3]) == [3.0, 3.0, 20.0, 20.0]
    assert "| 3 / 12 / 20 | 50 % |" in tool.table({"s": with_specks}, ["buoy"])


def test_the_page_names_each_source_and_class(tool, tmp_path, capsys):
    path = _dataset(tmp_path / "a")
    doc = tmp_path / "page.md"
    assert tool.main([f"sim={path}", f"other={path}", "--every", "1", "--doc", str(doc)]) == 0
    text = doc.read_text()
    assert text.count("| buoy | 2 | 15 / 15 / 15 |") == 2
    assert text.count("| 20 / 20 / 20 | 0 % |") == 2  # longer side, none under 16 px
    assert "| sim | buoy |" in text and "| other | buoy |" in text
    assert "swimmer |" not in text.split(tool.BEGIN)[1]  # no swimmer boxes: no row
    assert "| sim | buoy |" in capsys.readouterr().out


def test_bad_sources_are_one_line_errors(tool, tmp_path, capsys):
    for bad in (["nameless.json"], [f"x={tmp_path / 'none.json'}"]):
        with pytest.raises(SystemExit) as stop:
            tool.main(bad)
        assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "expected NAME=ANNOTATIONS.json" in err and "annotation file not found" in err
