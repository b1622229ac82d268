"""LADD and HERIDAL importers: Pascal VOC fixtures written here in each dataset's layout."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from sarmission.cli import main as sarmission
from sarmission.data.coco_video import DatasetFormatError, read_coco_video, write_coco_video
from sarmission.data.importers import import_dataset


def _voc(filename: str, size: tuple[int, int] | None, objects: list[tuple]) -> str:
    size_xml = (
        f"<size><width>{size[0]}</width><height>{size[1]}</height><depth>3</depth></size>"
        if size
        else ""
    )
    objs = "".join(
        f"<object><name>{name}</name><pose>Unspecified</pose><truncated>0</truncated>"
        f"<difficult>{difficult}</difficult><bndbox><xmin>{x0}</xmin><ymin>{y0}</ymin>"
        f"<xmax>{x1}</xmax><ymax>{y1}</ymax></bndbox></object>"
        for name, x0, y0, x1, y1, difficult in objects
    )
    return (
        f"<annotation><folder>JPEGImages</folder><filename>{filename}</filename>"
        f"<source><database>Unknown</database></source>{size_xml}<segmented>0</segmented>"
        f"{objs}</annotation>"
    )


def _image(path: Path, width: int = 80, height: int = 60) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), np.full((height, width, 3), 90, np.uint8))


@pytest.fixture
def ladd(tmp_path: Path) -> Path:
    root = tmp_path / "LADD"
    (root / "Annotations").mkdir(parents=True)
    (root / "ImageSets" / "Main").mkdir(parents=True)
    for stem in ("1_000", "1_001", "2_000"):
        _image(root / "JPEGImages" / f"{stem}.jpg")
    (root / "Annotations" / "1_000.xml").write_text(
        _voc(
            "1_000.jpg",
            (80, 60),
            [("Pedestrian", 11, 21, 20, 40, 0), ("Pedestrian", 70, 50, 95, 70, 1)],
        )
    )
    (root / "Annotations" / "1_001.xml").write_text(_voc("1_001.jpg", (80, 60), []))
    # no <size>: read from the image; a second class kept by name
    (root / "Annotations" / "2_000.xml").write_text(
        _voc("2_000.jpg", None, [("pedestrian", 1, 1, 10, 10, 0), ("Dog", 30, 30, 40, 40, 0)])
    )
    (root / "ImageSets" / "Main" / "train.txt").write_text("1_000\n2_000\n")
    (root / "ImageSets" / "Main" / "test.txt").write_text("1_001\n")
    return root


def test_ladd_boxes_classes_and_split(ladd, tmp_path):
    data = import_dataset("ladd", ladd, progress=False)
    names = {c.id: c.name for c in data.categories}
    assert [Path(im.file_name).name for im in data.images] == [
        "1_000.jpg",
        "1_001.jpg",
        "2_000.jpg",
    ]
    assert all(Path(im.file_name).is_absolute() for im in data.images)
    assert [(im.width, im.height) for im in data.images] == [(80, 60)] * 3
    rows = [(names[a.category_id], a.image_id, a.bbox, a.iscrowd) for a in data.annotations]
    assert rows == [
        ("person", 1, (10.0, 20.0, 10.0, 20.0), 0),  # VOC is 1-based and inclusive
        ("person", 1, (69.0, 49.0, 11.0, 11.0), 1),  # difficult -> ignore; clipped to the image
        ("person", 3, (0.0, 0.0, 10.0, 10.0), 0),
        ("dog", 3, (29.0, 29.0, 11.0, 11.0), 0),
    ]
    train = import_dataset("ladd", ladd, split="train", progress=False)
    assert [Path(im.file_name).stem for im in train.images] == ["1_000", "2_000"]
    # the list saved on Windows (a byte-order mark, CRLF), an entry written as a file name:
    # the first id once read as "\ufeff1_000" and the image was dropped without a word
    (ladd / "ImageSets" / "Main" / "train.txt").write_bytes(b"\xef\xbb\xbf1_000\r\n2_000.jpg\r\n")
    train = import_dataset("ladd", ladd, split="train", progress=False)
    assert [Path(im.file_name).stem for im in train.images] == ["1_000", "2_000"]
    out = tmp_path / "ladd.json"
    write_coco_video(data, out)
    back = read_coco_video(out)
    assert [a.bbox for a in back.annotations] == [a.bbox for a in data.annotations]
    assert back.licenses and "Lacmus" in back.licenses[0]["name"]


def test_voc_bad_input_says_what(ladd, tmp_path):
    (ladd / "Annotations" / "1_001.xml").write_text("<annotation><filename>")
    with pytest.raises(DatasetFormatError, match="1_001.xml: not valid XML"):
        import_dataset("ladd", ladd, progress=False)
    (ladd / "Annotations" / "1_001.xml").write_text(
        _voc("1_001.jpg", (80, 60), [("Pedestrian", "a", 1, 2, 3, 0)])
    )
    with pytest.raises(DatasetFormatError, match="<xmin> is 'a', not a number"):
        import_dataset("ladd", ladd, progress=False)
    with pytest.raises(DatasetFormatError, match="no Pascal VOC"):
        import_dataset("ladd", tmp_path / "LADD" / "JPEGImages", progress=False)
    with pytest.raises(DatasetFormatError, match="no split 'val'"):
        import_dataset("heridal", ladd, split="val", progress=False)


def test_heridal_folders_are_splits_and_missing_images_are_counted(tmp_path, capsys):
    root = tmp_path / "HERIDAL"
    _image(root / "trainImages" / "train_BRS_0001.JPG", 120, 90)
    (root / "trainImages" / "labels").mkdir(parents=True)
    (root / "trainImages" / "labels" / "train_BRS_0001.xml").write_text(
        _voc("train_BRS_0001.JPG", (120, 90), [("human", 5, 6, 15, 26, 0)])
    )
    (root / "trainImages" / "labels" / "train_BRS_0002.xml").write_text(
        _voc("train_BRS_0002.JPG", (120, 90), [("human", 5, 6, 15, 26, 0)])
    )
    _image(root / "testImages" / "test_ZRI_0007.JPG", 120, 90)
    (root / "testImages" / "test_ZRI_0007.xml").write_text(
        _voc("test_ZRI_0007.JPG", (0, 0), [("person", 50, 40, 60, 70, 0)])
    )
    train = import_dataset("heridal", root, split="train", progress=False)
    assert [Path(im.file_name).name for im in train.images] == ["train_BRS_0001.JPG"]
    assert train.info["skipped"] == {"no image file": 1}
    assert [(a.bbox, train.categories[0].name) for a in train.annotations] == [
        ((4.0, 5.0, 11.0, 21.0), "person")
    ]
    test = import_dataset("heridal", root, split="test", progress=False)
    assert [(im.width, im.height) for im in test.images] == [(120, 90)]  # size 0 -> from file
    out = tmp_path / "heridal_test.json"
    assert (
        sarmission(
            [
                "data",
                "import",
                "heridal",
                str(root),
                "--split",
                "test",
                "--out",
                str(out),
                "--no-progress",
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out
    assert "1 images in 0 videos" in printed and "boxes: 1 person" in printed
    assert read_coco_video(out).images[0].file_name == test.images[0].file_name
    assert (
        sarmission(["data", "import", "heridal", str(tmp_path / "nowhere"), "--out", str(out)]) == 2
    )


def test_an_image_name_in_two_splits_pairs_with_the_one_beside_its_xml(tmp_path):
    """``trainImages/IMG_0001.xml`` was paired with ``testImages/IMG_0001.JPG`` (the first of
    the name found anywhere): wrong labels, a test image in the training split."""
    root = tmp_path / "HERIDAL"
    _image(root / "testImages" / "IMG_0001.JPG", 200, 150)
    _image(root / "trainImages" / "IMG_0001.JPG", 120, 90)
    (root / "trainImages" / "IMG_0001.xml").write_text(
        _voc("IMG_0001.JPG", None, [("human", 5, 6, 15, 26, 0)])
    )
    train = import_dataset("heridal", root, split="train", progress=False)
    assert [Path(im.file_name).parent.name for im in train.images] == ["trainImages"]
    assert [(im.width, im.height) for im in train.images] == [(120, 90)]
    # equally near (neither beside the XML, in two other folders): no pairing by chance
    other = tmp_path / "LADD"
    _image(other / "a" / "x.jpg")
    _image(other / "b" / "x.jpg")
    (other / "labels").mkdir(parents=True)
    (other / "labels" / "x.xml").write_text(_voc("x.jpg", (80, 60), [("human", 5, 6, 15, 26, 0)]))
    (other / "labels" / "y.xml").write_text(_voc("y.jpg", (80, 60), [("human", 5, 6, 15, 26, 0)]))
    _image(other / "a" / "y.jpg")
    data = import_dataset("heridal", other, progress=False)
    assert [Path(im.file_name).name for im in data.images] == ["y.jpg"]
    assert data.info["skipped"] == {"image name ambiguous": 1}


def test_an_import_never_writes_over_what_it_reads(ladd, tmp_path, capsys):
    """`--out` naming an annotation file of the source (or the source file itself) wrote the
    import over it; a folder gave '[Errno 21] ... .partial'."""
    xml = next(ladd.rglob("*.xml"))
    before = xml.read_bytes()
    args = ["data", "import", "ladd", str(ladd), "--no-progress", "--out"]
    assert sarmission([*args, str(xml)]) == 2
    assert "a file of the dataset being imported" in capsys.readouterr().err
    assert xml.read_bytes() == before
    assert sarmission([*args, str(tmp_path)]) == 2
    assert "a folder; give the JSON file to write" in capsys.readouterr().err
    again = ladd / "imported.json"  # an earlier import's output in the folder: written again
    assert sarmission([*args, str(again)]) == 0 and sarmission([*args, str(again)]) == 0
