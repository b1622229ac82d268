"""Decode ahead: a frame source read in its own thread, a bounded number of frames ahead.

Decoding a 4K H.264 frame costs about as much CPU as detecting in it; in one thread the two
take turns and one of two cores idles. :class:`Prefetcher` runs the source's iterator in a
daemon thread and hands its items over through a queue, so the next frame is decoded while the
current one is processed. The reader starts on an item only while fewer than ``depth`` items are
decoded and not yet done with (the consumer is done with an item when it asks for the next), so
besides the frame being worked on at most ``depth`` more exist (each 4K frame is 25 MB).
Nothing is dropped: a slow consumer makes the reader wait. OpenCV and the FFmpeg decoder release
the GIL, so the two threads do run at once.

An exception in the reader reaches the consumer at the point in the sequence where it happened;
:meth:`Prefetcher.close` (or leaving a ``with`` block) stops the reader and closes the source's
iterator in the reader's thread, so a video file is released however the loop ends.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterable, Iterator
from typing import Generic, TypeVar

T = TypeVar("T")

_END = object()
#: How often a blocked reader looks whether it was told to stop (seconds).
_POLL_S = 0.1


class _Failure:
    """An exception raised by the reader, carried to the consumer."""

    def __init__(self, exc: BaseException) -> None:
        self.exc = exc


class Prefetcher(Generic[T]):
    """Iterate ``items`` in a reader thread, up to ``depth`` items ahead of the consumer."""

    def __init__(self, items: Iterable[T], depth: int = 1, name: str = "decode") -> None:
        if depth < 1:
            raise ValueError(f"depth must be at least 1, got {depth}")
        self._items = items
        self._queue: queue.Queue[object] = queue.Queue()
        # One ticket per item not yet finished with: ``depth`` ahead plus the consumer's.
        self._tickets = threading.Semaphore(depth + 1)
        self._taken = False  # the consumer holds an item it has not finished with
        self._stop = threading.Event()
        self._done = False
        self._thread = threading.Thread(target=self._read, name=name, daemon=True)
        self._thread.start()

    def _ticket(self) -> bool:
        """Wait until another item may be started; False when told to stop first."""
        while not self._stop.is_set():
            if self._tickets.acquire(timeout=_POLL_S):
                return True
        return False

    def _put(self, item: object) -> bool:
        self._queue.put(item)
        return not self._stop.is_set()

    def _read(self) -> None:
        iterator = iter(self._items)
        try:
            while self._ticket():
                try:
                    item = next(iterator)
                except StopIteration:
                    break
                if not self._put(item):
                    return
        except BaseException as exc:  # handed to the consumer, raised there
            self._put(_Failure(exc))
            return
        finally:
            close = getattr(iterator, "close", None)
            if close is not None:
                close()
        self._put(_END)

    def __iter__(self) -> Iterator[T]:
        return self

    def __next__(self) -> T:
        if self._taken:  # done with the previous item: the reader may start one more
            self._taken = False
            self._tickets.release()
        if self._done:
            raise StopIteration
        item = self._queue.get()
        if item is _END:
            self._done = True
            raise StopIteration
        if isinstance(item, _Failure):
            self._done = True
            raise item.exc
        self._taken = True
        return item  # type: ignore[return-value]

    def close(self, timeout_s: float = 5.0) -> None:
        """Stop the reader and wait for it to release the source (at most ``timeout_s``)."""
        self._done = True
        self._stop.set()
        self._thread.join(timeout_s)
        while True:  # let go of the frames nobody will read
            try:
                self._queue.get_nowait()
            except queue.Empty:
                break

    def __enter__(self) -> Prefetcher[T]:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
