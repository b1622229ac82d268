"""One frame loop for every session: frames from a source into the mission controller.

A live run, the simulator, a replayed video differ in where frames and telemetry come from; the
loop that feeds the controller, counts the frames, reports progress and stops on a limit, a stop
request or the end of the source is this one.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable
from typing import Any, Protocol


class SessionFrame(Protocol):
    """A frame as the loop needs it (:class:`~sarmission.data.frames.Frame`); ``image`` (BGR, or
    the decoder's YUV planes) None when the camera delivered none."""

    @property
    def index(self) -> int: ...

    @property
    def timestamp_s(self) -> float: ...

    @property
    def image(self) -> Any: ...


class FrameSink(Protocol):
    """What takes the frames: the mission controller."""

    def process(self, frame_index: int, timestamp: float, frame: Any) -> Any: ...

    def skip(self, frame_index: int, reason: str) -> None: ...


class SessionRunner:
    """Feeds frames to ``sink`` and counts them in :attr:`frames_read` (over every :meth:`run`).

    ``on_frame`` is called after each frame is handed over (e.g. to advance a progress bar).
    """

    def __init__(self, sink: FrameSink, on_frame: Callable[[], None] | None = None) -> None:
        self.sink = sink
        self.on_frame = on_frame
        self.frames_read = 0

    def run(
        self,
        frames: Iterable[SessionFrame],
        stop: threading.Event | None = None,
        max_frames: int | None = None,
        duration_s: float | None = None,
    ) -> bool:
        """Hand frames over until ``frames`` ends, ``max_frames`` were read in all, ``duration_s``
        of wall time passed or ``stop`` is set. True when it stopped because ``frames`` ended.

        No frame is taken from ``frames`` once a limit is reached."""
        deadline = None if duration_s is None else time.monotonic() + duration_s
        source = iter(frames)
        while not (stop is not None and stop.is_set()):
            if max_frames is not None and self.frames_read >= max_frames:
                return False
            if deadline is not None and time.monotonic() >= deadline:
                return False
            frame = next(source, None)
            if frame is None:
                return True
            self.frames_read += 1
            image = frame.image
            if image is None:
                self.sink.skip(frame.index, "camera delivered no image")
            else:
                self.sink.process(frame.index, frame.timestamp_s, image)
            if self.on_frame is not None:
                self.on_frame()
        return False
