"""Warnings about untrusted input, at most one per key every few seconds, with a count.

A hostile or broken sender can produce thousands of bad messages a second; logging each would
bury the console and cost CPU. :class:`RateLimitedLog` counts every event and logs the first of
each key, then at most one line per ``interval_s`` saying how many were dropped meanwhile.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter
from collections.abc import Callable, Hashable


class RateLimitedLog:
    """Counts events by key; logs at most one line per key every ``interval_s`` seconds."""

    def __init__(
        self,
        logger: logging.Logger,
        interval_s: float = 5.0,
        level: int = logging.WARNING,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.logger = logger
        self.interval_s = interval_s
        self.level = level
        self.clock = clock
        self.counts: Counter[Hashable] = Counter()
        self._last: dict[Hashable, float] = {}
        self._since_last: Counter[Hashable] = Counter()
        self._lock = threading.Lock()

    def event(self, key: Hashable, message: str, *args: object) -> bool:
        """Count one event of ``key``; log ``message % args`` if this key has been quiet for
        ``interval_s``. Returns whether a line was logged."""
        now = self.clock()
        with self._lock:
            self.counts[key] += 1
            self._since_last[key] += 1
            last = self._last.get(key)
            if last is not None and now - last < self.interval_s:
                return False
            self._last[key] = now
            repeated = self._since_last[key] - 1
            self._since_last[key] = 0
        suffix = f" ({repeated} more since the last warning)" if repeated else ""
        self.logger.log(self.level, message + suffix, *args)
        return True

    @property
    def total(self) -> int:
        """Events counted over every key."""
        with self._lock:
            return sum(self.counts.values())
