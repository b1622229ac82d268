"""Decoding ahead in a reader thread: order kept, a bounded number of frames ahead, errors
raised where they happened, the source released however the loop ends, and real overlap."""

from __future__ import annotations

import threading

import cv2
import numpy as np
import pytest
from conftest import wait_until

from sarmission.data.frames import open_frame_source
from sarmission.data.prefetch import Prefetcher


def test_items_come_in_order_and_at_most_depth_ahead():
    produced: list[int] = []

    def items():
        for i in range(20):
            produced.append(i)
            yield i

    with Prefetcher(items(), depth=2) as ahead:
        got = [next(ahead)]
        # item 0 is being worked on: the reader decodes 1 and 2, not 3 (4K frames are 25 MB)
        assert wait_until(lambda: len(produced) == 3, 10.0)
        assert not wait_until(lambda: len(produced) > 3, 0.3)
        got.append(next(ahead))  # done with 0: one more may start
        assert wait_until(lambda: len(produced) == 4, 10.0)
        assert not wait_until(lambda: len(produced) > 4, 0.3)
        got += list(ahead)
    assert got == list(range(20))


def test_an_error_is_raised_where_it_happened():
    def items():
        yield 1
        yield 2
        raise OSError("disk gone")

    ahead = Prefetcher(items())
    assert next(ahead) == 1 and next(ahead) == 2
    with pytest.raises(OSError, match="disk gone"):
        next(ahead)
    with pytest.raises(StopIteration):
        next(ahead)


def test_closing_early_stops_the_reader_and_closes_the_source():
    closed = threading.Event()

    def items():
        try:
            i = 0
            while True:
                yield i
                i += 1
        finally:
            closed.set()

    ahead = Prefetcher(items(), depth=1, name="test-reader")
    assert next(ahead) == 0
    ahead.close()
    assert closed.is_set()
    assert not any(t.name == "test-reader" for t in threading.enumerate())
    with pytest.raises(StopIteration):
        next(ahead)


def test_the_next_frame_is_decoded_while_the_current_one_is_worked_on():
    decoded = [threading.Event() for _ in range(3)]

    def items():
        for i in range(3):
            decoded[i].set()
            yield i

    ahead = Prefetcher(items())
    assert next(ahead) == 0
    # still "processing" frame 0: without a reader thread, frame 1 would not be decoded yet
    assert decoded[1].wait(10.0)
    assert list(ahead) == [1, 2]


def test_a_video_read_ahead_gives_the_same_frames(tmp_path):
    path = tmp_path / "clip.mp4"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (64, 48))
    rng = np.random.default_rng(0)
    for _ in range(9):
        writer.write(rng.integers(0, 256, (48, 64, 3), dtype=np.uint8))
    writer.release()
    source = open_frame_source(path)
    direct = list(source)
    with Prefetcher(source) as ahead:
        read_ahead = list(ahead)
    assert [f.index for f in read_ahead] == [f.index for f in direct] == list(range(9))
    assert [f.timestamp_s for f in read_ahead] == [f.timestamp_s for f in direct]
    for a, b in zip(read_ahead, direct, strict=True):
        np.testing.assert_array_equal(a.image_bgr, b.image_bgr)
