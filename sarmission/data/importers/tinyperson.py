"""TinyPerson (UCAS-VG, ECCV 2020 workshop): people a few pixels tall at sea and on beaches.

The ``tiny_set`` folder holds ``annotations/tiny_set_{train,test}.json`` (COCO-like, with the
image sizes) and the images under ``train/`` and ``test/``. ``sea_person`` becomes ``swimmer``,
``earth_person`` ``person``; a box marked ``ignore``, ``uncertain`` or ``in_dense_image`` is
stored as an ignore region, one marked ``logo`` (a person on a poster or a screen) is left out.
Frames named ``bb_V<video>_I<frame>`` are grouped by their source video. The images are not
read. No telemetry.
"""

from __future__ import annotations

import json
import logging
import re
import sys
from pathlib import Path
from typing import Any

from sarmission.data.coco_video import DatasetFormatError, VideoDataset
from sarmission.data.importers.builder import DatasetBuilder

log = logging.getLogger(__name__)

SOURCE = "TinyPerson (UCAS-VG)"
LICENCE = "as published by UCAS-VG, for academic use (see docs/datasets.md)"

SPLITS = ("train", "test")
#: TinyPerson category name -> the project's.
CATEGORIES = {"sea_person": "swimmer", "earth_person": "person"}
#: Box flags that make an ignore region.
IGNORE_FLAGS = ("ignore", "uncertain", "in_dense_image")

_FRAME_NAME = re.compile(r"^bb_(V\d+)_I(\d+)$")


def find_tiny_set(root: Path) -> Path:
    """The folder holding ``annotations/tiny_set_*.json``: ``root`` or ``root/tiny_set``."""
    for folder in (root, root / "tiny_set"):
        if any((folder / "annotations" / f"tiny_set_{s}.json").is_file() for s in SPLITS):
            return folder
    raise DatasetFormatError(
        f"{root}: no TinyPerson annotations (annotations/tiny_set_train.json or "
        "tiny_set_test.json, in it or in tiny_set/)"
    )


def video_frame(file_name: str) -> tuple[str, int] | None:
    """``labeled_images/bb_V0032_I0001640.jpg`` -> ``("V0032", 1640)``; None for other names."""
    match = _FRAME_NAME.match(Path(file_name).stem)
    return (match.group(1), int(match.group(2))) if match else None


def _records(doc: Any, key: str, required: tuple[str, ...], path: Path) -> list[dict]:
    """``doc[key]``, a list of objects each with the ``required`` keys."""
    items = doc.get(key) if isinstance(doc, dict) else None
    if not isinstance(items, list):
        raise DatasetFormatError(f"{path}: no list {key!r} (not TinyPerson's layout)")
    for index, item in enumerate(items):
        missing = [k for k in required if not isinstance(item, dict) or k not in item]
        if missing:
            raise DatasetFormatError(f"{path}: {key}[{index}] lacks {', '.join(missing)}")
    return items


def _load(path: Path) -> tuple[list[dict], list[dict], dict[int, str]]:
    """Images, annotations and category names by id of one annotation file."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DatasetFormatError(f"{path}: not a readable JSON file ({exc})") from None
    images = _records(doc, "images", ("id", "file_name", "width", "height"), path)
    annotations = _records(doc, "annotations", ("image_id", "bbox", "category_id"), path)
    categories = _records(doc, "categories", ("id", "name"), path)
    return images, annotations, {c["id"]: str(c["name"]) for c in categories}


def _import_split(folder: Path, split: str, out: DatasetBuilder, progress: bool) -> None:
    from tqdm import tqdm

    path = folder / "annotations" / f"tiny_set_{split}.json"
    images, annotations, names = _load(path)
    by_image: dict[Any, list[dict]] = {}
    for image in images:
        key = image["id"]
        if not isinstance(key, int | str) or isinstance(key, bool):
            raise DatasetFormatError(f"{path}: image id {key!r} is not an integer or a string")
        if key in by_image:  # its boxes would land on both images
            raise DatasetFormatError(f"{path}: image id {key!r} is used twice")
        by_image[key] = []
    for ann in annotations:
        key = ann["image_id"]
        if not isinstance(key, int | str) or isinstance(key, bool) or key not in by_image:
            raise DatasetFormatError(f"{path}: an annotation of unknown image {key!r}")
        by_image[key].append(ann)
    missing: list[Path] = []
    for image in tqdm(
        images, desc=f"TinyPerson {split}", unit="image", file=sys.stderr, disable=not progress
    ):
        file = folder / split / str(image["file_name"])
        if not file.is_file():
            missing.append(file)
            continue
        grouped = video_frame(str(image["file_name"]))
        try:
            width, height = int(image["width"]), int(image["height"])
        except (TypeError, ValueError):
            raise DatasetFormatError(f"{path}: image {image['id']!r} has no size") from None
        image_id = out.image(
            file,
            width,
            height,
            video=grouped[0] if grouped else None,
            frame_index=grouped[1] if grouped else None,
            extra={"split": split},
        )
        for ann in by_image[image["id"]]:
            if ann.get("logo"):
                out.skipped["logo"] += 1
                continue
            bbox = ann["bbox"]
            try:
                x, y, w, h = (float(v) for v in bbox)
            except (TypeError, ValueError):
                raise DatasetFormatError(
                    f"{path}: annotation bbox {bbox!r} is not 4 numbers"
                ) from None
            name = names.get(ann["category_id"])
            if name is None:
                raise DatasetFormatError(
                    f"{path}: annotation of unknown category {ann['category_id']!r}"
                )
            flags = {flag: bool(ann.get(flag)) for flag in IGNORE_FLAGS}
            out.box(
                image_id,
                CATEGORIES.get(name, name),
                x,
                y,
                w,
                h,
                ignore=any(flags.values()) or bool(ann.get("iscrowd")),
                extra={"tinyperson_category": name, **flags},
            )
    if missing:
        out.skipped["no image file"] += len(missing)
        log.warning(
            "%s: %d image(s) not found under %s (first: %s)",
            path,
            len(missing),
            folder / split,
            missing[0],
        )


def import_tinyperson(root: Path, split: str | None = None, progress: bool = True) -> VideoDataset:
    """The TinyPerson folder ``root`` (``tiny_set`` or its parent), one split or both, as the
    project's dataset (module docstring)."""
    root = Path(root)
    if not root.is_dir():
        raise DatasetFormatError(f"{root}: not a folder")
    folder = find_tiny_set(root)
    if split is not None and split.lower() not in SPLITS:
        raise DatasetFormatError(f"TinyPerson has no split {split!r} (only train, test)")
    splits = [split.lower()] if split is not None else list(SPLITS)
    present = [s for s in splits if (folder / "annotations" / f"tiny_set_{s}.json").is_file()]
    if split is not None and not present:
        raise DatasetFormatError(f"{folder / 'annotations'}: no tiny_set_{split.lower()}.json")
    out = DatasetBuilder(SOURCE, LICENCE)
    for name in present:
        _import_split(folder, name, out, progress)
    return out.build()
