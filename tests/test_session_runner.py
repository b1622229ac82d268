"""SessionRunner: the one frame loop of live runs and replays - limits, stop, skips, counting."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from typing import Any

import numpy as np

from sarmission.data.frames import Frame
from sarmission.mission.session_runner import SessionRunner


class RecordingSink:
    """Records what the loop hands over; sets ``stop`` after ``stop_after`` frames."""

    def __init__(self, stop: threading.Event | None = None, stop_after: int = 0) -> None:
        self.processed: list[tuple[int, float]] = []
        self.skipped: list[tuple[int, str]] = []
        self.stop = stop
        self.stop_after = stop_after

    def process(self, frame_index: int, timestamp: float, frame: Any) -> list[Any]:
        assert isinstance(frame, np.ndarray)
        self.processed.append((frame_index, timestamp))
        if self.stop is not None and len(self.processed) >= self.stop_after:
            self.stop.set()
        return []

    def skip(self, frame_index: int, reason: str) -> None:
        self.skipped.append((frame_index, reason))


class CountingFrames:
    """``count`` frames at 10 fps; frames listed in ``blank`` come without an image."""

    def __init__(self, count: int, blank: tuple[int, ...] = ()) -> None:
        self.count = count
        self.blank = blank
        self.taken = 0

    def __iter__(self) -> Iterator[Frame]:
        for i in range(self.count):
            self.taken += 1
            image = None if i in self.blank else np.zeros((4, 4, 3), np.uint8)
            yield Frame(i, i / 10.0, image)  # type: ignore[arg-type]


def test_every_frame_goes_to_the_sink_and_the_end_is_reported():
    sink = RecordingSink()
    ticks = []
    runner = SessionRunner(sink, on_frame=lambda: ticks.append(runner.frames_read))
    ended = runner.run(CountingFrames(3))
    assert ended is True
    assert sink.processed == [(0, 0.0), (1, 0.1), (2, 0.2)]
    assert runner.frames_read == 3
    assert ticks == [1, 2, 3]


def test_a_frame_without_an_image_is_skipped_and_counted():
    sink = RecordingSink()
    runner = SessionRunner(sink)
    assert runner.run(CountingFrames(3, blank=(1,)))
    assert [i for i, _ in sink.processed] == [0, 2]
    assert sink.skipped == [(1, "camera delivered no image")]
    assert runner.frames_read == 3


def test_max_frames_stops_before_taking_another_frame():
    frames = CountingFrames(10)
    sink = RecordingSink()
    runner = SessionRunner(sink)
    assert runner.run(frames, max_frames=4) is False
    assert [i for i, _ in sink.processed] == [0, 1, 2, 3]
    assert frames.taken == 4


def test_max_frames_counts_over_every_run():
    sink = RecordingSink()
    runner = SessionRunner(sink)
    runner.run(CountingFrames(3), max_frames=5)
    assert runner.run(CountingFrames(3), max_frames=5) is False
    assert runner.frames_read == 5
    assert len(sink.processed) == 5


def test_a_stop_request_ends_the_loop_after_the_current_frame():
    stop = threading.Event()
    frames = CountingFrames(10)
    sink = RecordingSink(stop, stop_after=2)
    assert SessionRunner(sink).run(frames, stop=stop) is False
    assert [i for i, _ in sink.processed] == [0, 1]
    assert frames.taken == 2


def test_a_spent_duration_takes_no_frame():
    frames = CountingFrames(5)
    sink = RecordingSink()
    assert SessionRunner(sink).run(frames, duration_s=0.0) is False
    assert frames.taken == 0 and sink.processed == []
