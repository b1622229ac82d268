"""Frames of one annotated video, in frame order, paired with their image records.

A video's frames are found in one of two ways:

- the video entry names a video file (``"file_name": "seq1.mp4"`` beside the annotation file, as
  ``sarmission sim generate --video`` writes): it is decoded in order and frame ``i`` of the file
  is the image whose ``frame_index`` is ``i``;
- otherwise every image's own ``file_name`` is read (SeaDronesSee, SAR-Tiny, image folders).

Frames that cannot be read are skipped with a warning (never raised), and counted.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from sarmission.data.coco_video import ImageRecord, VideoDataset
from sarmission.data.frames import FrameSourceError, open_frame_source

log = logging.getLogger(__name__)


@dataclass
class AnnotatedFrame:
    """One decoded frame of an annotated video."""

    image: ImageRecord
    frame_bgr: np.ndarray


def video_file(dataset: VideoDataset, video_id: int) -> Path | None:
    """The video file of ``video_id`` if its entry names one, resolved beside the annotations."""
    video = next((v for v in dataset.videos if v.id == video_id), None)
    name = video.extra.get("file_name") if video is not None else None
    if not name:
        return None
    path = Path(name)
    if not path.is_absolute() and dataset.source_path is not None:
        path = dataset.source_path.parent / path
    return path


def sequence_ids(dataset: VideoDataset) -> list[int | None]:
    """Video ids in the dataset (``[None]`` for a plain COCO file without videos)."""
    return [v.id for v in dataset.videos] or [None]


def sequence_images(dataset: VideoDataset, video_id: int | None) -> list[ImageRecord]:
    """Images of one video sorted by frame index (all images when ``video_id`` is None)."""
    images = [im for im in dataset.images if video_id is None or im.video_id == video_id]
    return sorted(images, key=lambda im: im.frame_index if im.frame_index is not None else im.id)


def iter_sequence(
    dataset: VideoDataset, video_id: int | None, counters: dict[str, int] | None = None
) -> Iterator[AnnotatedFrame]:
    """Yield the frames of one video in order; unreadable frames are skipped and counted.

    ``counters`` (if given) receives ``counters["skipped"]`` += 1 per unreadable frame.
    """
    images = sequence_images(dataset, video_id)
    path = video_file(dataset, video_id) if video_id is not None else None
    if path is not None:
        yield from _from_video_file(path, images, counters)
        return
    for image in images:
        file = dataset.image_path(image)
        frame = cv2.imread(str(file), cv2.IMREAD_COLOR)
        if frame is None:
            log.warning("skipping unreadable frame %s", file)
            if counters is not None:
                counters["skipped"] = counters.get("skipped", 0) + 1
            continue
        yield AnnotatedFrame(image, frame)


def _from_video_file(
    path: Path, images: list[ImageRecord], counters: dict[str, int] | None
) -> Iterator[AnnotatedFrame]:
    by_index = {im.frame_index: im for im in images}
    try:
        source = open_frame_source(path)
    except FrameSourceError as exc:
        raise FrameSourceError(f"annotated video {path}: {exc}") from None
    seen = set()
    for frame in source:
        image = by_index.get(frame.index)
        if image is not None:
            seen.add(frame.index)
            yield AnnotatedFrame(image, frame.image_bgr)
    missing = len(by_index) - len(seen)
    if missing and counters is not None:
        counters["skipped"] = counters.get("skipped", 0) + missing
    if missing:
        log.warning("%s: %d annotated frames could not be decoded", path, missing)
