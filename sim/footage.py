"""Recorded footage as the simulated camera's picture: a video, an image folder or an annotated
dataset played through :class:`sim.camera.SimCamera`.

:class:`FootageRenderer` satisfies SimCamera's ``Renderer`` protocol: ``render(t, pose)`` returns
the footage frame shown at time ``t`` - index ``floor((t - start_s) * fps)`` - and, when the
footage comes with a COCO video annotation file, that frame's ground truth as
:class:`~sim.render.ObjectAnnotation` (the camera pose is not used: the picture was taken already).

Decoding is sequential: frames are asked for in non-decreasing time, so the next one is decoded
(skipped ones only grabbed), a few recent frames are cached, and the video is only re-opened or
seeked when the request goes back (a loop) or far ahead. Past the last frame ``render`` raises
:class:`EndOfFootage`, or starts again from the first frame with ``loop=True``.

:class:`FootageCamera` is the SimCamera for footage: the footage (and a :class:`MetaFlight`)
starts at the first read, so nothing is missed while the MAVLink link comes up, and the end of
the footage ends the source (``read()`` returns None) as the end of a file does.
"""

from __future__ import annotations

import logging
import math
import time
from collections import OrderedDict
from pathlib import Path

import cv2
import numpy as np

from sarmission.data.coco_video import Annotation, VideoDataset, read_coco_video
from sarmission.data.frames import (
    IMAGE_EXTENSIONS,
    Frame,
    FrameSourceError,
    ImageFolderSource,
)
from sarmission.data.sequence import sequence_images, video_file
from sarmission.geo.camera import CameraPose
from sim.camera import FrameTruth, SimCamera
from sim.render import ObjectAnnotation
from sim.scene import TARGET_CATEGORIES

log = logging.getLogger(__name__)

#: Cached decoded frames.
CACHE_FRAMES = 4
#: A request this many frames or more ahead of the decoder seeks instead of grabbing forward.
SEEK_AHEAD = 90


class EndOfFootage(Exception):  # noqa: N818 - an end, not an error
    """The time asked for lies past the last frame of the footage (and it does not loop)."""


class UnreadableFrame(Exception):  # noqa: N818
    """A frame of the footage exists but cannot be decoded (a corrupt image file)."""


def is_annotation_file(path: str | Path) -> bool:
    """True for a ``.json`` file (a COCO video annotation file)."""
    p = Path(path)
    return p.suffix.lower() == ".json" and p.is_file()


def to_object_annotation(
    ann: Annotation, category: str, supercategory: str | None
) -> ObjectAnnotation:
    """A COCO box as the simulator's annotation (what a run's scoring reads)."""
    x, y, w, h = ann.bbox
    extra = ann.extra or {}
    is_target = extra.get("is_target")
    if not isinstance(is_target, bool):
        is_target = category in TARGET_CATEGORIES or supercategory == "person"
    ned = extra.get("position_ned")
    position = (
        tuple(float(v) for v in ned)
        if isinstance(ned, list) and len(ned) == 3
        else (math.nan, math.nan, math.nan)
    )
    visibility = extra.get("visibility")
    return ObjectAnnotation(
        track_id=ann.track_id if ann.track_id is not None else -ann.id,
        category=category,
        category_id=ann.category_id,
        is_target=is_target,
        bbox_xyxy=(float(x), float(y), float(x + w), float(y + h)),
        area=float(ann.area or w * h),
        visibility=float(visibility) if isinstance(visibility, int | float) else 1.0,
        position_ned=position,  # type: ignore[arg-type]
        lat=ann.gt_lat,
        lon=ann.gt_lon,
    )


class _VideoFrames:
    """Frame ``i`` of a video file: sequential decoding, re-open/seek only when needed."""

    def __init__(self, path: Path, default_fps: float | None) -> None:
        self.path = path
        self._capture = self._open()
        fps = self._capture.get(cv2.CAP_PROP_FPS)
        self.native_fps = fps if fps and fps > 0 and math.isfinite(fps) else None
        self.fps = self.native_fps or default_fps or 30.0
        count = int(self._capture.get(cv2.CAP_PROP_FRAME_COUNT))
        self.length: int | None = count if count > 0 else None
        self._next = 0  # index the next read() returns

    def _open(self) -> cv2.VideoCapture:
        capture = cv2.VideoCapture(str(self.path))
        if not capture.isOpened():
            capture.release()
            raise FrameSourceError(f"{self.path}: OpenCV cannot open this file as a video")
        return capture

    def get(self, index: int) -> np.ndarray | None:
        """The decoded frame ``index``; None past the end (the length is then known)."""
        if self.length is not None and index >= self.length:
            return None
        if index < self._next:
            if index < SEEK_AHEAD:
                self._capture.release()
                self._capture = self._open()
                self._next = 0
            else:
                self._seek(index)
        elif index - self._next >= SEEK_AHEAD:
            self._seek(index)
        while self._next < index:
            if not self._capture.grab():
                return self._ended(self._next)
            self._next += 1
        ok, image = self._capture.read()
        if not ok or image is None or image.size == 0:
            return self._ended(index)
        self._next = index + 1
        return image

    def _seek(self, index: int) -> None:
        self._capture.set(cv2.CAP_PROP_POS_FRAMES, index)
        self._next = int(self._capture.get(cv2.CAP_PROP_POS_FRAMES))

    def _ended(self, index: int) -> None:
        self.length = index if self.length is None else min(self.length, index)
        return None

    def close(self) -> None:
        self._capture.release()


class _FileFrames:
    """Frame ``i`` of a list of image files."""

    def __init__(self, files: list[Path]) -> None:
        self.files = files
        self.length: int | None = len(files)

    def get(self, index: int) -> np.ndarray | None:
        if index >= len(self.files):
            return None
        image = cv2.imread(str(self.files[index]), cv2.IMREAD_COLOR)
        if image is None or image.size == 0:
            raise UnreadableFrame(f"{self.files[index]}: cannot decode")
        return image

    def close(self) -> None:
        pass


class FootageRenderer:
    """Frames of recorded footage by time, with their ground truth when there is any.

    Args:
        path_or_dataset: a video file, an image folder, a COCO video annotation file (``.json``)
            or a read :class:`VideoDataset`; a dataset's frames are its video's file (when the
            video entry names one) or its images' files.
        fps: frames per second of the footage; default the video's own rate, else the rate the
            annotation file declares, else 30.
        annotations: a dataset (or its ``.json``) to take ground truth and the frame order from
            when ``path_or_dataset`` is plain footage.
        video_id: which video of the dataset (default: its first).
        loop: start again from the first frame after the last instead of :class:`EndOfFootage`.
        start_s: time ``t`` at which the first frame is shown.
    """

    def __init__(
        self,
        path_or_dataset: str | Path | VideoDataset,
        fps: float | None = None,
        annotations: str | Path | VideoDataset | None = None,
        video_id: int | None = None,
        loop: bool = False,
        start_s: float = 0.0,
    ) -> None:
        from sim.meta_flight import dataset_fps

        if fps is not None and fps <= 0:
            raise ValueError(f"fps must be positive, got {fps}")
        footage: Path | None = None
        dataset = annotations
        if isinstance(path_or_dataset, VideoDataset) or is_annotation_file(path_or_dataset):
            if dataset is not None:
                raise ValueError("give the annotations either as the footage or separately")
            dataset = path_or_dataset
        else:
            footage = Path(path_or_dataset)
        if dataset is not None and not isinstance(dataset, VideoDataset):
            dataset = read_coco_video(dataset)
        self.dataset: VideoDataset | None = dataset
        if dataset is not None and video_id is None and dataset.videos:
            video_id = dataset.videos[0].id
        self.video_id = video_id
        self.loop = loop
        self.start_s = float(start_s)
        declared = dataset_fps(dataset, video_id) if dataset is not None else None
        self._frames: _VideoFrames | _FileFrames
        self._gt: dict[int, list[ObjectAnnotation]] = {}
        if dataset is not None:
            images = sequence_images(dataset, video_id)
            if not images:
                raise FrameSourceError(f"{dataset.source_path}: video {video_id} has no images")
            names = {c.id: (c.name, c.supercategory) for c in dataset.categories}
            by_image = dataset.annotations_by_image()
            position = {}
            for k, im in enumerate(images):
                index = im.frame_index if im.frame_index is not None else k
                position[im.id] = index
                self._gt[index] = [
                    to_object_annotation(a, *names.get(a.category_id, ("?", None)))
                    for a in by_image.get(im.id, [])
                ]
            if footage is None:
                footage = video_file(dataset, video_id) if video_id is not None else None
                if footage is None:
                    files = [dataset.image_path(im) for im in images]
                    if images[0].frame_index not in (None, 0):
                        log.info(
                            "video %s starts at frame_index %s", video_id, images[0].frame_index
                        )
                    self._gt = {k: self._gt.get(position[im.id], []) for k, im in enumerate(images)}
                    self._frames = _FileFrames(files)
        if footage is not None:
            if not footage.exists():
                raise FrameSourceError(f"{footage}: no such file or folder")
            if footage.is_dir():
                self._frames = _FileFrames(ImageFolderSource(footage).files)
            elif footage.suffix.lower() in IMAGE_EXTENSIONS:
                raise FrameSourceError(f"{footage}: a single image is not footage; give its folder")
            else:
                self._frames = _VideoFrames(footage, None)
        native = self._frames.native_fps if isinstance(self._frames, _VideoFrames) else None
        self.fps = float(fps or native or declared or 30.0)
        self.path = footage
        self._cache: OrderedDict[int, np.ndarray] = OrderedDict()
        self.frames_shown: set[int] = set()

    @property
    def has_ground_truth(self) -> bool:
        return self.dataset is not None

    @property
    def length(self) -> int | None:
        """Frames in the footage (None while a video without a count has not ended)."""
        return self._frames.length

    def start_at(self, t: float) -> None:
        """Show the first frame at time ``t``."""
        self.start_s = float(t)

    def index_at(self, t: float) -> int:
        """Footage frame index shown at time ``t`` (before looping)."""
        return max(0, math.floor((t - self.start_s) * self.fps + 1e-9))

    def frame(self, index: int) -> np.ndarray:
        """Decoded frame ``index`` (cached); :class:`EndOfFootage` past the end."""
        if index in self._cache:
            self._cache.move_to_end(index)
            return self._cache[index]
        image = self._frames.get(index)
        if image is None:
            raise EndOfFootage(
                f"frame {index} is past the end of the footage ({self._frames.length} frames)"
            )
        self._cache[index] = image
        while len(self._cache) > CACHE_FRAMES:
            self._cache.popitem(last=False)
        return image

    def render(
        self, t: float, pose: CameraPose | None = None
    ) -> tuple[np.ndarray, list[ObjectAnnotation]]:
        """The frame shown at ``t`` and its annotations ([] without ground truth)."""
        index = self.index_at(t)
        try:
            image = self.frame(index)
        except EndOfFootage:
            if not self.loop or not self._frames.length:
                raise
            index %= self._frames.length
            image = self.frame(index)
        self.frames_shown.add(index)
        return image, list(self._gt.get(index, []))

    def close(self) -> None:
        self._frames.close()
        self._cache.clear()


class FootageCamera(SimCamera):
    """SimCamera over a :class:`FootageRenderer`: starts the footage (and a flight that follows
    it) at the first read; ``read()`` returns None once the footage has ended, and a frame
    without an image (counted in ``skipped``) for a frame that cannot be decoded."""

    renderer: FootageRenderer
    _started_footage = False

    def read(self) -> Frame | None:  # type: ignore[override]
        if not self._started_footage:
            t0 = self.vehicle.sim_time()
            self.renderer.start_at(t0)
            start = getattr(self.vehicle.flight, "start_at", None)
            if start is not None:
                start(t0)
            self._started_footage = True
        try:
            return super().read()
        except EndOfFootage:
            return None
        except UnreadableFrame as exc:
            log.warning("%s", exc)
            self.skipped += 1
            index = self._count
            self._count += 1
            self.truth.append(FrameTruth(index, self.vehicle.sim_time(), []))
            return Frame(index, time.monotonic(), None)  # type: ignore[arg-type]

    def close(self) -> None:
        self.renderer.close()
