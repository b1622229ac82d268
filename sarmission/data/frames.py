"""Frame sources: a video file or a folder of images, iterated as :class:`Frame` objects.

Unreadable frames (a corrupt image file, a frame the decoder fails on) are skipped with a
logged warning and counted in ``source.skipped``; they never raise. Frame ``index`` is the
position in the source (skipped frames leave a gap) and ``timestamp_s = index / fps``.
"""

from __future__ import annotations

import logging
import re
from abc import ABC, abstractmethod
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

log = logging.getLogger(__name__)

IMAGE_EXTENSIONS = frozenset({".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"})
#: Consecutive failed reads after which a video is taken to have ended.
MAX_CONSECUTIVE_VIDEO_FAILURES = 25


class FrameSourceError(ValueError):
    """A frame source cannot be opened (missing path, unsupported or unreadable file)."""


@dataclass
class Frame:
    """One frame: position in its source, capture time (s), BGR ``uint8`` image ``[H, W, 3]``."""

    index: int
    timestamp_s: float
    image_bgr: np.ndarray


class FrameSource(ABC):
    """Base of the frame sources: iterable of :class:`Frame`, ``len()`` when the count is known."""

    def __init__(self, path: Path, fps: float) -> None:
        self.path = path
        self.fps = fps
        self.skipped = 0

    @abstractmethod
    def __iter__(self) -> Iterator[Frame]:
        """Frames in order; each iteration starts again from the first frame."""

    @property
    @abstractmethod
    def length(self) -> int | None:
        """Number of frames in the source, or ``None`` when the container does not say."""

    def __len__(self) -> int:
        """The frame count; ``TypeError`` when unknown (check :attr:`length` first)."""
        if self.length is None:
            raise TypeError(f"{self.path}: frame count unknown")
        return self.length

    def _skip(self, index: int, reason: str) -> None:
        self.skipped += 1
        log.warning("%s: frame %d skipped (%s)", self.path, index, reason)


def _natural_key(path: Path) -> list[object]:
    """``frame2.png`` before ``frame10.png``: digit runs compare as numbers."""
    return [int(part) if part.isdigit() else part.lower()
            for part in re.split(r"(\d+)", path.name)]


class ImageFolderSource(FrameSource):
    """Images of one folder (png, jpg, jpeg, bmp, tif) in natural name order at a nominal fps."""

    def __init__(self, path: Path, fps: float = 30.0) -> None:
        super().__init__(path, fps)
        self.files = sorted((p for p in path.iterdir()
                             if p.is_file() and p.suffix.lower() in IMAGE_EXTENSIONS),
                            key=_natural_key)
        if not self.files:
            raise FrameSourceError(
                f"{path}: no images ({', '.join(sorted(IMAGE_EXTENSIONS))}) in folder")

    @property
    def length(self) -> int:
        return len(self.files)

    def __iter__(self) -> Iterator[Frame]:
        for index, file in enumerate(self.files):
            image = cv2.imread(str(file), cv2.IMREAD_COLOR)
            if image is None or image.size == 0:
                self._skip(index, f"cannot decode {file.name}")
                continue
            yield Frame(index, index / self.fps, image)


class VideoFileSource(FrameSource):
    """Frames of a video file decoded by OpenCV (BGR ``uint8``).

    ``fps`` is the container's rate (``default_fps`` when it reports none). A failed read before
    the reported frame count is a skipped frame; reading stops at the count or after
    :data:`MAX_CONSECUTIVE_VIDEO_FAILURES` failures in a row.
    """

    def __init__(self, path: Path, default_fps: float = 30.0) -> None:
        capture = self._open(path)
        try:
            fps = capture.get(cv2.CAP_PROP_FPS)
            count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT))
            first_ok, _ = capture.read()
        finally:
            capture.release()
        if not first_ok:
            raise FrameSourceError(f"{path}: unsupported or unreadable video (no frame decodes)")
        super().__init__(path, fps if fps > 0 else default_fps)
        self._count = count if count > 0 else None

    @staticmethod
    def _open(path: Path) -> cv2.VideoCapture:
        capture = cv2.VideoCapture(str(path))
        if not capture.isOpened():
            capture.release()
            raise FrameSourceError(f"{path}: OpenCV cannot open this file as a video")
        return capture

    @property
    def length(self) -> int | None:
        return self._count

    def __iter__(self) -> Iterator[Frame]:
        capture = self._open(self.path)
        try:
            index, failures = 0, 0
            while self._count is None or index < self._count:
                ok, image = capture.read()
                if ok and image is not None and image.size > 0:
                    failures = 0
                    yield Frame(index, index / self.fps, image)
                else:
                    failures += 1
                    if self._count is None or failures >= MAX_CONSECUTIVE_VIDEO_FAILURES:
                        break
                    self._skip(index, "decoder returned no image")
                index += 1
        finally:
            capture.release()


def open_frame_source(path: str | Path, fps: float = 30.0) -> FrameSource:
    """Open a video file or an image folder.

    ``fps`` is the rate of an image folder, and of a video whose container reports none.
    Raises :class:`FrameSourceError` for a missing path, a single image file, a folder without
    images, or a file OpenCV cannot open or decode a first frame from.
    """
    path = Path(path)
    if fps <= 0:
        raise FrameSourceError(f"fps must be positive, got {fps}")
    if not path.exists():
        raise FrameSourceError(f"{path}: no such file or folder")
    if path.is_dir():
        return ImageFolderSource(path, fps)
    if path.suffix.lower() in IMAGE_EXTENSIONS:
        raise FrameSourceError(f"{path}: a single image is not a frame source; give its folder")
    return VideoFileSource(path, fps)
