"""Frame sources for live runs: each read returns the next frame stamped with the local
``time.monotonic()`` of its capture, the clock the MAVLink telemetry is mapped to.

- :class:`CameraSource`: a camera device through ``cv2.VideoCapture(N)``; a failed grab is a
  frame without an image (the controller counts it as skipped); many failures in a row end it.
  It asks for a one-frame driver queue (a slow consumer gets the newest frame, not one that
  waited in the queue) and stamps each frame when its grab returns, before it is decoded, or
  with the driver's own capture time where that is on the same clock (:func:`capture_time`).
- :class:`FileSource`: a video file or an image folder played as a camera at its frame rate
  (a frame is not returned before it is due; the stamp is the time it was returned), decoded
  one frame ahead in its own thread (a video to its YUV planes, as ``detect`` reads it).
- :class:`~sarmission.data.stream.StreamSource`: a live network stream (``rtsp://``,
  ``udp://`` MPEG-TS, ...), decoded in its own thread, newest frame first, reconnected when
  lost; :func:`open_video_source` picks it for a URL.

Every source has ``read() -> Frame | None`` (None: the source has ended), ``skipped`` and
``close()``; the simulator's camera (``sim.camera.SimCamera``) has the same interface.
"""

from __future__ import annotations

import logging
import os
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Protocol

import cv2

from sarmission.data.frames import Frame, open_frame_source
from sarmission.data.prefetch import Prefetcher
from sarmission.data.stream import StreamSource, is_stream_url

log = logging.getLogger(__name__)

#: Consecutive failed grabs after which a camera is taken to be gone.
MAX_CAMERA_FAILURES = 50
#: A driver frame time older than this when the grab returns is not believed (seconds).
DRIVER_STAMP_MAX_AGE_S = 1.0
#: Longest single wait (s) of a file played in real time: a stop request is seen within it.
PACING_SLICE_S = 0.1


class LiveSource(Protocol):
    """A camera-like frame source."""

    skipped: int

    def read(self) -> Frame | None: ...

    def close(self) -> None: ...


def capture_time(driver_ms: float, grabbed_at: float) -> float:
    """A grabbed frame's capture time on the ``time.monotonic()`` clock.

    ``driver_ms`` is OpenCV's ``CAP_PROP_POS_MSEC`` after the grab: with V4L2 the buffer's
    timestamp, which UVC and most capture drivers take on CLOCK_MONOTONIC (Python's monotonic
    clock) when the frame was captured. Other backends report a stream position there instead.
    So the driver's time is used when it lies at most :data:`DRIVER_STAMP_MAX_AGE_S` before
    ``grabbed_at`` (when the grab returned), else ``grabbed_at`` itself.
    """
    driver_s = driver_ms / 1000.0
    if 0.0 <= grabbed_at - driver_s <= DRIVER_STAMP_MAX_AGE_S:
        return driver_s
    return grabbed_at


def _camera_problem(index: int) -> str:
    """Why camera ``index`` may not open, as far as the system tells (Linux device nodes)."""
    device = Path(f"/dev/video{index}")
    if sys.platform.startswith("linux"):
        if not device.exists():
            return f"no such device ({device} does not exist)"
        if not os.access(device, os.R_OK | os.W_OK):
            return f"permission denied on {device} (is this user in its group, e.g. 'video'?)"
    return "OpenCV could not open it (in use by another program, or not a capture device?)"


class CameraSource:
    """Camera device ``index`` via OpenCV; ``width``/``height`` request a capture size.

    Raises OSError with one line saying why (e.g. ``cannot open camera 0: no such device``)
    when the camera cannot be opened; OpenCV's own warnings about it are kept off the console.
    """

    def __init__(self, index: int, width: int | None = None, height: int | None = None) -> None:
        self.index = index
        level = cv2.utils.logging.getLogLevel()
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
        try:
            self.capture = cv2.VideoCapture(index)
        finally:
            cv2.utils.logging.setLogLevel(level)
        if not self.capture.isOpened():
            self.capture.release()
            raise OSError(f"cannot open camera {index}: {_camera_problem(index)}")
        self.capture.set(cv2.CAP_PROP_BUFFERSIZE, 1)
        if width:
            self.capture.set(cv2.CAP_PROP_FRAME_WIDTH, width)
        if height:
            self.capture.set(cv2.CAP_PROP_FRAME_HEIGHT, height)
        self.skipped = 0
        self._count = 0
        self._failures = 0

    def read(self) -> Frame | None:
        """The next frame; its image is None when the grab failed; None once the camera is gone."""
        ok = self.capture.grab()
        grabbed_at = time.monotonic()
        stamp = capture_time(self.capture.get(cv2.CAP_PROP_POS_MSEC), grabbed_at)
        image = self.capture.retrieve()[1] if ok else None
        index = self._count
        self._count += 1
        if image is not None:
            self._failures = 0
            return Frame(index, stamp, image)
        self._failures += 1
        self.skipped += 1
        if self._failures >= MAX_CAMERA_FAILURES:
            log.warning("camera %d: %d failed grabs in a row; stopping", self.index, self._failures)
            return None
        return Frame(index, stamp, None)

    def close(self) -> None:
        self.capture.release()


class FileSource:
    """A video file or image folder played back in real time as if it were a camera.

    The wait for a frame to fall due is taken in short slices and ends early once the run
    asks to stop (:meth:`watch`) or the source is closed: a long pause in a file (a slow
    image folder, a gap in a recording) never holds up a stop request or ``--duration``.
    """

    def __init__(self, path: str | Path, fps: float = 30.0, realtime: bool = True) -> None:
        self.source = open_frame_source(path, fps, yuv=True)
        self.fps = self.source.fps
        self.realtime = realtime
        self._frames: Iterator[Frame] = Prefetcher(self.source, depth=1)
        self._start: float | None = None
        self._closed = threading.Event()
        self._stop: threading.Event | None = None
        self._deadline: float | None = None

    @property
    def skipped(self) -> int:
        return self.source.skipped

    def watch(self, stop: threading.Event | None = None, deadline: float | None = None) -> None:
        """End any wait for a frame once ``stop`` is set or at ``deadline``
        (``time.monotonic()``): the frame is then returned at once."""
        self._stop, self._deadline = stop, deadline

    def _interrupted(self) -> bool:
        """Whether a wait for a frame must end now (stop asked, deadline passed, closed)."""
        return (
            self._closed.is_set()
            or (self._stop is not None and self._stop.is_set())
            or (self._deadline is not None and time.monotonic() >= self._deadline)
        )

    def read(self) -> Frame | None:
        """The next frame of the file, once it is due (or a stop is asked); None at the end."""
        frame = next(self._frames, None)
        if frame is None:
            return None
        if self._start is None:
            self._start = time.monotonic() - frame.timestamp_s
        if self.realtime:
            due = self._start + frame.timestamp_s
            while not self._interrupted():
                delay = due - time.monotonic()
                if delay <= 0:
                    break
                self._closed.wait(min(delay, PACING_SLICE_S))
        return frame.restamped(time.monotonic())

    def close(self) -> None:
        self._closed.set()
        close = getattr(self._frames, "close", None)
        if close is not None:
            close()
        self._frames = iter(())


def open_video_source(path: str, fps: float = 30.0) -> LiveSource:
    """A live source for ``--video``: a stream URL (``rtsp://``, ``udp://``, ...) or a file
    played in real time. Raises :class:`~sarmission.data.frames.FrameSourceError` when it
    cannot be opened."""
    if is_stream_url(path):
        return StreamSource(path, default_fps=fps)
    return FileSource(path, fps)
