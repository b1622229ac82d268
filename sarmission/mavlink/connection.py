"""One MAVLink 2 link to the autopilot: reader thread, heartbeat, streams, link health, signing.

``MavlinkLink(url)`` opens any pymavlink connection string (``udp:``/``udpin:``, ``udpout:``,
``tcp:``, serial devices) and speaks MAVLink 2 with the ardupilotmega dialect (a superset of
common). It runs two daemon threads:

- reader: parses every byte, counts malformed input (``bad_packets``) and messages refused by
  signing (``rejected_signatures``) and skips them, detects the autopilot (the first HEARTBEAT
  whose ``autopilot`` is not MAV_AUTOPILOT_INVALID and whose ``type`` is not a GCS), keeps the
  time it was last heard, and hands every message to the subscribers
  (``callback(msg, arrival)``, ``arrival`` = ``time.monotonic()``).
- housekeeping (5 Hz): our HEARTBEAT at 1 Hz as MAV_TYPE_ONBOARD_CONTROLLER /
  MAV_AUTOPILOT_INVALID, and the stream watchdog: every message asked for with
  :meth:`MavlinkLink.request_streams` that has not arrived for ``max(3 periods, 2 s)`` is asked
  for again (fire and forget, at most every 2 s), unless the autopilot refused it. This covers
  ArduPilot, which sends only HEARTBEAT until asked with MAV_CMD_SET_MESSAGE_INTERVAL, lost
  requests, and an autopilot reboot.

Sends from several threads are serialised by a lock (the MAVLink sequence number and signing
timestamp are per connection). With ``signing_key`` (32 bytes) outgoing messages are signed and
incoming ones must carry a valid signature (unsigned ones too, unless ``allow_unsigned``).
"""

from __future__ import annotations

import hashlib
import logging
import math
import queue
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

log = logging.getLogger(__name__)

M = mavlink2
MAV_COMP_ID_ONBOARD_COMPUTER = M.MAV_COMP_ID_ONBOARD_COMPUTER
Callback = Callable[[Any, float], None]

STREAM_RETRY_S = 2.0
HOUSEKEEPING_PERIOD_S = 0.2
_REFUSED = (M.MAV_RESULT_DENIED, M.MAV_RESULT_UNSUPPORTED)


def signing_key_from_passphrase(passphrase: str) -> bytes:
    """The 32-byte MAVLink 2 signing key ``sha256(passphrase)`` (as MAVProxy derives it)."""
    return hashlib.sha256(passphrase.encode("utf-8")).digest()


class MessageQueue:
    """Messages of some types (and matching a predicate) collected from a link, for waiting.

    Register before sending the request so an early reply cannot be missed; use as a context
    manager (or call :meth:`close`) to unsubscribe.
    """

    def __init__(
        self, link: MavlinkLink, types: Iterable[str], predicate: Callable[[Any], bool] | None
    ) -> None:
        self._queue: queue.Queue[Any] = queue.Queue()
        self._predicate = predicate
        self._unsubscribe = link.subscribe(self._on_message, types)

    def _on_message(self, msg: Any, arrival: float) -> None:
        if self._predicate is None or self._predicate(msg):
            self._queue.put(msg)

    def get(self, timeout: float) -> Any | None:
        """The next matching message, or None after ``timeout`` seconds."""
        try:
            return self._queue.get(timeout=max(0.0, timeout))
        except queue.Empty:
            return None

    def close(self) -> None:
        self._unsubscribe()

    def __enter__(self) -> MessageQueue:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def mavlink2_connection(url: str, source_system: int, source_component: int) -> Any:
    """A pymavlink connection for ``url`` that always speaks MAVLink 2 (ardupilotmega dialect).

    pymavlink picks its wire protocol from process-wide state; this replaces the connection's
    codec with a MAVLink 2 one so MAVLink 2-only messages (e.g. GIMBAL_DEVICE_ATTITUDE_STATUS,
    id 285) can be sent and parsed whatever the rest of the process uses. An address that cannot
    be opened raises ``OSError`` naming the URL.
    """
    try:
        conn = mavutil.mavlink_connection(
            url, source_system=source_system, source_component=source_component
        )
    except OSError as exc:
        raise OSError(f"cannot open MAVLink connection {url!r}: {exc.strerror or exc}") from exc
    conn.mav = mavlink2.MAVLink(conn, srcSystem=source_system, srcComponent=source_component)
    conn.mav.robust_parsing = True
    conn.WIRE_PROTOCOL_VERSION = "2.0"
    conn.first_byte = False
    return conn


class MavlinkLink:
    """A MAVLink 2 connection of a companion component to one autopilot.

    ``url``: pymavlink connection string. ``source_system``/``source_component``: our ids (the
    vehicle's system id and MAV_COMP_ID_ONBOARD_COMPUTER by default). ``signing_key``: 32-byte
    MAVLink 2 key or None. ``link_timeout_s``: the link is down when the autopilot has not been
    heard for longer. The link starts on construction; :meth:`close` stops it.
    """

    def __init__(
        self,
        url: str,
        source_system: int = 1,
        source_component: int = MAV_COMP_ID_ONBOARD_COMPUTER,
        signing_key: bytes | None = None,
        *,
        link_timeout_s: float = 3.0,
        allow_unsigned: bool = False,
    ) -> None:
        self.url = url
        self.source_system = source_system
        self.source_component = source_component
        self.link_timeout_s = link_timeout_s
        self.bad_packets = 0
        self.rejected_signatures = 0
        self.received = 0
        self.autopilot: tuple[int, int] | None = None
        self._autopilot_seen = threading.Event()
        self._last_heard: float | None = None
        self._last_by_type: dict[int, float] = {}
        self._streams: dict[int, float] = {}  # msg id -> rate Hz (<= 0: off)
        self._stream_sent: dict[int, float] = {}
        self._stream_result: dict[int, int] = {}
        self._subscribers: list[tuple[Callback, frozenset[str] | None]] = []
        self._sub_lock = threading.Lock()
        self._send_lock = threading.Lock()
        self._stop = threading.Event()
        self._conn = mavlink2_connection(url, source_system, source_component)
        if signing_key is not None:
            if len(signing_key) != 32:
                raise ValueError(f"signing key must be 32 bytes, got {len(signing_key)}")
            self._conn.setup_signing(
                bytes(signing_key),
                sign_outgoing=True,
                allow_unsigned_callback=(lambda mav, msg_id: True) if allow_unsigned else None,
            )
        self._next_heartbeat = 0.0
        self._reader = threading.Thread(target=self._read_loop, name="mavlink-reader", daemon=True)
        self._keeper = threading.Thread(
            target=self._housekeeping_loop, name="mavlink-housekeeping", daemon=True
        )
        self._reader.start()
        self._keeper.start()

    # -- public state ------------------------------------------------------------------------
    @property
    def mav(self) -> Any:
        """The pymavlink MAVLink object: use its ``*_encode`` methods and :meth:`send`."""
        return self._conn.mav

    @property
    def target_system(self) -> int:
        """The autopilot's system id (the vehicle's; 1 before detection)."""
        return self.autopilot[0] if self.autopilot else 1

    @property
    def target_component(self) -> int:
        """The autopilot's component id (1 before detection)."""
        return self.autopilot[1] if self.autopilot else 1

    @property
    def last_heard(self) -> float | None:
        """``time.monotonic()`` of the last message from the autopilot (None: never)."""
        return self._last_heard

    def silence_s(self) -> float:
        """Seconds since the autopilot was last heard (inf if never)."""
        last = self._last_heard
        return math.inf if last is None else time.monotonic() - last

    @property
    def link_ok(self) -> bool:
        """The autopilot is known and was heard within ``link_timeout_s``."""
        return self.autopilot is not None and self.silence_s() <= self.link_timeout_s

    def wait_autopilot(self, timeout: float) -> bool:
        """Block until the autopilot's HEARTBEAT was seen (True) or ``timeout`` passed."""
        return self._autopilot_seen.wait(timeout)

    @property
    def signing_stats(self) -> dict[str, int]:
        """pymavlink signing counters (good/bad signatures, unsigned accepted, rejected)."""
        s = self._conn.mav.signing
        return {
            "goodsig": s.goodsig_count,
            "badsig": s.badsig_count,
            "unsigned": s.unsigned_count,
            "reject": s.reject_count,
        }

    # -- subscribe / send --------------------------------------------------------------------
    def subscribe(
        self, callback: Callback, types: Iterable[str] | None = None
    ) -> Callable[[], None]:
        """Call ``callback(msg, arrival)`` from the reader thread for every message of ``types``
        (message type names; None = all). Returns a function that unsubscribes."""
        entry = (callback, None if types is None else frozenset(types))
        with self._sub_lock:
            self._subscribers.append(entry)

        def unsubscribe() -> None:
            with self._sub_lock:
                if entry in self._subscribers:
                    self._subscribers.remove(entry)

        return unsubscribe

    def expect(
        self, types: Iterable[str], predicate: Callable[[Any], bool] | None = None
    ) -> MessageQueue:
        """A :class:`MessageQueue` of future messages of ``types`` matching ``predicate``."""
        return MessageQueue(self, types, predicate)

    def from_autopilot(self, msg: Any) -> bool:
        """True when ``msg`` was sent by the detected autopilot."""
        return self.autopilot == (msg.get_srcSystem(), msg.get_srcComponent())

    def send(self, msg: Any) -> bool:
        """Send an encoded message (``link.mav.xxx_encode(...)``); False if the OS refused."""
        with self._send_lock:
            try:
                self._conn.mav.send(msg)
                return True
            except OSError as exc:
                log.debug("send %s failed: %s", msg.get_type(), exc)
                return False

    # -- streams -----------------------------------------------------------------------------
    def request_streams(
        self, rates_hz: Mapping[int, float], timeout_s: float = 1.0
    ) -> dict[int, int | None]:
        """Ask the autopilot for messages (id -> Hz; <= 0 stops one) with
        MAV_CMD_SET_MESSAGE_INTERVAL (param1 id, param2 interval us = 1e6 / rate, -1 = off).

        Waits up to ``timeout_s`` for the autopilot, then sends the requests one by one and
        waits up to ``timeout_s`` for each COMMAND_ACK. Returns id -> MAV_RESULT (None: no ACK
        yet). The rates are remembered and re-requested by the watchdog while missing.
        """
        self._streams.update({int(k): float(v) for k, v in rates_hz.items()})
        results: dict[int, int | None] = {int(k): None for k in rates_hz}
        now = time.monotonic()
        self._stream_sent.update({k: now for k in results})  # keep the watchdog off them for now
        if not self.wait_autopilot(timeout_s):
            return results
        for msg_id in results:
            with self.expect(
                ["COMMAND_ACK"],
                lambda m: m.command == M.MAV_CMD_SET_MESSAGE_INTERVAL and self.from_autopilot(m),
            ) as acks:
                self._send_stream_request(msg_id)
                ack = acks.get(timeout_s)
            if ack is not None:
                results[msg_id] = int(ack.result)
                self._stream_result[msg_id] = int(ack.result)
        return results

    def _send_stream_request(self, msg_id: int) -> None:
        rate = self._streams[msg_id]
        interval_us = 1e6 / rate if rate > 0 else -1.0
        self._stream_sent[msg_id] = time.monotonic()
        self.send(
            self.mav.command_long_encode(
                self.target_system,
                self.target_component,
                M.MAV_CMD_SET_MESSAGE_INTERVAL,
                0,
                float(msg_id),
                interval_us,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
            )
        )

    def _stream_watchdog(self, now: float) -> None:
        if self.autopilot is None:
            return
        for msg_id, rate in list(self._streams.items()):
            if rate <= 0 or self._stream_result.get(msg_id) in _REFUSED:
                continue
            if now - self._stream_sent.get(msg_id, -math.inf) < STREAM_RETRY_S:
                continue
            last = self._last_by_type.get(msg_id, -math.inf)
            if now - last > max(3.0 / rate, 2.0):
                self._send_stream_request(msg_id)

    # -- threads -----------------------------------------------------------------------------
    def _read_loop(self) -> None:
        while not self._stop.is_set():
            try:
                msg = self._conn.recv_match(blocking=True, timeout=0.1)
            except OSError as exc:
                if self._stop.is_set():
                    return
                log.debug("read failed: %s", exc)
                time.sleep(0.05)
                continue
            except Exception:  # pymavlink raises assorted errors on garbage; never die on them
                self.bad_packets += 1
                log.debug("undecodable input", exc_info=True)
                continue
            if msg is not None:
                self._on_message(msg, time.monotonic())

    def _on_message(self, msg: Any, arrival: float) -> None:
        mtype = msg.get_type()
        if mtype == "BAD_DATA":
            if "signature" in str(getattr(msg, "reason", "")).lower():
                self.rejected_signatures += 1
            else:
                self.bad_packets += 1
            return
        self.received += 1
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        if (
            self.autopilot is None
            and mtype == "HEARTBEAT"
            and msg.autopilot != M.MAV_AUTOPILOT_INVALID
            and msg.type != M.MAV_TYPE_GCS
        ):
            self.autopilot = src
            self._autopilot_seen.set()
            log.info("autopilot %d/%d (type %d) on %s", src[0], src[1], msg.type, self.url)
        if src == self.autopilot:
            self._last_heard = arrival
            self._last_by_type[msg.get_msgId()] = arrival
        with self._sub_lock:
            subscribers = list(self._subscribers)
        for callback, types in subscribers:
            if types is None or mtype in types:
                try:
                    callback(msg, arrival)
                except Exception:
                    log.exception("subscriber failed on %s", mtype)

    def _housekeeping_loop(self) -> None:
        while not self._stop.wait(HOUSEKEEPING_PERIOD_S):
            now = time.monotonic()
            if now >= self._next_heartbeat:
                self._next_heartbeat = now + 1.0
                self.send(
                    self.mav.heartbeat_encode(
                        M.MAV_TYPE_ONBOARD_CONTROLLER,
                        M.MAV_AUTOPILOT_INVALID,
                        0,
                        0,
                        M.MAV_STATE_ACTIVE,
                    )
                )
            self._stream_watchdog(now)

    # -- lifecycle ---------------------------------------------------------------------------
    def close(self) -> None:
        """Stop both threads and close the transport (idempotent)."""
        if self._stop.is_set():
            return
        self._stop.set()
        for thread in (self._keeper, self._reader):
            if thread is not threading.current_thread():
                thread.join(timeout=2.0)
        try:
            self._conn.close()
        except OSError:
            pass

    def __enter__(self) -> MavlinkLink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
