"""VisDrone (AISKYEYE team, Tianjin University): city streets and squares seen from drones.

Two layouts, told apart by their folders. DET (still images): ``images/*.jpg`` with
``annotations/<stem>.txt``, one box per line ``left,top,width,height,score,category,truncation,
occlusion``; the image size is read from the image. VID and MOT (videos):
``sequences/<seq>/<7-digit frame>.jpg`` with ``annotations/<seq>.txt``, one box per line
``frame,target_id,left,top,width,height,score,category,truncation,occlusion`` (frames from 1);
each sequence is a video, its frame size read once. Pedestrians and people become ``person``,
the vehicles keep their names (objects, never people: :mod:`sarmission.class_roles`), category 0
("ignored regions") and score 0 become ignore regions. A release folder
(``VisDrone2019-DET-train``) is given as the folder, or picked from its parent by ``--split``.
"""

from __future__ import annotations

import logging
import math
import re
import sys
from pathlib import Path

from sarmission.data.coco_video import DatasetFormatError, VideoDataset
from sarmission.data.importers.builder import IGNORED, DatasetBuilder, image_size

log = logging.getLogger(__name__)

SOURCE = "VisDrone (AISKYEYE, Tianjin University)"
LICENCE = "as published by the AISKYEYE team, for academic use (see docs/datasets.md)"

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp")

#: VisDrone category number -> (project category, VisDrone's own name).
CATEGORIES: dict[int, tuple[str, str]] = {
    0: (IGNORED, "ignored regions"),
    1: ("person", "pedestrian"),
    2: ("person", "people"),
    3: ("bicycle", "bicycle"),
    4: ("car", "car"),
    5: ("van", "van"),
    6: ("truck", "truck"),
    7: ("tricycle", "tricycle"),
    8: ("awning_tricycle", "awning-tricycle"),
    9: ("bus", "bus"),
    10: ("motor", "motor"),
    11: ("others", "others"),
}

DET_COLUMNS = 8  # left, top, width, height, score, category, truncation, occlusion
VID_COLUMNS = 10  # frame, target_id, then the DET columns


def _layout(folder: Path) -> str | None:
    """``"VID"``, ``"DET"`` or None: which VisDrone layout ``folder`` has."""
    if not (folder / "annotations").is_dir():
        return None
    if (folder / "sequences").is_dir():
        return "VID"
    if (folder / "images").is_dir():
        return "DET"
    return None


def _release_split(name: str) -> str | None:
    """``VisDrone2019-DET-test-dev`` -> ``test-dev``; None for a name of no release."""
    match = re.match(r"visdrone\d*-(?:det|vid|mot)-(.+)$", name, re.IGNORECASE)
    return match.group(1).lower() if match else None


def find_release(root: Path, split: str | None = None) -> tuple[Path, str]:
    """The folder to import and its layout: ``root`` itself or, with ``split``, the one
    sub-folder of ``root`` whose name contains ``-<split>`` (a name ending so wins)."""
    if not root.is_dir():
        raise DatasetFormatError(f"{root}: not a folder")
    subfolders = sorted(p for p in root.iterdir() if p.is_dir() and _layout(p))
    if split is not None:
        tag = f"-{split.lower()}"
        matching = [p for p in subfolders if tag in p.name.lower()]
        exact = [p for p in matching if p.name.lower().endswith(tag)]
        chosen = exact or matching
        if len(chosen) == 1:
            return chosen[0], _layout(chosen[0]) or ""
        if len(chosen) > 1:
            raise DatasetFormatError(
                f"{root}: several VisDrone folders for split {split!r} "
                f"({', '.join(p.name for p in chosen)}); give one of them as the folder"
            )
        own = _release_split(root.name)
        if own is not None and not own.startswith(split.lower()):
            raise DatasetFormatError(f"{root}: the {own!r} split, not {split!r}")
    layout = _layout(root)
    if layout is None:
        found = ""
        if subfolders:
            found = (
                f"; VisDrone folders in it: {', '.join(p.name for p in subfolders)} "
                "(give one of them, or choose one by its split)"
            )
        wanted = f" and no sub-folder named like *-{split}" if split is not None else ""
        raise DatasetFormatError(
            f"{root}: no VisDrone layout (annotations/ beside images/ or sequences/){wanted}{found}"
        )
    return root, layout


def _rows(path: Path, columns: int) -> list[tuple[int, list[float]]]:
    """The numeric rows of one annotation file with their line numbers (blank lines skipped,
    a trailing comma allowed); ``DatasetFormatError`` names the file and line of a bad one."""
    rows = []
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise DatasetFormatError(f"{path}: not a text file") from None
    for number, line in enumerate(text.splitlines(), start=1):
        fields = [f.strip() for f in line.strip().split(",")]
        while fields and fields[-1] == "":
            fields.pop()
        if not fields:
            continue
        if len(fields) < columns:
            raise DatasetFormatError(
                f"{path}:{number}: {len(fields)} columns, expected {columns} ({line.strip()!r})"
            )
        try:
            values = [float(f) for f in fields[:columns]]
        except ValueError:
            values = []
        if len(values) < columns or not all(math.isfinite(v) for v in values):
            raise DatasetFormatError(f"{path}:{number}: not numbers ({line.strip()!r})")
        rows.append((number, values))
    return rows


def _add_box(
    out: DatasetBuilder,
    image_id: int,
    det: list[float],
    where: str,
    track_id: int | None = None,
) -> None:
    """Add one DET-column box (``left, top, width, height, score, category, truncation,
    occlusion``) to image ``image_id``."""
    left, top, width, height, score, category, truncation, occlusion = det
    if not category.is_integer() or int(category) not in CATEGORIES:
        raise DatasetFormatError(f"{where}: unknown VisDrone category {category:g}")
    name, visdrone_name = CATEGORIES[int(category)]
    extra: dict[str, object] = {"truncation": int(truncation), "occlusion": int(occlusion)}
    if name == "person":
        extra["visdrone_category"] = visdrone_name
    out.box(
        image_id,
        name,
        left,
        top,
        width,
        height,
        ignore=name == IGNORED or score == 0,
        track_id=track_id if name != IGNORED else None,
        extra=extra,
    )


def _images_by_stem(folder: Path) -> dict[str, Path]:
    return {
        p.stem: p
        for p in sorted(folder.iterdir())
        if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file()
    }


def _import_det(folder: Path, out: DatasetBuilder, progress: bool) -> None:
    from tqdm import tqdm

    images = _images_by_stem(folder / "images")
    files = sorted((folder / "annotations").glob("*.txt"))
    unannotated = len(set(images) - {f.stem for f in files})
    if unannotated:
        out.skipped["image without annotation file"] += unannotated
    for path in tqdm(
        files, desc="VisDrone DET", unit="image", file=sys.stderr, disable=not progress
    ):
        image = images.get(path.stem)
        if image is None:
            out.skipped["no image file"] += 1
            log.warning("%s: its image %s.jpg is not in %s", path, path.stem, folder / "images")
            continue
        rows = _rows(path, DET_COLUMNS)
        width, height = image_size(image)
        image_id = out.image(image, width, height)
        for number, values in rows:
            _add_box(out, image_id, values, f"{path}:{number}")


def _import_vid(folder: Path, out: DatasetBuilder, progress: bool) -> None:
    from tqdm import tqdm

    files = sorted((folder / "annotations").glob("*.txt"))
    for path in tqdm(
        files, desc="VisDrone VID", unit="sequence", file=sys.stderr, disable=not progress
    ):
        sequence = folder / "sequences" / path.stem
        frames = (
            {int(stem): p for stem, p in _images_by_stem(sequence).items() if stem.isdigit()}
            if sequence.is_dir()
            else {}
        )
        if not frames:
            out.skipped["no image file"] += 1
            log.warning("%s: its sequence %s has no frames", path, sequence)
            continue
        rows = _rows(path, VID_COLUMNS)
        width, height = image_size(frames[min(frames)])
        image_ids = {
            frame: out.image(frames[frame], width, height, video=path.stem, frame_index=frame - 1)
            for frame in sorted(frames)
        }
        missing = 0
        for number, values in rows:
            frame, target = values[0], values[1]
            image_id = image_ids.get(int(frame)) if frame.is_integer() else None
            if image_id is None:
                missing += 1
                continue
            track = int(target) if target.is_integer() and target > 0 else None
            _add_box(out, image_id, values[2:], f"{path}:{number}", track_id=track)
        if missing:
            out.skipped["box of a missing frame"] += missing
            log.warning("%s: %d box(es) of frames missing from %s", path, missing, sequence)


def import_visdrone(root: Path, split: str | None = None, progress: bool = True) -> VideoDataset:
    """The VisDrone DET or VID/MOT folder ``root`` (or its sub-folder of one split) as the
    project's dataset (module docstring)."""
    folder, layout = find_release(Path(root), split)
    if not any((folder / "annotations").glob("*.txt")):
        raise DatasetFormatError(f"{folder / 'annotations'}: no VisDrone .txt annotation found")
    out = DatasetBuilder(SOURCE, LICENCE)
    out.info["visdrone_layout"] = layout
    out.info["visdrone_folder"] = folder.name
    if layout == "VID":
        _import_vid(folder, out, progress)
    else:
        _import_det(folder, out, progress)
    return out.build()
