"""Telemetry streams asked of the autopilot: when to ask again, and when to give up.

ArduPilot sends nothing but HEARTBEAT until each message is asked for with
MAV_CMD_SET_MESSAGE_INTERVAL, forgets the intervals when it reboots, and a request can be lost.
:class:`StreamWatchdog` keeps the wanted rates and says which stream to ask for again: one missing
for ``max(3 periods, retry_s)`` is re-requested, with backoff (``retry_s``, then 2x, 4x, ... up to
:data:`MAX_RETRY_S`) while it stays missing.

A stream that never arrived from this autopilot is given up after ``max_tries`` requests: ArduPilot
accepts an interval for a message it has nothing to send for (GIMBAL_DEVICE_ATTITUDE_STATUS with
no mount) and then stays silent. It is logged once and listed in ``given_up``, and taken back if it
arrives after all (ArduPilot keeps an accepted interval: HOME_POSITION starts by itself once home
is set). A stream that arrived and then stopped (a reboot) is asked for as long as it is missing.
Streams the autopilot refused (DENIED, UNSUPPORTED) are not asked for again.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Mapping
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as M

log = logging.getLogger(__name__)

#: Longest wait between two requests for a stream that stays missing (seconds).
MAX_RETRY_S = 30.0
_REFUSED = (M.MAV_RESULT_DENIED, M.MAV_RESULT_UNSUPPORTED)


def message_name(msg_id: int) -> str:
    """The message's name (``GIMBAL_DEVICE_ATTITUDE_STATUS``) or ``message <id>``."""
    cls = M.mavlink_map.get(msg_id)
    return getattr(cls, "msgname", None) or f"message {msg_id}"


@dataclass
class _Stream:
    rate_hz: float  # <= 0: off
    sent: float = -math.inf  # last request
    tries: int = 0  # requests since it last arrived (or since it was wanted)
    last_arrival: float = -math.inf
    seen: bool = False  # arrived at least once from this autopilot
    result: int | None = None  # MAV_RESULT of the last acknowledged request
    given_up: bool = False


class StreamWatchdog:
    """Wanted streams (message id -> Hz) and their request bookkeeping; thread-safe.

    ``retry_s``: first wait before asking again (and the shortest "missing" time);
    ``max_tries``: requests for a never-seen stream before giving up.
    """

    def __init__(self, retry_s: float = 2.0, max_tries: int = 3) -> None:
        if retry_s <= 0 or max_tries < 1:
            raise ValueError("retry_s must be positive and max_tries at least 1")
        self.retry_s = retry_s
        self.max_tries = max_tries
        self._streams: dict[int, _Stream] = {}
        self._lock = threading.Lock()

    def want(self, rates_hz: Mapping[int, float], now: float) -> None:
        """Remember ``rates_hz``; an explicit request starts its tries afresh. ``now`` holds
        the watchdog off them while the caller sends the requests itself."""
        with self._lock:
            for msg_id, rate in rates_hz.items():
                s = self._streams.setdefault(int(msg_id), _Stream(float(rate)))
                s.rate_hz = float(rate)
                s.tries = 0
                s.given_up = False
                s.sent = now

    def rate(self, msg_id: int) -> float:
        """The wanted rate (Hz; <= 0 off); 0 for a stream never wanted."""
        with self._lock:
            s = self._streams.get(msg_id)
            return s.rate_hz if s is not None else 0.0

    def sent(self, msg_id: int, now: float) -> None:
        """A request for ``msg_id`` went out at ``now``."""
        with self._lock:
            s = self._streams.get(msg_id)
            if s is not None:
                s.sent = now
                s.tries += 1

    def acknowledged(self, msg_id: int, result: int) -> None:
        """The autopilot answered a request for ``msg_id`` with ``result`` (MAV_RESULT)."""
        with self._lock:
            s = self._streams.get(msg_id)
            if s is not None:
                s.result = int(result)

    def arrived(self, msg_id: int, now: float) -> None:
        """A message ``msg_id`` came from the autopilot."""
        with self._lock:
            s = self._streams.get(msg_id)
            if s is None:
                return
            s.last_arrival = now
            s.seen = True
            s.tries = 0
            back = s.given_up
            s.given_up = False
        if back:
            log.info("%s: arrives after all", message_name(msg_id))

    def due(self, now: float) -> list[int]:
        """Streams to ask for again now (each is counted as sent); gives up on the hopeless."""
        out: list[int] = []
        gave_up: list[tuple[int, int, int | None]] = []
        with self._lock:
            for msg_id, s in self._streams.items():
                if s.rate_hz <= 0 or s.result in _REFUSED or s.given_up:
                    continue
                if now - s.last_arrival <= max(3.0 / s.rate_hz, self.retry_s):
                    continue
                wait = min(self.retry_s * 2 ** max(s.tries - 1, 0), MAX_RETRY_S)
                if now - s.sent < wait:
                    continue
                if not s.seen and s.tries >= self.max_tries:
                    s.given_up = True
                    gave_up.append((msg_id, s.tries, s.result))
                    continue
                s.sent = now
                s.tries += 1
                out.append(msg_id)
        for msg_id, tries, result in gave_up:
            how = (
                "accepted by the autopilot but never sent"
                if result == M.MAV_RESULT_ACCEPTED
                else "never sent"
            )
            log.warning("%s: %s after %d requests; giving up", message_name(msg_id), how, tries)
        return out

    def reset(self) -> None:
        """A new autopilot: forget what the last one sent, answered and was given up on."""
        with self._lock:
            for s in self._streams.values():
                s.sent = -math.inf
                s.tries = 0
                s.last_arrival = -math.inf
                s.seen = False
                s.result = None
                s.given_up = False

    @property
    def given_up(self) -> list[int]:
        """Ids of the streams given up on (wanted, never sent by the autopilot)."""
        with self._lock:
            return sorted(i for i, s in self._streams.items() if s.given_up)
