"""COCO video annotations as used by SeaDronesSee MOT and the SAR-Tiny datasets.

File layout (``[x, y, w, h]`` boxes in pixels, top-left corner)::

    {"info": {...}, "licenses": [...],                       # licenses optional
     "videos": [{"id", "name", ...}],                        # optional for plain COCO files
     "images": [{"id", "file_name", "height", "width", "video_id", "frame_index",
                 "meta": {...} | null}],                     # meta: per-frame flight telemetry
     "annotations": [{"id", "image_id", "video_id", "track_id", "category_id",
                      "bbox": [x, y, w, h], "area", "iscrowd", "gt_lat", "gt_lon"}],
     "categories": [{"id", "name", "supercategory"}]}

Required keys: ``images``, ``annotations`` and ``categories`` at the top; ``id``, ``file_name``,
``height``, ``width`` per image; ``id``, ``image_id``, ``category_id``, ``bbox`` per annotation;
``id``, ``name`` per video and category. Everything else is optional and unknown keys are kept in
``extra`` so that :func:`write_coco_video` reproduces them (round trip). A missing ``meta`` reads as
``None`` and is written back as ``null``.

The telemetry in ``meta`` comes in two dialects, both accepted (see :func:`parse_telemetry`):
SeaDronesSee MOT (``gps_latitude``, ``altitude``, ``gimbal_pitch``, ``xspeed`` ...) and the
object-detection v2 release with unit suffixes (``latitude``, ``height_above_takeoff(meter)``,
``gimbal_pitch(degrees)``, ``xSpeed(m/s)``, ``datetime(utc)`` ...).
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)


class DatasetFormatError(ValueError):
    """An annotation file is not valid JSON or lacks what the format requires."""


@dataclass
class FrameTelemetry:
    """Flight telemetry of one frame; every field is ``None`` when unknown.

    Units: degrees for latitude/longitude/angles, metres above take-off for ``altitude``,
    m/s for speeds, POSIX seconds (UTC) or seconds since the log start for ``time``.
    """

    latitude: float | None = None
    longitude: float | None = None
    altitude: float | None = None
    gimbal_pitch: float | None = None
    gimbal_roll: float | None = None
    gimbal_heading: float | None = None
    compass_heading: float | None = None
    speed: float | None = None
    xspeed: float | None = None
    yspeed: float | None = None
    zspeed: float | None = None
    time: float | None = None

    def is_empty(self) -> bool:
        """True when no field is known."""
        return all(getattr(self, f.name) is None for f in fields(self))


@dataclass
class Category:
    """An object category."""

    id: int
    name: str
    supercategory: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass
class Video:
    """One video (sequence of images)."""

    id: int
    name: str
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass
class ImageRecord:
    """One frame: file, size, place in its video, raw ``meta`` and the telemetry parsed from it."""

    id: int
    file_name: str
    height: int
    width: int
    video_id: int | None = None
    frame_index: int | None = None
    meta: dict[str, Any] | None = None
    telemetry: FrameTelemetry = field(default_factory=FrameTelemetry)
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass
class Annotation:
    """One ground-truth box. ``bbox`` is COCO ``(x, y, w, h)`` in pixels.

    ``gt_lat`` / ``gt_lon`` are the true target position in degrees, when the file provides it.
    """

    id: int
    image_id: int
    category_id: int
    bbox: tuple[float, float, float, float]
    track_id: int | None = None
    video_id: int | None = None
    area: float = 0.0
    iscrowd: int = 0
    gt_lat: float | None = None
    gt_lon: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass
class VideoDataset:
    """A whole annotation file. ``source_path`` is where it was read from (not compared)."""

    videos: list[Video]
    images: list[ImageRecord]
    annotations: list[Annotation]
    categories: list[Category]
    info: dict[str, Any] = field(default_factory=dict)
    licenses: list[Any] | None = None
    source_path: Path | None = field(default=None, compare=False)

    def image(self, image_id: int) -> ImageRecord:
        """The image with this id (``KeyError`` if none)."""
        for image in self.images:
            if image.id == image_id:
                return image
        raise KeyError(image_id)

    def video_images(self, video_id: int) -> list[ImageRecord]:
        """Images of one video in frame order (by ``frame_index``, then id)."""
        chosen = [im for im in self.images if im.video_id == video_id]
        return sorted(chosen, key=lambda im: (im.frame_index is None, im.frame_index or 0, im.id))

    def annotations_by_image(self) -> dict[int, list[Annotation]]:
        """Annotations grouped by image id; every image has an entry (possibly empty)."""
        grouped: dict[int, list[Annotation]] = {im.id: [] for im in self.images}
        for ann in self.annotations:
            grouped.setdefault(ann.image_id, []).append(ann)
        return grouped

    def image_path(self, image: ImageRecord, root: str | Path | None = None) -> Path:
        """Resolve an image file.

        With ``root`` the file is ``root / file_name``. Otherwise, relative to the folder ``d`` of
        the annotation file, the first existing of ``d/images/file_name``, ``d/file_name`` and
        ``d/../images/file_name`` (SeaDronesSee keeps ``annotations/`` beside ``images/``); when
        none exists, ``d/images/file_name``. Absolute file names are returned as they are.
        """
        name = Path(image.file_name)
        if root is not None:
            return Path(root) / name
        if name.is_absolute():
            return name
        base = self.source_path.parent if self.source_path is not None else Path.cwd()
        candidates = [base / "images" / name, base / name, base.parent / "images" / name]
        for candidate in candidates:
            if candidate.exists():
                return candidate
        return candidates[0]


# --------------------------------------------------------------------------- telemetry


#: FrameTelemetry field -> accepted key names, normalised (lower case, unit suffix in parentheses
#: removed, only letters and digits kept); the first present key wins.
_TELEMETRY_KEYS: dict[str, tuple[str, ...]] = {
    "latitude": ("gpslatitude", "latitude", "lat"),
    "longitude": ("gpslongitude", "longitude", "lon", "lng"),
    "altitude": ("heightabovetakeoff", "relativealtitude", "altitude"),
    "gimbal_pitch": ("gimbalpitch",),
    "gimbal_roll": ("gimbalroll",),
    "gimbal_heading": ("gimbalheading", "gimbalyaw"),
    "compass_heading": ("compassheading", "heading", "yaw"),
    "speed": ("speed",),
    "xspeed": ("xspeed",),
    "yspeed": ("yspeed",),
    "zspeed": ("zspeed",),
}
_TIME_KEYS = ("time", "timestamp")
_DATETIME_KEYS = ("datetime", "datetimeutc", "datetimeoriginal")
_MILLISECOND_UNITS = {"ms", "millisecond", "milliseconds", "msec"}


def _normalise_key(key: str) -> tuple[str, str]:
    """``"xSpeed(m/s)"`` -> ``("xspeed", "m/s")``: bare lower-case name and unit."""
    unit = " ".join(re.findall(r"\(([^)]*)\)", key)).strip().lower()
    bare = re.sub(r"\([^)]*\)", "", key).lower()
    return re.sub(r"[^a-z0-9]", "", bare), unit


def _to_float(value: Any) -> float | None:
    """Finite float from a number or numeric string; ``None`` when not possible."""
    if isinstance(value, bool) or value is None:
        return None
    if isinstance(value, int | float):
        number = float(value)
    elif isinstance(value, str):
        try:
            number = float(value.strip())
        except ValueError:
            return None
    else:
        return None
    return number if math.isfinite(number) else None


def _parse_datetime(value: Any) -> float | None:
    """POSIX seconds from an ISO-8601, ``YYYY/MM/DD hh:mm:ss`` or EXIF date string (naive = UTC)."""
    if not isinstance(value, str):
        return None
    text = value.strip().replace("Z", "+00:00")
    if re.match(r"^\d{4}:\d{2}:\d{2}", text):
        text = text[:10].replace(":", "-") + text[10:]
    text = text.replace("/", "-")
    try:
        stamp = datetime.fromisoformat(text)
    except ValueError:
        return None
    if stamp.tzinfo is None:
        stamp = stamp.replace(tzinfo=UTC)
    return stamp.timestamp()


def parse_telemetry(meta: Mapping[str, Any] | None, where: str = "meta") -> FrameTelemetry:
    """Normalise an image's ``meta`` dict into :class:`FrameTelemetry`.

    Keys match case-insensitively, ignoring ``_``/spaces and unit suffixes in parentheses, so
    ``gps_latitude``, ``Latitude`` and ``latitude(deg)`` all give ``latitude``. ``altitude`` prefers
    ``height_above_takeoff`` over ``altitude``. ``time`` is a number of seconds (``time(ms)`` style
    keys are divided by 1000); without it a ``date_time`` / ``datetime(utc)`` string becomes POSIX
    seconds. ``gps_latitude_ref`` of ``S`` / ``gps_longitude_ref`` of ``W`` make a positive value
    negative. Numeric strings are parsed; unparsable values become ``None`` with a warning naming
    ``where``, and so do two keys of one name that disagree (``gimbal_pitch`` beside
    ``gimbal_pitch(degrees)``). ``None`` or an empty dict gives all-``None`` telemetry. Values
    are kept as the file gives them: :mod:`sarmission.data.meta_conventions` reads their meaning
    (the gimbal pitch's sign differs between datasets).
    """
    if not meta:
        return FrameTelemetry()
    if not isinstance(meta, Mapping):
        log.warning("%s: telemetry is a %s, not an object; ignored", where, type(meta).__name__)
        return FrameTelemetry()
    by_name: dict[str, tuple[str, str, Any]] = {}
    conflicting: set[str] = set()
    for key, value in meta.items():
        name, unit = _normalise_key(str(key))
        first = by_name.setdefault(name, (str(key), unit, value))
        if first[2] != value and _to_float(first[2]) != _to_float(value):
            log.warning(
                "%s: %r = %r and %r = %r disagree; both ignored",
                where,
                first[0],
                first[2],
                key,
                value,
            )
            conflicting.add(name)
    for name in conflicting:
        by_name[name] = (by_name[name][0], by_name[name][1], None)

    values: dict[str, float | None] = {}
    for attr, names in _TELEMETRY_KEYS.items():
        key = next((n for n in names if n in by_name), None)
        if key is None:
            continue
        raw_key, _, raw = by_name[key]
        values[attr] = _to_float(raw)
        if values[attr] is None and raw is not None:
            log.warning("%s: %r = %r is not a number; ignored", where, raw_key, raw)

    for attr, ref_name, negative in (
        ("latitude", "gpslatituderef", "S"),
        ("longitude", "gpslongituderef", "W"),
    ):
        ref = by_name.get(ref_name)
        value = values.get(attr)
        if ref is not None and value is not None and str(ref[2]).strip().upper() == negative:
            values[attr] = -abs(value)

    values["time"] = _parse_time(by_name, where)
    return FrameTelemetry(**values)


def _parse_time(by_name: dict[str, tuple[str, str, Any]], where: str) -> float | None:
    for name in _TIME_KEYS:
        if name in by_name:
            raw_key, unit, raw = by_name[name]
            seconds = _to_float(raw)
            if seconds is not None:
                return seconds / 1000.0 if unit in _MILLISECOND_UNITS else seconds
            stamp = _parse_datetime(raw)
            if stamp is not None:
                return stamp
            if raw is not None:
                log.warning("%s: %r = %r is not a time; ignored", where, raw_key, raw)
    for name in _DATETIME_KEYS:
        if name in by_name:
            raw_key, _, raw = by_name[name]
            stamp = _parse_datetime(raw)
            if stamp is not None:
                return stamp
            if raw is not None:
                log.warning("%s: %r = %r is not a date/time; ignored", where, raw_key, raw)
    return None


# --------------------------------------------------------------------------- reading


class _Reader:
    """Validates one file's records, raising :class:`DatasetFormatError` with their location."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, message: str) -> DatasetFormatError:
        return DatasetFormatError(f"{self.path}: {message}")

    def records(self, doc: dict[str, Any], section: str, required: bool) -> list[dict[str, Any]]:
        if section not in doc:
            if required:
                raise self.fail(f"missing required top-level key {section!r}")
            return []
        items = doc[section]
        if not isinstance(items, list):
            raise self.fail(f"{section!r} must be a list, got {type(items).__name__}")
        for i, item in enumerate(items):
            if not isinstance(item, dict):
                raise self.fail(f"{section}[{i}] must be an object, got {type(item).__name__}")
        return items

    def require(self, item: dict[str, Any], where: str, keys: tuple[str, ...]) -> None:
        missing = [k for k in keys if k not in item]
        if missing:
            raise self.fail(f"{where} is missing required key(s) {', '.join(map(repr, missing))}")

    def integer(self, item: dict[str, Any], key: str, where: str) -> Any:
        """The integer at ``key`` (integral floats accepted), ``None`` when absent or null."""
        value = item.get(key)
        if value is None:
            return None
        if isinstance(value, float) and value.is_integer():
            return int(value)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(f"{where}: {key!r} must be an integer, got {value!r}")
        return value

    def required_integer(self, item: dict[str, Any], key: str, where: str) -> int:
        """The integer at ``key``, which must be there and not null."""
        value = self.integer(item, key, where)
        if value is None:
            raise self.fail(f"{where}: {key!r} must be an integer, got null")
        return value

    def number(self, item: dict[str, Any], key: str, where: str) -> float | None:
        value = item.get(key)
        if value is None:
            return None
        number = _to_float(value)
        if number is None:
            raise self.fail(f"{where}: {key!r} must be a number, got {value!r}")
        return number


def _label(section: str, index: int, item: dict[str, Any]) -> str:
    return f"{section}[{index}]" + (f" (id={item['id']!r})" if "id" in item else "")


def _extra(item: dict[str, Any], known: tuple[str, ...]) -> dict[str, Any]:
    return {k: v for k, v in item.items() if k not in known}


_VIDEO_KEYS = ("id", "name")
_CATEGORY_KEYS = ("id", "name", "supercategory")
_IMAGE_KEYS = ("id", "file_name", "height", "width", "video_id", "frame_index", "meta")
_ANNOTATION_KEYS = (
    "id",
    "image_id",
    "video_id",
    "track_id",
    "category_id",
    "bbox",
    "area",
    "iscrowd",
    "gt_lat",
    "gt_lon",
)


def read_coco_video(path: str | Path) -> VideoDataset:
    """Read a COCO video annotation file (see the module docstring for the layout).

    Raises :class:`DatasetFormatError` for unreadable or malformed JSON, missing required keys,
    wrong value types, duplicate ids and references to unknown images, videos or categories.
    Garbage telemetry values only warn (see :func:`parse_telemetry`).
    """
    path = Path(path)
    reader = _Reader(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise reader.fail(f"cannot read file ({exc.strerror or exc})") from exc
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise reader.fail(f"not valid JSON ({exc})") from exc
    if not isinstance(doc, dict):
        raise reader.fail(f"top level must be an object, got {type(doc).__name__}")

    videos = [_read_video(reader, i, v) for i, v in enumerate(reader.records(doc, "videos", False))]
    categories = [
        _read_category(reader, i, c) for i, c in enumerate(reader.records(doc, "categories", True))
    ]
    images = [
        _read_image(reader, i, im) for i, im in enumerate(reader.records(doc, "images", True))
    ]
    annotations = [
        _read_annotation(reader, i, a)
        for i, a in enumerate(reader.records(doc, "annotations", True))
    ]

    info = doc.get("info") or {}
    if not isinstance(info, dict):
        raise reader.fail(f"'info' must be an object, got {type(info).__name__}")
    licenses = doc.get("licenses")
    if licenses is not None and not isinstance(licenses, list):
        raise reader.fail(f"'licenses' must be a list, got {type(licenses).__name__}")

    dataset = VideoDataset(videos, images, annotations, categories, info, licenses, path)
    _check_references(reader, dataset)
    return dataset


def _read_video(reader: _Reader, index: int, item: dict[str, Any]) -> Video:
    where = _label("videos", index, item)
    reader.require(item, where, _VIDEO_KEYS)
    return Video(reader.integer(item, "id", where), str(item["name"]), _extra(item, _VIDEO_KEYS))


def _read_category(reader: _Reader, index: int, item: dict[str, Any]) -> Category:
    where = _label("categories", index, item)
    reader.require(item, where, ("id", "name"))
    supercategory = item.get("supercategory")
    return Category(
        reader.integer(item, "id", where),
        str(item["name"]),
        None if supercategory is None else str(supercategory),
        _extra(item, _CATEGORY_KEYS),
    )


def _read_image(reader: _Reader, index: int, item: dict[str, Any]) -> ImageRecord:
    where = _label("images", index, item)
    reader.require(item, where, ("id", "file_name", "height", "width"))
    meta = item.get("meta")
    if meta is not None and not isinstance(meta, dict):
        log.warning("%s: 'meta' is a %s, not an object; ignored", where, type(meta).__name__)
        meta = None
    frame_index = reader.integer(item, "frame_index", where)
    if frame_index is None and "frame_id" in item:
        frame_index = reader.integer(item, "frame_id", where)
    return ImageRecord(
        id=reader.required_integer(item, "id", where),
        file_name=str(item["file_name"]),
        height=reader.required_integer(item, "height", where),
        width=reader.required_integer(item, "width", where),
        video_id=reader.integer(item, "video_id", where),
        frame_index=frame_index,
        meta=meta,
        telemetry=parse_telemetry(meta, f"{reader.path}: {where} meta"),
        extra=_extra(item, _IMAGE_KEYS + (("frame_id",) if "frame_index" not in item else ())),
    )


def _read_annotation(reader: _Reader, index: int, item: dict[str, Any]) -> Annotation:
    where = _label("annotations", index, item)
    reader.require(item, where, ("id", "image_id", "category_id", "bbox"))
    bbox = item["bbox"]
    if (
        not isinstance(bbox, list | tuple)
        or len(bbox) != 4
        or any(_to_float(v) is None for v in bbox)
    ):
        raise reader.fail(f"{where}: 'bbox' must be 4 numbers [x, y, w, h], got {bbox!r}")
    x, y, w, h = (float(v) for v in bbox)
    area = reader.number(item, "area", where)
    return Annotation(
        id=reader.integer(item, "id", where),
        image_id=reader.integer(item, "image_id", where),
        category_id=reader.integer(item, "category_id", where),
        bbox=(x, y, w, h),
        track_id=reader.integer(item, "track_id", where),
        video_id=reader.integer(item, "video_id", where),
        area=w * h if area is None else area,
        iscrowd=reader.integer(item, "iscrowd", where) or 0,
        gt_lat=reader.number(item, "gt_lat", where),
        gt_lon=reader.number(item, "gt_lon", where),
        extra=_extra(item, _ANNOTATION_KEYS),
    )


def _check_references(reader: _Reader, dataset: VideoDataset) -> None:
    for section, records in (
        ("videos", dataset.videos),
        ("images", dataset.images),
        ("annotations", dataset.annotations),
        ("categories", dataset.categories),
    ):
        seen: set[int] = set()
        for record in records:
            if record.id in seen:
                raise reader.fail(f"duplicate id {record.id} in {section!r}")
            seen.add(record.id)
    video_ids = {v.id for v in dataset.videos}
    image_ids = {im.id for im in dataset.images}
    category_ids = {c.id for c in dataset.categories}
    for image in dataset.images:
        if image.video_id is not None and dataset.videos and image.video_id not in video_ids:
            raise reader.fail(f"image id={image.id} refers to unknown video_id {image.video_id}")
    for ann in dataset.annotations:
        if ann.image_id not in image_ids:
            raise reader.fail(f"annotation id={ann.id} refers to unknown image_id {ann.image_id}")
        if ann.category_id not in category_ids:
            raise reader.fail(
                f"annotation id={ann.id} refers to unknown category_id {ann.category_id}"
            )


# --------------------------------------------------------------------------- writing


def _drop_none(record: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in record.items() if v is not None}


def write_coco_video(dataset: VideoDataset, path: str | Path) -> None:
    """Write ``dataset`` as COCO video JSON; :func:`read_coco_video` reads back an equal dataset.

    Optional fields that are ``None`` are left out, except ``meta`` which is written as ``null``.
    Keys kept in ``extra`` are written beside the known ones. The file appears whole or not at
    all (written beside it, then renamed).
    """
    doc: dict[str, Any] = {"info": dataset.info}
    if dataset.licenses is not None:
        doc["licenses"] = dataset.licenses
    doc["videos"] = [{"id": v.id, "name": v.name, **v.extra} for v in dataset.videos]
    doc["images"] = [
        {
            **_drop_none(
                {
                    "id": im.id,
                    "file_name": im.file_name,
                    "height": im.height,
                    "width": im.width,
                    "video_id": im.video_id,
                    "frame_index": im.frame_index,
                }
            ),
            "meta": im.meta,
            **im.extra,
        }
        for im in dataset.images
    ]
    doc["annotations"] = [
        {
            **_drop_none(
                {
                    "id": a.id,
                    "image_id": a.image_id,
                    "video_id": a.video_id,
                    "track_id": a.track_id,
                    "category_id": a.category_id,
                    "bbox": list(a.bbox),
                    "area": a.area,
                    "iscrowd": a.iscrowd,
                    "gt_lat": a.gt_lat,
                    "gt_lon": a.gt_lon,
                }
            ),
            **a.extra,
        }
        for a in dataset.annotations
    ]
    doc["categories"] = [
        {**_drop_none({"id": c.id, "name": c.name, "supercategory": c.supercategory}), **c.extra}
        for c in dataset.categories
    ]
    # beside it first, then renamed: an interrupted write never leaves half a file at ``path``
    path = Path(path)
    partial = path.with_name(f".{path.name}.partial")
    try:
        partial.write_text(json.dumps(doc, indent=1), encoding="utf-8")
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)
