"""The STATUSTEXTs the simulated vehicle receives, chunks joined, logged and kept.

A text longer than 50 characters arrives as chunks sharing a non-zero ``id``; a chunk shorter than
50 characters is the last one.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

log = logging.getLogger(__name__)

#: Characters in one STATUSTEXT chunk.
CHUNK_CHARS = 50


@dataclass
class StatusText:
    """A STATUSTEXT received (chunks of one ``id`` joined), with the sim time it arrived."""

    sim_time: float
    severity: int
    text: str
    src_system: int
    src_component: int


class StatusTextLog:
    """Every STATUSTEXT received, in :attr:`statustexts`, stamped with ``clock()``."""

    def __init__(self, clock: Callable[[], float]) -> None:
        self.clock = clock
        self.statustexts: list[StatusText] = []
        self._chunks: dict[tuple[int, int, int], list[str]] = {}
        self._lock = threading.Lock()

    def on_statustext(self, msg: Any) -> None:
        """Keep and log one STATUSTEXT, or hold a chunk until its text is complete."""
        text = msg.text if isinstance(msg.text, str) else msg.text.decode("utf-8", "replace")
        text = text.rstrip("\x00")
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        msg_id = getattr(msg, "id", 0)
        if msg_id:
            key = (src[0], src[1], msg_id)
            parts = self._chunks.setdefault(key, [])
            parts.append(text)
            if len(text) >= CHUNK_CHARS:  # a full chunk: more follow
                return
            text = "".join(self._chunks.pop(key))
        entry = StatusText(self.clock(), int(msg.severity), text, src[0], src[1])
        with self._lock:
            self.statustexts.append(entry)
        log.warning("STATUSTEXT from %d/%d severity %d: %s", src[0], src[1], entry.severity, text)
