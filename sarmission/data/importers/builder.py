"""The project's COCO-video dataset, assembled one image and box at a time by an importer.

Every importer reads a published dataset's own layout and hands its images and boxes to a
:class:`DatasetBuilder`, which numbers images, boxes and videos, unites categories by name and
keeps image paths absolute (the written file may go anywhere). Category names are the
project's (:mod:`sarmission.class_roles`): ``person`` on land, ``swimmer`` /
``swimmer_with_life_jacket`` at sea, object names as the dataset spells them, normalised. An
ignore region (a crowd, an unsure box) is stored with ``iscrowd = 1``: training and evaluation
never count it as a target nor as background.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2

from sarmission.class_roles import normalise_class
from sarmission.data.coco_video import (
    Annotation,
    Category,
    DatasetFormatError,
    ImageRecord,
    Video,
    VideoDataset,
    parse_telemetry,
)

log = logging.getLogger(__name__)

#: Category of regions a dataset marks to be ignored (no class of its own).
IGNORED = "ignored"


def image_size(path: Path) -> tuple[int, int]:
    """``(width, height)`` of an image file, read from the file (``DatasetFormatError`` if it
    cannot be read)."""
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise DatasetFormatError(f"{path}: not a readable image")
    return int(image.shape[1]), int(image.shape[0])


@dataclass
class DatasetBuilder:
    """Collects one imported dataset (module docstring). ``source``: what the dataset is
    called in ``info``; ``licence``: its licence, written into ``licenses``."""

    source: str
    licence: str
    videos: list[Video] = field(default_factory=list)
    images: list[ImageRecord] = field(default_factory=list)
    annotations: list[Annotation] = field(default_factory=list)
    info: dict[str, Any] = field(default_factory=dict)
    skipped: Counter[str] = field(default_factory=Counter)
    _categories: dict[str, int] = field(default_factory=dict)
    _videos: dict[str, int] = field(default_factory=dict)

    def category(self, name: str) -> int:
        """The id of category ``name`` (normalised), created on first use."""
        key = normalise_class(name)
        if not key:
            raise DatasetFormatError(f"empty category name {name!r}")
        return self._categories.setdefault(key, len(self._categories) + 1)

    def video(self, name: str) -> int:
        """The id of the video called ``name``, created on first use."""
        if name not in self._videos:
            self._videos[name] = len(self._videos) + 1
            self.videos.append(Video(self._videos[name], name))
        return self._videos[name]

    def image(
        self,
        path: Path,
        width: int,
        height: int,
        *,
        video: str | None = None,
        frame_index: int | None = None,
        meta: dict[str, Any] | None = None,
        extra: dict[str, Any] | None = None,
    ) -> int:
        """Add an image (``path`` made absolute); returns its id."""
        if not (width > 0 and height > 0 and math.isfinite(width) and math.isfinite(height)):
            raise DatasetFormatError(f"{path}: image size {width}x{height}")
        image_id = len(self.images) + 1
        self.images.append(
            ImageRecord(
                id=image_id,
                file_name=str(Path(path).resolve()),
                width=int(width),
                height=int(height),
                video_id=self.video(video) if video is not None else None,
                frame_index=frame_index,
                meta=meta,
                telemetry=parse_telemetry(meta, str(path)),
                extra=dict(extra or {}),
            )
        )
        return image_id

    def box(
        self,
        image_id: int,
        category: str,
        x: float,
        y: float,
        w: float,
        h: float,
        *,
        ignore: bool = False,
        track_id: int | None = None,
        extra: dict[str, Any] | None = None,
    ) -> bool:
        """Add a box ``x, y, w, h`` (pixels, top-left corner) clipped to its image; a box with
        no area inside the image is skipped and counted. Returns whether it was added."""
        image = self.images[image_id - 1]
        if not all(math.isfinite(float(v)) for v in (x, y, w, h)):
            self.skipped["box not a number"] += 1
            return False
        x0, y0 = max(0.0, float(x)), max(0.0, float(y))
        x1 = min(float(image.width), float(x) + float(w))
        y1 = min(float(image.height), float(y) + float(h))
        if not (x1 > x0 and y1 > y0):
            self.skipped["box outside its image or empty"] += 1
            return False
        bbox = (x0, y0, x1 - x0, y1 - y0)
        self.annotations.append(
            Annotation(
                id=len(self.annotations) + 1,
                image_id=image_id,
                category_id=self.category(category),
                bbox=bbox,
                track_id=track_id,
                video_id=image.video_id,
                area=bbox[2] * bbox[3],
                iscrowd=int(ignore),
                extra=dict(extra or {}),
            )
        )
        return True

    def build(self) -> VideoDataset:
        """The dataset; raises ``DatasetFormatError`` when no image was found."""
        if not self.images:
            raise DatasetFormatError(f"{self.source}: no annotated image found")
        by_video: dict[int, list[ImageRecord]] = {}
        for image in self.images:
            if image.video_id is not None:
                by_video.setdefault(image.video_id, []).append(image)
        names = {v.id: v.name for v in self.videos}
        for video_id, frames in by_video.items():  # frames without an index: numbered in order
            unnumbered = sum(im.frame_index is None for im in frames)
            if unnumbered:
                if unnumbered < len(frames):  # the numbers the others had are lost: say so
                    log.warning(
                        "%s: video %s: %d of %d frames have no frame number; all its frames "
                        "are numbered in file order",
                        self.source,
                        names.get(video_id, video_id),
                        unnumbered,
                        len(frames),
                    )
                for index, im in enumerate(frames):
                    im.frame_index = index
        info = {"description": f"imported from {self.source}", **self.info}
        if self.skipped:
            info["skipped"] = dict(self.skipped)
        return VideoDataset(
            videos=self.videos,
            images=self.images,
            annotations=self.annotations,
            categories=[
                Category(cid, name, "person" if name in ("person", "swimmer") else None)
                for name, cid in self._categories.items()
            ],
            info=info,
            licenses=[{"name": self.licence}],
        )
