"""SeaDronesSee (object detection v2 and multi-object tracking): people in open water, from
drones, with each frame's flight log in ``meta``.

The release keeps ``annotations/instances_<split>.json`` (COCO, read by
:func:`~sarmission.data.coco_video.read_coco_video`, both meta dialects) beside
``images/<split>/``; ``FOLDER`` may be that folder or one annotation file. What the import
adds:

- the pitch convention stated in ``info.meta_conventions`` (SeaDronesSee stores the gimbal
  pitch as a positive angle below the horizon: docs/datasets.md), so no reader has to guess it:
  the file's own statement where it has one, else what its pitches' signs say (as ``replay``
  reads a file: :func:`~sarmission.data.meta_conventions.dataset_conventions`), else the
  dataset's; a file with both signs, or files that disagree, are refused;
- images grouped into the videos they were cut from (``source.video``, frame
  ``source.frame_no``; object detection v2 samples them sparsely);
- category names as the project spells them (``floater`` is a swimmer with a life jacket);
  boxes of ``ignored`` are ignore regions;
- absolute image paths where the images are found (``images/<split>/``); images not found are
  counted and named in one warning (the images are published apart from the annotations).
"""

from __future__ import annotations

import logging
from pathlib import Path

from sarmission.class_roles import CATEGORY_ALIASES, normalise_class
from sarmission.data.coco_video import DatasetFormatError, VideoDataset, read_coco_video
from sarmission.data.importers.builder import IGNORED, DatasetBuilder
from sarmission.data.meta_conventions import (
    DEPRESSION,
    INFO_KEY,
    ConventionError,
    dataset_conventions,
)

log = logging.getLogger(__name__)

SOURCE = "SeaDronesSee"
LICENCE = "CC0 1.0 (SeaDronesSee repository README)"


def annotation_files(root: Path, split: str | None) -> list[Path]:
    """The annotation file(s) to read: ``root`` itself, or its
    ``annotations/instances_<split>*.json`` (every ``instances_*.json`` without a split)."""
    if root.is_file():
        named = _split_of(root)
        if split and named and named != split:  # the file itself says which split it is
            raise DatasetFormatError(f"{root.name} is the {named} split, not {split}")
        return [root]
    folder = root / "annotations" if (root / "annotations").is_dir() else root
    pattern = f"instances_{split}*.json" if split else "instances_*.json"
    found = sorted(folder.glob(pattern))
    if not found:
        raise DatasetFormatError(f"{folder}: no {pattern} (the SeaDronesSee annotation files)")
    return found


def _image_file(root: Path, json_path: Path, split: str, name: str) -> tuple[Path, bool]:
    """Where image ``name`` lies and whether it is there; when it is not, where the release
    keeps it (``images/<split>/``)."""
    base = root if root.is_dir() else json_path.parent.parent
    candidates = (
        base / "images" / split / name,
        json_path.parent.parent / "images" / split / name,
        json_path.parent / "images" / name,
        json_path.parent / name,
        json_path.parent.parent / "images" / name,
    )
    for candidate in candidates:
        if candidate.is_file():
            return candidate, True
    return candidates[0], False


def _split_of(json_path: Path) -> str:
    """``instances_val.json`` -> ``val``; ``instances_train_objects_in_water.json`` -> ``train``."""
    stem = json_path.stem
    return stem.removeprefix("instances_").split("_")[0] if stem.startswith("instances_") else ""


def _frame_number(value: object) -> int | None:
    """A frame number as the files give it (300, 300.0 or "300"); None for anything else."""
    if isinstance(value, bool):
        return None
    if isinstance(value, str) and value.strip().isdigit():
        return int(value.strip())
    if isinstance(value, int | float) and float(value).is_integer():
        return int(value)
    return None


def pitch_convention(part: VideoDataset, json_path: Path) -> str | None:
    """How ``part`` gives its gimbal pitch: as it states, else as its pitches' signs say;
    None when it has no pitch off the horizon (nothing to tell apart). A file with both
    signs is a :class:`DatasetFormatError`: a pitch of 45 and one of -45 cannot both be
    below the horizon, and importing it under one statement would place half its frames."""
    try:
        found = dataset_conventions(part)
    except ConventionError as exc:
        raise DatasetFormatError(f"{json_path.name}: {exc}") from None
    stated = found.how.startswith("as stated")
    if stated or any(im.telemetry.gimbal_pitch for im in part.images):
        return found.pitch
    return None


def import_seadronessee(
    root: Path, split: str | None = None, progress: bool = True
) -> VideoDataset:
    """The SeaDronesSee folder or annotation file ``root`` as the project's dataset (module
    docstring)."""
    out = DatasetBuilder(SOURCE, LICENCE)
    missing: list[str] = []
    pitch: tuple[str, Path] | None = None
    # (split, image file name) -> the annotation file that had it first
    seen: dict[tuple[str, str], Path] = {}
    for json_path in annotation_files(root, split):
        part = read_coco_video(json_path)
        part_split = _split_of(json_path)
        shared = [im.file_name for im in part.images if (part_split, im.file_name) in seen]
        if shared:  # MOT: objects_in_water and swimmer label the same frames
            raise DatasetFormatError(
                f"{json_path.name} and {seen[(part_split, shared[0])].name} annotate the same "
                f"images ({len(shared)} shared, e.g. {shared[0]}): import one of them (give "
                "its path instead of the folder)"
            )
        seen.update(((part_split, im.file_name), json_path) for im in part.images)
        convention = pitch_convention(part, json_path)
        if convention is not None:
            if pitch is not None and pitch[0] != convention:
                raise DatasetFormatError(
                    f"{json_path.name} gives the gimbal pitch as {convention}, "
                    f"{pitch[1].name} as {pitch[0]}: mixed conventions in one import"
                )
            pitch = (convention, json_path)
        out.info[INFO_KEY] = {"gimbal_pitch": pitch[0] if pitch else DEPRESSION}
        names = {c.id: normalise_class(c.name) for c in part.categories}
        by_image = part.annotations_by_image()
        videos = {v.id: v.name for v in part.videos}
        for image in part.images:
            source = image.extra.get("source")
            source = source if isinstance(source, dict) else {}
            video = source.get("video")
            frame = source.get("frame_no", image.extra.get("frame"))
            if video is not None:
                video = f"{source.get('folder_name', '')}/{video}".strip("/")
            elif image.video_id is not None:
                video = videos.get(image.video_id, str(image.video_id))
                frame = image.frame_index
            path, found = _image_file(root, json_path, part_split, image.file_name)
            if not found:
                missing.append(image.file_name)
            image_id = out.image(
                path,
                image.width,
                image.height,
                video=video,
                frame_index=_frame_number(frame),
                meta=image.meta,
                extra={"seadronessee_id": image.id},
            )
            for ann in by_image.get(image.id, []):
                name = names.get(ann.category_id)
                if name is None:
                    raise DatasetFormatError(
                        f"{json_path}: annotation {ann.id} has unknown category {ann.category_id}"
                    )
                name = CATEGORY_ALIASES.get(name, name)
                out.box(
                    image_id,
                    name,
                    *ann.bbox,
                    ignore=bool(ann.iscrowd) or name == IGNORED,
                    track_id=ann.track_id,
                )
    if missing:
        out.info["images_not_found"] = len(missing)
        log.warning(
            "%d of %d SeaDronesSee images not found (e.g. %s): they are published apart from "
            "the annotations; put them in images/<split>/ beside annotations/",
            len(missing),
            len(out.images),
            missing[0],
        )
    return out.build()
