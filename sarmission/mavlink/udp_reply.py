"""Where a listening UDP link (``udp:``/``udpin:``) sends: to the autopilot, not to everyone.

pymavlink's UDP server sends every outgoing message to every address that ever sent it a
datagram, garbage included: anyone who can reach the port gets a copy of every command and
every alert (with the casualty's position), and each new source port adds one more copy of
everything, for good. :class:`UdpReplyTarget` takes over the connection's ``recv`` and
``write`` so that it sends to one address: that of the adopted autopilot's latest message;
before an autopilot is adopted, that of the latest valid MAVLink message (only messages the
link admitted, so an unsigned sender on a signed link never counts); before any, nowhere.

The autopilot's address is sticky: a message with the autopilot's ids from another address (a
spoofer copying them on an unsigned link) moves the replies only once the address in use has
been silent for ``move_after_s`` (a rebooted autopilot may come back from another port); until
then it is counted in ``contested`` and warned about at most once every few seconds.
"""

from __future__ import annotations

import errno
import logging
from typing import Any

from pymavlink import mavutil

from sarmission.ratelimit import RateLimitedLog

log = logging.getLogger(__name__)

Address = tuple[str, int]


class UdpReplyTarget:
    """Pins the replies of a pymavlink UDP server connection (module docstring)."""

    def __init__(self, conn: Any, move_after_s: float = 3.0) -> None:
        self._conn = conn
        self.move_after_s = move_after_s
        self.datagram_from: Address | None = None  # sender of the datagram read last
        self.valid_from: Address | None = None  # sender of the latest admitted message
        self.autopilot_at: Address | None = None  # where the autopilot's messages come from
        self._autopilot_heard = 0.0  # arrival of its latest message from autopilot_at
        self.unsent = 0  # messages not sent: nobody to send them to yet
        self.contested = 0  # autopilot messages from another address while autopilot_at lives
        self._warn = RateLimitedLog(log)
        conn.recv = self._recv
        conn.write = self._write

    @staticmethod
    def applies_to(conn: Any) -> bool:
        """Whether ``conn`` is a pymavlink UDP connection that listens (``udpin``)."""
        return isinstance(conn, mavutil.mavudp) and bool(getattr(conn, "udp_server", False))

    @property
    def target(self) -> Address | None:
        """Where the next message goes."""
        return self.autopilot_at or self.valid_from

    def admitted(self, from_autopilot: bool, arrival: float) -> None:
        """The message just parsed passed the link's checks; ``from_autopilot``: it carries the
        adopted autopilot's ids; ``arrival``: monotonic seconds. Call on the reader thread,
        right after it was read."""
        address = self.datagram_from
        if address is None:
            return
        self.valid_from = address
        if not from_autopilot:
            return
        if address == self.autopilot_at:
            self._autopilot_heard = arrival
            return
        silent = arrival - self._autopilot_heard
        if self.autopilot_at is not None and silent <= self.move_after_s:
            self.contested += 1
            self._warn.event(
                "contested",
                "autopilot messages from %s:%d ignored for replies: it answers at %s:%d",
                *address,
                *self.autopilot_at,
            )
            return
        if self.autopilot_at is not None:
            log.info(
                "autopilot silent at %s:%d for %.1f s, now heard at %s:%d: replies go there",
                *self.autopilot_at,
                silent,
                *address,
            )
        self.autopilot_at = address
        self._autopilot_heard = arrival

    def autopilot_changed(self) -> None:
        """Another autopilot was adopted: its address is learnt from its next message."""
        self.autopilot_at = None

    def _recv(self, n: int | None = None) -> bytes:
        try:
            data, address = self._conn.port.recvfrom(mavutil.UDP_MAX_PACKET_LEN)
        except OSError as exc:
            if exc.errno in (errno.EAGAIN, errno.EWOULDBLOCK, errno.ECONNREFUSED):
                return b""
            raise
        self.datagram_from = address
        return data

    def _write(self, buf: bytes) -> None:
        target = self.target
        if target is None:
            self.unsent += 1
            return
        try:
            self._conn.port.sendto(buf, target)
        except OSError as exc:
            if exc.errno not in (errno.ECONNREFUSED, errno.EAGAIN, errno.EWOULDBLOCK):
                raise
