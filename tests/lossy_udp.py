"""A lossy UDP relay for tests: loses, duplicates, delays and reorders MAVLink datagrams.

It sits between a client (the companion's link, ``udpout:127.0.0.1:<proxy.port>``) and a server
(a vehicle listening with ``udpin:127.0.0.1:<target_port>``), both ways. Each datagram is
dropped with probability ``loss``; a kept one is sent twice with probability ``duplicate`` (the
copies back to back, as a radio or router repeats a packet), held ``delay_s`` or, with
probability ``late``, ``late_delay_s`` (so later datagrams overtake it).

Every decision is a seeded hash of the datagram's MAVLink content without its sequence number
and checksum, and of how many times that content passed before in that direction: independent
draws per datagram, yet the n-th copy of one message meets the same fate for a seed whatever
the threads' timing, so a seeded test is reproducible.
"""

from __future__ import annotations

import hashlib
import heapq
import itertools
import select
import socket
import threading
import time
from collections import Counter
from dataclasses import dataclass, field

UP = "up"  # client -> server
DOWN = "down"  # server -> client
_MAVLINK2_SIGNED = 0x01


def mavlink_content(data: bytes) -> bytes:
    """A MAVLink datagram without its sequence number, checksum and signature (what stays
    the same when the same message is sent again)."""
    if len(data) >= 12 and data[0] == 0xFD:
        tail = 15 if data[2] & _MAVLINK2_SIGNED else 2
        return data[:4] + data[5:-tail]
    if len(data) >= 8 and data[0] == 0xFE:
        return data[:2] + data[3:-2]
    return data


@dataclass
class Impairment:
    """What the relay does to datagrams (probabilities per datagram; delays in seconds)."""

    loss: float = 0.3
    duplicate: float = 0.1
    delay_s: tuple[float, float] = (0.0, 0.005)
    late: float = 0.2
    late_delay_s: tuple[float, float] = (0.02, 0.08)


@dataclass
class DirectionStats:
    """Datagrams seen, dropped, duplicated and held late in one direction."""

    received: int = 0
    dropped: int = 0
    duplicated: int = 0
    late: int = 0
    forwarded: int = 0
    seen: Counter = field(default_factory=Counter)

    @property
    def loss_rate(self) -> float:
        return self.dropped / self.received if self.received else 0.0


class LossyUdpProxy:
    """The relay on 127.0.0.1: clients send to :attr:`port`; it forwards to ``target_port``
    and answers the client that sent last. Use as a context manager or start()/stop()."""

    def __init__(self, target_port: int, seed: int, impairment: Impairment | None = None) -> None:
        self.target = ("127.0.0.1", target_port)
        self.seed = seed
        self.impairment = impairment or Impairment()
        self.front = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.front.bind(("127.0.0.1", 0))
        self.back = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.back.bind(("127.0.0.1", 0))
        for s in (self.front, self.back):
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        self.port = int(self.front.getsockname()[1])
        self.stats = {UP: DirectionStats(), DOWN: DirectionStats()}
        self._client: tuple[str, int] | None = None
        self._queue: list[tuple[float, int, socket.socket, bytes, tuple[str, int]]] = []
        self._order = itertools.count()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="lossy-udp", daemon=True)

    def start(self) -> LossyUdpProxy:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5.0)
        self.front.close()
        self.back.close()

    def __enter__(self) -> LossyUdpProxy:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def idle(self) -> bool:
        """No datagram is held for later."""
        return not self._queue

    def _draws(self, direction: str, data: bytes) -> list[float]:
        stats = self.stats[direction]
        content = mavlink_content(data)
        copy = stats.seen[content]
        stats.seen[content] += 1
        digest = hashlib.sha256(f"{self.seed}|{direction}|{copy}|".encode() + content).digest()
        return [int.from_bytes(digest[i : i + 4], "big") / 2**32 for i in range(0, 20, 4)]

    def _schedule(
        self, direction: str, data: bytes, sock: socket.socket, to: tuple[str, int]
    ) -> None:
        imp, stats = self.impairment, self.stats[direction]
        stats.received += 1
        u_loss, u_dup, u_late, u_delay, _ = self._draws(direction, data)
        if u_loss < imp.loss:
            stats.dropped += 1
            return
        lo, hi = imp.late_delay_s if u_late < imp.late else imp.delay_s
        stats.late += u_late < imp.late
        due = time.monotonic() + lo + (hi - lo) * u_delay
        copies = 2 if u_dup < imp.duplicate else 1
        stats.duplicated += copies - 1
        for _ in range(copies):  # equal due times keep the copies back to back
            heapq.heappush(self._queue, (due, next(self._order), sock, data, to))

    def _run(self) -> None:
        while not self._stop.is_set():
            now = time.monotonic()
            while self._queue and self._queue[0][0] <= now:
                _, _, sock, data, to = heapq.heappop(self._queue)
                try:
                    sock.sendto(data, to)
                    self.stats[UP if sock is self.back else DOWN].forwarded += 1
                except OSError:
                    pass
            wait = min(0.01, self._queue[0][0] - now) if self._queue else 0.01
            readable, _, _ = select.select([self.front, self.back], [], [], max(wait, 0.0))
            for sock in readable:
                try:
                    data, addr = sock.recvfrom(65535)
                except OSError:
                    continue
                if sock is self.front:
                    self._client = addr
                    self._schedule(UP, data, self.back, self.target)
                elif self._client is not None:
                    self._schedule(DOWN, data, self.front, self._client)
