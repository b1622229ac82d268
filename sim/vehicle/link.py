"""The simulated vehicle's MAVLink connection and clock, shared by its parts.

Every message the vehicle sends goes through :meth:`VehicleLink.send`, which counts it by name
and shrugs off a client that went away; the sim clock runs ``speedup`` times wall time.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from sarmission.mavlink.connection import mavlink2_connection

log = logging.getLogger(__name__)


class VehicleLink:
    """One pymavlink connection as system ``system_id``/``component_id`` plus the sim clock.

    ``sim_time() = (monotonic() - start) * speedup`` seconds since :meth:`open` (0 before).
    """

    def __init__(self, url: str, system_id: int, component_id: int, speedup: float) -> None:
        self.url = url
        self.system_id = system_id
        self.component_id = component_id
        self.speedup = speedup
        self.conn: Any = None
        self.sent_counts: dict[str, int] = {}
        self._started = threading.Event()
        self._mono0 = 0.0
        self._unix0 = 0.0

    def open(self) -> None:
        """Open the connection and start the clock."""
        self.conn = mavlink2_connection(self.url, self.system_id, self.component_id)
        self._mono0 = time.monotonic()
        self._unix0 = time.time()
        self._started.set()

    def close(self) -> None:
        """Close the connection (the clock keeps running)."""
        if self.conn is not None:
            try:
                self.conn.close()
            except OSError:
                pass
            self.conn = None

    @property
    def mav(self) -> Any:
        """The connection's MAVLink encoder (its ``*_send`` methods)."""
        return self.conn.mav

    def sim_time(self) -> float:
        """Seconds of simulated flight since :meth:`open` (0 before)."""
        if not self._started.is_set():
            return 0.0
        return (time.monotonic() - self._mono0) * self.speedup

    def unix_us(self, t: float) -> int:
        """Unix time in microseconds of sim time ``t``."""
        return int((self._unix0 + t) * 1e6)

    def send(self, kind: str, fn: Callable[..., Any], *args: Any) -> None:
        """Call ``fn(*args)`` (a ``mav.*_send``) and count one ``kind`` sent; a send the OS
        refuses is logged, not raised."""
        if self.conn is None:
            return
        try:
            fn(*args)
            self.sent_counts[kind] = self.sent_counts.get(kind, 0) + 1
        except OSError as exc:  # e.g. ICMP port unreachable from a client that went away
            log.debug("send %s failed: %s", kind, exc)
