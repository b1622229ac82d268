"""How many and how long: the operator feed's bounds on connections, streams and slow clients.

Each connection costs a thread, so the feed caps connections (and, within them, the streams that
stay open) and answers beyond the cap with a 503 from its accept loop, without a thread. A
request must arrive whole within a deadline (a client sending a byte now and then cannot hold a
thread), and the kernel is told to give up on a peer that stopped acknowledging data (a ground
station that flew out of radio range sends no FIN).
"""

from __future__ import annotations

import io
import json
import socket
import threading
import time

#: Rejected sockets kept half-closed at most, so the client reads the 503 instead of a reset.
_MAX_LINGERING = 256
_LINGER_S = 2.0


class Slots:
    """A counter with a cap: :meth:`take` succeeds while fewer than ``cap`` are held."""

    def __init__(self, cap: int) -> None:
        if cap < 1:
            raise ValueError(f"a cap must be at least 1, got {cap}")
        self.cap = cap
        self._held = 0
        self._lock = threading.Lock()

    @property
    def held(self) -> int:
        """How many are held now."""
        return self._held

    def take(self) -> bool:
        """Hold one if any is free; returns whether it did."""
        with self._lock:
            if self._held >= self.cap:
                return False
            self._held += 1
            return True

    def give(self) -> None:
        """Return one taken by :meth:`take`."""
        with self._lock:
            self._held = max(0, self._held - 1)


class BusyRejecter:
    """Answers connections beyond the cap with ``503`` from the accept loop: the reply is sent
    without blocking, the socket is half-closed and drained by :meth:`reap` (called from the
    server loop) until the client closes or a short linger ends."""

    def __init__(self, message: str) -> None:
        body = json.dumps({"error": message, "status": 503}).encode()
        self._reply = (
            b"HTTP/1.0 503 Service Unavailable\r\nContent-Type: application/json\r\n"
            b"Retry-After: 5\r\nCache-Control: no-store\r\nConnection: close\r\n"
            + f"Content-Length: {len(body)}\r\n\r\n".encode()
            + body
        )
        self._lingering: list[tuple[socket.socket, float]] = []
        self.rejected = 0

    def reject(self, sock: socket.socket) -> None:
        """Send the 503 and keep ``sock`` until :meth:`reap` closes it."""
        self.rejected += 1
        try:
            sock.setblocking(False)
            sock.send(self._reply)
            sock.shutdown(socket.SHUT_WR)
        except OSError:
            sock.close()
            return
        if len(self._lingering) >= _MAX_LINGERING:
            sock.close()
        else:
            self._lingering.append((sock, time.monotonic() + _LINGER_S))

    def reap(self) -> None:
        """Drain the rejected sockets; close those whose client is done or whose linger ended."""
        now = time.monotonic()
        keep = []
        for sock, until in self._lingering:
            if _drained(sock) or now >= until:
                sock.close()
            else:
                keep.append((sock, until))
        self._lingering = keep

    def close(self) -> None:
        """Close every socket still lingering."""
        for sock, _ in self._lingering:
            sock.close()
        self._lingering = []


def _drained(sock: socket.socket) -> bool:
    """Read what ``sock`` has without blocking; True once the peer closed (or it failed)."""
    try:
        while True:
            if not sock.recv(65536):
                return True
    except BlockingIOError:
        return False
    except OSError:
        return True


class RequestTimeout(TimeoutError):
    """The request (line, headers and body) did not arrive within its deadline."""


class DeadlineReader(io.RawIOBase):
    """Reads a socket until a fixed deadline, however the bytes trickle in; afterwards the socket
    keeps ``send_timeout_s`` for writes. Raises :class:`RequestTimeout` past the deadline."""

    def __init__(self, sock: socket.socket, deadline_s: float, send_timeout_s: float) -> None:
        super().__init__()
        self._sock = sock
        self._deadline = time.monotonic() + deadline_s
        self._send_timeout_s = send_timeout_s
        self.expired = False

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: memoryview) -> int:  # type: ignore[override]
        left = self._deadline - time.monotonic()
        if left <= 0:
            self.expired = True
            raise RequestTimeout("the request did not arrive in time")
        self._sock.settimeout(left)
        try:
            return self._sock.recv_into(buffer)
        except TimeoutError:
            self.expired = True
            raise RequestTimeout("the request did not arrive in time") from None
        finally:
            self._sock.settimeout(self._send_timeout_s)


def tune_socket(sock: socket.socket, send_timeout_s: float) -> None:
    """Writes time out after ``send_timeout_s``; on Linux, TCP keepalive probes an idle peer and
    unacknowledged data is given up after the same time, so a vanished client ends its stream."""
    sock.settimeout(send_timeout_s)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
        for name, value in (
            ("TCP_KEEPIDLE", 30),
            ("TCP_KEEPINTVL", 10),
            ("TCP_KEEPCNT", 3),
            ("TCP_USER_TIMEOUT", int(send_timeout_s * 1000)),
        ):
            if hasattr(socket, name):
                sock.setsockopt(socket.IPPROTO_TCP, getattr(socket, name), value)
    except OSError:
        pass
