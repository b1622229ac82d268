"""Frame sources: a video file or a folder of images, iterated as :class:`Frame` objects.

Unreadable frames (a corrupt image file, a frame the decoder fails on) are skipped with a
logged warning and counted in ``source.skipped``; they never raise. Frame ``index`` is the
position in the source (skipped frames leave a gap). A video frame's ``timestamp_s`` is its
presentation time in the file (so a variable frame rate keeps its real spacing), an image's
``index / fps``.

Videos are decoded by OpenCV's FFmpeg backend with the thread plan's decoding threads
(:mod:`sarmission.threads`); :class:`~sarmission.data.prefetch.Prefetcher` runs a source in its
own thread. Network streams (``rtsp://``, ``udp://``, ...) are live sources: see
:mod:`sarmission.data.stream`.
"""

from __future__ import annotations

import logging
import math
import re
from abc import ABC, abstractmethod
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from sarmission.ratelimit import RateLimitedLog
from sarmission.yuv import YuvImage

if TYPE_CHECKING:
    from sarmission.data.stream import StreamSource

log = logging.getLogger(__name__)

IMAGE_EXTENSIONS = frozenset({".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"})
#: Consecutive failed reads after which a video is taken to have ended.
MAX_CONSECUTIVE_VIDEO_FAILURES = 25
#: A step between two frames' presentation times longer than this (s) is a discontinuity.
MAX_TIMESTAMP_STEP_S = 5.0
#: Frame rates taken from a user (frames/s): outside these, a typo, not a camera (``nan``,
#: ``inf`` or ``1e-300`` once gave a run that never paced, or never returned a frame).
MIN_FPS, MAX_FPS = 0.001, 1000.0


class FrameSourceError(ValueError):
    """A frame source cannot be opened (missing path, unsupported or unreadable file)."""


class Frame:
    """One frame: position in its source, capture time (s) and the picture, either as BGR
    ``uint8`` ``image_bgr`` ``[H, W, 3]`` or as the decoder's YUV planes ``yuv`` (a
    :class:`~sarmission.yuv.YuvImage`; ``image_bgr`` then converts the whole picture on first
    use). For a live stream also its presentation time in the stream (``timestamp_s`` is then on
    the local monotonic clock). ``image_bgr`` is None for a frame without a picture."""

    __slots__ = ("_bgr", "index", "stream_time_s", "timestamp_s", "yuv")

    def __init__(
        self,
        index: int,
        timestamp_s: float,
        image_bgr: np.ndarray | None = None,
        stream_time_s: float | None = None,
        yuv: YuvImage | None = None,
    ) -> None:
        self.index = index
        self.timestamp_s = timestamp_s
        self._bgr = image_bgr
        self.stream_time_s = stream_time_s
        self.yuv = yuv

    @classmethod
    def of(cls, index: int, timestamp_s: float, picture: np.ndarray | YuvImage | None) -> Frame:
        """A frame of a picture as :attr:`image` gives it (BGR array or YUV planes)."""
        if isinstance(picture, YuvImage):
            return cls(index, timestamp_s, yuv=picture)
        return cls(index, timestamp_s, picture)

    @property
    def image_bgr(self) -> np.ndarray | None:
        """The picture as BGR uint8 (a YUV frame's converted once, on first use)."""
        if self._bgr is None and self.yuv is not None:
            return self.yuv.bgr
        return self._bgr

    @property
    def image(self) -> np.ndarray | YuvImage | None:
        """The picture as decoded: the YUV planes when the source gives them, else BGR (what
        :meth:`~sarmission.perception.mitenet.MiteNet.process` takes without converting)."""
        return self.yuv if self.yuv is not None else self._bgr

    def restamped(self, timestamp_s: float) -> Frame:
        """The same frame and picture (not converted) with another capture time."""
        return Frame(self.index, timestamp_s, self._bgr, self.stream_time_s, self.yuv)

    def __repr__(self) -> str:
        kind = "yuv" if self.yuv is not None else "bgr" if self._bgr is not None else "none"
        return f"Frame(index={self.index}, timestamp_s={self.timestamp_s}, picture={kind})"


class FrameSource(ABC):
    """Base of the frame sources: iterable of :class:`Frame`, ``len()`` when the count is known."""

    def __init__(self, path: Path, fps: float) -> None:
        self.path = path
        self.fps = fps
        self.skipped = 0
        self._warnings = RateLimitedLog(log)

    @abstractmethod
    def __iter__(self) -> Iterator[Frame]:
        """Frames in order; each iteration starts again from the first frame."""

    @property
    @abstractmethod
    def length(self) -> int | None:
        """Number of frames in the source, or ``None`` when the container does not say."""

    def __bool__(self) -> bool:
        """A source is a source, whatever its count: without this, ``if source`` would call
        :meth:`__len__`, which raises for a container that does not state its frame count
        (Matroska, MPEG-TS)."""
        return True

    def __len__(self) -> int:
        """The frame count; ``TypeError`` when unknown (check :attr:`length` first)."""
        if self.length is None:
            raise TypeError(f"{self.path}: frame count unknown")
        return self.length

    def _skip(self, index: int, reason: str, kind: str | None = None) -> None:
        """Count a frame that could not be read; warn about it, at most every few seconds per
        ``kind`` (default: the reason), so that a damaged file cannot flood the console."""
        self.skipped += 1
        self._warnings.event(kind or reason, "%s: frame %d skipped (%s)", self.path, index, reason)


def _natural_key(path: Path) -> list[object]:
    """``frame2.png`` before ``frame10.png``: digit runs compare as numbers."""
    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", path.name)]


class ImageFolderSource(FrameSource):
    """Images of one folder (png, jpg, jpeg, bmp, tif) in natural name order at a nominal fps."""

    def __init__(self, path: Path, fps: float = 30.0) -> None:
        super().__init__(path, fps)
        self.files = sorted(
            (p for p in path.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_EXTENSIONS),
            key=_natural_key,
        )
        if not self.files:
            raise FrameSourceError(
                f"{path}: no images ({', '.join(sorted(IMAGE_EXTENSIONS))}) in folder"
            )

    @property
    def length(self) -> int:
        return len(self.files)

    def __iter__(self) -> Iterator[Frame]:
        for index, file in enumerate(self.files):
            image = cv2.imread(str(file), cv2.IMREAD_COLOR)
            if image is None or image.size == 0:
                self._skip(index, f"cannot decode {file.name}", "undecodable image")
                continue
            yield Frame(index, index / self.fps, image)


class VideoFileSource(FrameSource):
    """Frames of a video file decoded by OpenCV (BGR ``uint8``).

    ``fps`` is the container's rate (``default_fps`` when it reports none). A failed read
    followed by a good one is a skipped frame; reading stops at the reported frame count or
    after :data:`MAX_CONSECUTIVE_VIDEO_FAILURES` failures in a row (the end of the file: some
    containers only estimate the count). ``threads`` is the number of FFmpeg
    decoding threads (default: the thread plan's).
    """

    def __init__(self, path: Path, default_fps: float = 30.0, threads: int | None = None) -> None:
        self.threads = threads
        capture = self._open(path, threads)
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
    def _open(path: Path, threads: int | None) -> cv2.VideoCapture:
        from sarmission.threads import thread_plan

        count = threads or thread_plan().decode
        capture = cv2.VideoCapture(str(path), cv2.CAP_ANY, [cv2.CAP_PROP_N_THREADS, count])
        if not capture.isOpened():  # a backend that takes no thread count
            capture.release()
            capture = cv2.VideoCapture(str(path))
        if not capture.isOpened():
            capture.release()
            raise FrameSourceError(f"{path}: OpenCV cannot open this file as a video")
        return capture

    @property
    def length(self) -> int | None:
        return self._count

    def __iter__(self) -> Iterator[Frame]:
        capture = self._open(self.path, self.threads)
        try:
            index = 0
            failed: list[int] = []  # reads that failed since the last frame
            clock = _PresentationTimes(self.fps, self.path)
            while self._count is None or index < self._count:
                ok, image = capture.read()
                if ok and image is not None and image.size > 0:
                    for skipped in failed:  # a frame came after them: they were frames
                        self._skip(skipped, "decoder returned no image")
                    failed.clear()
                    yield Frame(index, clock.time(index, capture.get(cv2.CAP_PROP_POS_MSEC)), image)
                else:
                    if self._count is None:
                        break
                    failed.append(index)
                    if len(failed) >= MAX_CONSECUTIVE_VIDEO_FAILURES:
                        break
                index += 1
            if failed:
                # No frame after them: the file ends here (the header's count is an estimate in
                # some containers, or the file was cut short). One line, not one per frame.
                log.info(
                    "%s: the video ends at frame %d of the %d its header announces",
                    self.path,
                    failed[0],
                    self._count,
                )
        finally:
            capture.release()


class _PresentationTimes:
    """A decoded frame's time in its file: the decoder's presentation time while it moves
    forward by a plausible step; time never jumps or goes back.

    A forward step longer than :data:`MAX_TIMESTAMP_STEP_S` (and than ten nominal frame
    periods per frame) is a discontinuity (e.g. two recordings joined end to end): the clock
    goes on at the nominal frame spacing and follows the file's times from there, with one
    warning. A file without timestamps, or whose times go back, is timed at the frame period
    from the last time given for the rest of the file.
    """

    def __init__(self, fps: float, name: object = "video") -> None:
        self.fps = fps
        self.name = name
        self._last: tuple[int, float] | None = None  # index and time of the last frame
        self._offset = 0.0  # added to the file's times since the last discontinuity
        self._last_seconds: float | None = None  # the file's own time of the last frame
        self._trusted = True
        self._warnings = RateLimitedLog(log, interval_s=60.0)

    def time(self, index: int, position_ms: float) -> float:
        seconds = position_ms / 1000.0
        last = self._last
        nominal = 0.0 if last is None else (index - last[0]) / self.fps
        if not (self._trusted and math.isfinite(seconds) and seconds >= 0):
            self._trusted = False
        elif last is not None and self._last_seconds is not None:
            step = seconds - self._last_seconds
            if step <= 0:
                self._trusted = False
            elif step > max(MAX_TIMESTAMP_STEP_S, 10.0 * nominal):
                self._offset = last[1] + nominal - seconds
                self._warnings.event(
                    "jump",
                    "%s: timestamps jump by %.1f s at frame %d; taken as a discontinuity "
                    "(timed at %.3g frames/s across it)",
                    self.name,
                    step,
                    index,
                    self.fps,
                )
        if self._trusted:
            stamp = seconds + self._offset
            self._last_seconds = seconds
        else:
            stamp = index / self.fps if last is None else last[1] + nominal
        self._last = (index, stamp)
        return stamp


def open_frame_source(
    path: str | Path, fps: float = 30.0, yuv: bool = False
) -> FrameSource | StreamSource:
    """Open a video file, an image folder or a live stream URL (``rtsp://``, ``udp://``, ...:
    a :class:`~sarmission.data.stream.StreamSource`, whose ``length`` is None). Only a ``str``
    can be a URL: a ``Path`` (e.g. from a dataset file) is always a file or folder.

    ``yuv``: a video file's frames come as the decoder's YUV planes (``Frame.yuv``, read by
    :class:`~sarmission.data.yuv_video.YuvVideoSource`) when PyAV is installed; BGR otherwise,
    and from image folders and streams.

    ``fps`` is the rate of an image folder, and of a video whose container reports none.
    Raises :class:`FrameSourceError` for a missing path, a single image file, a folder without
    images, a file OpenCV cannot open or decode a first frame from, or a stream that sends no
    video.
    """
    if not (math.isfinite(fps) and MIN_FPS <= fps <= MAX_FPS):
        raise FrameSourceError(f"fps must be from {MIN_FPS:g} to {MAX_FPS:g}, got {fps}")
    from sarmission.data.stream import StreamSource, is_stream_url

    if isinstance(path, str) and is_stream_url(path):
        return StreamSource(path, default_fps=fps)
    path = Path(path)
    if not path.exists():
        raise FrameSourceError(f"{path}: no such file or folder")
    if path.is_dir():
        return ImageFolderSource(path, fps)
    if path.suffix.lower() in IMAGE_EXTENSIONS:
        raise FrameSourceError(f"{path}: a single image is not a frame source; give its folder")
    if yuv:
        from sarmission.data.yuv_video import YuvVideoSource, yuv_decoding_available

        if yuv_decoding_available():
            return YuvVideoSource(path, fps)
    return VideoFileSource(path, fps)
