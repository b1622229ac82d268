"""Frame sources for live runs: each read returns the next frame stamped with the local
``time.monotonic()`` of its capture, the clock the MAVLink telemetry is mapped to.

- :class:`CameraSource`: a camera device through ``cv2.VideoCapture(N)``; a failed grab is a
  frame without an image (the controller counts it as skipped); many failures in a row end it.
- :class:`FileSource`: a video file or an image folder played as a camera at its frame rate
  (a frame is not returned before it is due; the stamp is the time it was returned).

Every source has ``read() -> Frame | None`` (None: the source has ended), ``skipped`` and
``close()``; the simulator's camera (``sim.camera.SimCamera``) has the same interface.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Protocol

import cv2

from sarmission.data.frames import Frame, open_frame_source

log = logging.getLogger(__name__)

#: Consecutive failed grabs after which a camera is taken to be gone.
MAX_CAMERA_FAILURES = 50


class LiveSource(Protocol):
    """A camera-like frame source."""

    skipped: int

    def read(self) -> Frame | None: ...

    def close(self) -> None: ...


class CameraSource:
    """Camera device ``index`` via OpenCV; ``width``/``height`` request a capture size."""

    def __init__(self, index: int, width: int | None = None, height: int | None = None) -> None:
        self.index = index
        self.capture = cv2.VideoCapture(index)
        if not self.capture.isOpened():
            self.capture.release()
            raise OSError(f"cannot open camera {index} (cv2.VideoCapture({index}) failed)")
        if width:
            self.capture.set(cv2.CAP_PROP_FRAME_WIDTH, width)
        if height:
            self.capture.set(cv2.CAP_PROP_FRAME_HEIGHT, height)
        self.skipped = 0
        self._count = 0
        self._failures = 0

    def read(self) -> Frame | None:
        """The next frame; its image is None when the grab failed; None once the camera is gone."""
        ok, image = self.capture.read()
        stamp = time.monotonic()
        index = self._count
        self._count += 1
        if ok and image is not None:
            self._failures = 0
            return Frame(index, stamp, image)
        self._failures += 1
        self.skipped += 1
        if self._failures >= MAX_CAMERA_FAILURES:
            log.warning("camera %d: %d failed grabs in a row; stopping", self.index,
                        self._failures)
            return None
        return Frame(index, stamp, None)

    def close(self) -> None:
        self.capture.release()


class FileSource:
    """A video file or image folder played back in real time as if it were a camera."""

    def __init__(self, path: str | Path, fps: float = 30.0, realtime: bool = True) -> None:
        self.source = open_frame_source(path, fps)
        self.fps = self.source.fps
        self.realtime = realtime
        self._frames: Iterator[Frame] = iter(self.source)
        self._start: float | None = None

    @property
    def skipped(self) -> int:
        return self.source.skipped

    def read(self) -> Frame | None:
        """The next frame of the file, once it is due; None at the end."""
        frame = next(self._frames, None)
        if frame is None:
            return None
        if self._start is None:
            self._start = time.monotonic() - frame.timestamp_s
        if self.realtime:
            delay = self._start + frame.timestamp_s - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        return Frame(frame.index, time.monotonic(), frame.image_bgr)

    def close(self) -> None:
        self._frames = iter(())
