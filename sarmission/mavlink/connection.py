"""One MAVLink 2 link to the autopilot: reader thread, heartbeat, adoption, streams, signing.

``MavlinkLink(url)`` opens any pymavlink connection string (``udp:``/``udpin:``, ``udpout:``,
``tcp:``, serial devices) and speaks MAVLink 2 with the ardupilotmega dialect (a superset of
common). It runs two daemon threads:

- reader: parses every byte, counts malformed input (``bad_packets``) and skips it; with signing,
  drops what fails the signature rules (:mod:`sarmission.mavlink.signing`); adopts one autopilot
  (:mod:`sarmission.mavlink.adoption`: the first autopilot-type HEARTBEAT, or the pinned
  ``target_system``/``target_component``; another one only after the adopted one fell silent),
  keeps the time it was last heard, and hands messages to the subscribers
  (``callback(msg, arrival)``, ``arrival`` = ``time.monotonic()``): :meth:`MavlinkLink.subscribe`
  gets every message, :meth:`MavlinkLink.subscribe_autopilot` only the adopted autopilot's (and
  its system's gimbals' attitude); what that filter drops is counted in ``ignored``.
- housekeeping (5 Hz): our HEARTBEAT at 1 Hz as MAV_TYPE_ONBOARD_CONTROLLER /
  MAV_AUTOPILOT_INVALID, and, while the autopilot is heard, the stream watchdog
  (:mod:`sarmission.mavlink.streams`): a message asked for with
  :meth:`MavlinkLink.request_streams` that stays missing is asked for again with backoff, and
  given up when it never came after a few requests. This covers ArduPilot, which sends only
  HEARTBEAT until asked with MAV_CMD_SET_MESSAGE_INTERVAL, lost requests, and a reboot.

Sends from several threads are serialised by a lock (the MAVLink sequence number and signing
timestamp are per connection). A link listening on UDP (``udp:``/``udpin:``) sends to the
adopted autopilot's address alone, not to everyone who sent it a datagram
(:mod:`sarmission.mavlink.udp_reply`). With ``signing_key`` (32 bytes) outgoing messages are
signed and incoming ones must carry a valid signature (unsigned ones too, unless
``allow_unsigned``).
"""

from __future__ import annotations

import hashlib
import logging
import math
import queue
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sarmission.mavlink.adoption import (
    GIMBAL_TYPES,
    SYSTEM_SWITCH_S,
    Adoption,
    AdoptionChange,
    Source,
    is_autopilot_heartbeat,
    source_kind,
)
from sarmission.mavlink.signing import SignatureGate, enable_signing
from sarmission.mavlink.streams import StreamWatchdog
from sarmission.mavlink.udp_reply import UdpReplyTarget

log = logging.getLogger(__name__)

M = mavlink2
MAV_COMP_ID_ONBOARD_COMPUTER = M.MAV_COMP_ID_ONBOARD_COMPUTER
Callback = Callable[[Any, float], None]
#: ``callback(new, old)``: autopilot ``new`` adopted, replacing ``old`` (None the first time).
AdoptedCallback = Callable[[Source, Source | None], None]

STREAM_RETRY_S = 2.0
STREAM_MAX_TRIES = 3
HOUSEKEEPING_PERIOD_S = 0.2
#: Seconds between two warnings about messages ignored from one sender.
IGNORED_WARN_S = 5.0


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


@dataclass(frozen=True, eq=False)
class _Subscription:
    callback: Callback
    types: frozenset[str] | None  # None: all
    gimbal_types: frozenset[str]  # also from the adopted system's gimbals (autopilot_only)
    autopilot_only: bool


class MavlinkLink:
    """A MAVLink 2 connection of a companion component to one autopilot.

    ``url``: pymavlink connection string. ``source_system``/``source_component``: our ids (the
    vehicle's system id and MAV_COMP_ID_ONBOARD_COMPUTER by default). ``signing_key``: 32-byte
    MAVLink 2 key or None. ``link_timeout_s``: the link is down when the autopilot has not been
    heard for longer (and only then may another autopilot of its system be adopted; one of
    another system only after ``system_switch_s``). ``target_system`` /
    ``target_component``: pin the autopilot (None: any). ``stream_retry_s`` /
    ``stream_max_tries``: the stream watchdog's first retry wait and the requests made for a
    stream that never comes. The link starts on construction; :meth:`close` stops it.
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
        target_system: int | None = None,
        target_component: int | None = None,
        stream_retry_s: float = STREAM_RETRY_S,
        stream_max_tries: int = STREAM_MAX_TRIES,
        system_switch_s: float = SYSTEM_SWITCH_S,
    ) -> None:
        self.url = url
        self.source_system = source_system
        self.source_component = source_component
        self.link_timeout_s = link_timeout_s
        self.bad_packets = 0
        self.received = 0
        #: Messages dropped by the autopilot source filter, by (system, component, type); the
        #: reader thread adds to it: copy it (``dict(link.ignored)``) before iterating.
        self.ignored: Counter[tuple[int, int, str]] = Counter()
        self._adoption = Adoption(
            link_timeout_s, target_system, target_component, f" on {url}", system_switch_s
        )
        self._autopilot_seen = threading.Event()
        self._streams = StreamWatchdog(stream_retry_s, stream_max_tries)
        self._subscribers: list[_Subscription] = []
        self._adopted_callbacks: list[AdoptedCallback] = []
        self._ignored_warned: dict[Source, float] = {}
        self._sub_lock = threading.Lock()
        self._send_lock = threading.Lock()
        self._stop = threading.Event()
        self._conn = mavlink2_connection(url, source_system, source_component)
        #: Listening on UDP: replies to the autopilot alone (:mod:`sarmission.mavlink.udp_reply`).
        self.replies = (
            UdpReplyTarget(self._conn, move_after_s=link_timeout_s)
            if UdpReplyTarget.applies_to(self._conn)
            else None
        )
        self._gate: SignatureGate | None = None
        if signing_key is not None:
            try:
                check = enable_signing(self._conn, signing_key)
            except ValueError:
                self._conn.close()
                raise
            self._gate = SignatureGate(check, allow_unsigned)
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
    def autopilot(self) -> Source | None:
        """The adopted autopilot's (system, component), None before one was heard."""
        return self._adoption.adopted

    @property
    def adoptions(self) -> int:
        """How many times an autopilot was adopted (1 after the first; each re-adoption adds
        one): a generation number for data that belongs to one autopilot."""
        return self._adoption.adoptions

    @property
    def target_system(self) -> int:
        """The adopted autopilot's system id (before: the pinned one, else 1)."""
        if self.autopilot is not None:
            return self.autopilot[0]
        pinned = self._adoption.target_system
        return 1 if pinned is None else pinned

    @property
    def target_component(self) -> int:
        """The adopted autopilot's component id (before: the pinned one, else 1)."""
        if self.autopilot is not None:
            return self.autopilot[1]
        pinned = self._adoption.target_component
        return 1 if pinned is None else pinned

    @property
    def last_heard(self) -> float | None:
        """``time.monotonic()`` of the last message from the autopilot (None: never)."""
        return self._adoption.last_heard

    def silence_s(self) -> float:
        """Seconds since the autopilot was last heard (inf if never)."""
        return self._adoption.silence_s(time.monotonic())

    @property
    def link_ok(self) -> bool:
        """The autopilot is known and was heard within ``link_timeout_s``."""
        return self.autopilot is not None and self.silence_s() <= self.link_timeout_s

    def wait_autopilot(self, timeout: float) -> bool:
        """Block until an autopilot was adopted (True) or ``timeout`` passed."""
        return self._autopilot_seen.wait(timeout)

    def other_autopilots(self) -> list[Source]:
        """Autopilot-type senders besides the adopted one heard within ``link_timeout_s``."""
        return self._adoption.rivals(time.monotonic())

    @property
    def streams_given_up(self) -> list[int]:
        """Message ids asked for that the autopilot never sent; no longer asked for."""
        return self._streams.given_up

    @property
    def bad_signatures(self) -> int:
        """Signed messages refused: signature wrong (another key, forged) or replayed."""
        return self._gate.bad_signatures if self._gate is not None else 0

    @property
    def unsigned_rejected(self) -> int:
        """Unsigned messages refused because signing is on."""
        return self._gate.unsigned_rejected if self._gate is not None else 0

    @property
    def rejected_signatures(self) -> int:
        """Messages refused by signing (bad signature or unsigned)."""
        return self.bad_signatures + self.unsigned_rejected

    @property
    def signing_stats(self) -> dict[str, int]:
        """Signing counters: good signatures, bad ones, unsigned accepted, messages rejected."""
        gate = self._gate
        if gate is None:
            return {"goodsig": 0, "badsig": 0, "unsigned": 0, "reject": 0}
        return {
            "goodsig": gate.accepted_signed,
            "badsig": gate.bad_signatures,
            "unsigned": gate.accepted_unsigned,
            "reject": gate.bad_signatures + gate.unsigned_rejected,
        }

    def diagnosis(self) -> str | None:
        """Why no autopilot is usable on this link, in one line; None while the link is ok.

        Signing problems come first ("autopilot 1/1 sends unsigned messages: signing is not
        enabled on the autopilot"), then an autopilot left out by the pin, then silence."""
        if self.link_ok:
            return None
        if self._gate is not None:
            since = -math.inf if self.last_heard is None else self.last_heard
            why = self._gate.diagnosis(since)
            if why:
                return why
        now = time.monotonic()
        pinned_out = [s for s in self._adoption.rivals(now) if not self._adoption.eligible(s)]
        if self.autopilot is None and pinned_out:
            others = ", ".join(f"{s[0]}/{s[1]}" for s in pinned_out)
            return (
                f"autopilot {others} heard, but the link is pinned to {self._adoption.pin_text()}"
            )
        if self.autopilot is not None:
            return (
                f"autopilot {self.autopilot[0]}/{self.autopilot[1]} silent for "
                f"{self.silence_s():.1f} s"
            )
        return f"no autopilot heard on {self.url}"

    # -- subscribe / send --------------------------------------------------------------------
    def subscribe(
        self, callback: Callback, types: Iterable[str] | None = None
    ) -> Callable[[], None]:
        """Call ``callback(msg, arrival)`` from the reader thread for every message of ``types``
        (message type names; None = all) from any sender. Returns a function that unsubscribes."""
        return self._add(_Subscription(callback, _types(types), frozenset(), False))

    def subscribe_autopilot(
        self,
        callback: Callback,
        types: Iterable[str] | None = None,
        gimbal_types: Iterable[str] = GIMBAL_TYPES,
    ) -> Callable[[], None]:
        """Like :meth:`subscribe`, but only messages from the adopted autopilot; those of
        ``gimbal_types`` (default GIMBAL_DEVICE_ATTITUDE_STATUS, MOUNT_ORIENTATION) also from
        a gimbal component of its system. Others of these types are dropped and counted in
        ``ignored``. Returns a function that unsubscribes."""
        return self._add(_Subscription(callback, _types(types), frozenset(gimbal_types), True))

    def on_adopted(self, callback: AdoptedCallback) -> Callable[[], None]:
        """Call ``callback(new, old)`` from the reader thread when an autopilot is adopted
        (``old`` None the first time), before its HEARTBEAT reaches the subscribers: data from
        ``old`` should be dropped. Returns a function that unsubscribes."""
        with self._sub_lock:
            self._adopted_callbacks.append(callback)

        def unsubscribe() -> None:
            with self._sub_lock:
                if callback in self._adopted_callbacks:
                    self._adopted_callbacks.remove(callback)

        return unsubscribe

    def _add(self, entry: _Subscription) -> Callable[[], None]:
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
        """True when ``msg`` was sent by the adopted autopilot."""
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
        yet). The rates are remembered and the watchdog asks again while one is missing.
        """
        results: dict[int, int | None] = {int(k): None for k in rates_hz}
        self._streams.want({int(k): float(v) for k, v in rates_hz.items()}, time.monotonic())
        if not self.wait_autopilot(timeout_s):
            return results
        for msg_id in results:
            with self.expect(
                ["COMMAND_ACK"],
                lambda m: m.command == M.MAV_CMD_SET_MESSAGE_INTERVAL and self.from_autopilot(m),
            ) as acks:
                self._streams.sent(msg_id, time.monotonic())
                self._send_stream_request(msg_id)
                ack = acks.get(timeout_s)
            if ack is not None:
                results[msg_id] = int(ack.result)
                self._streams.acknowledged(msg_id, int(ack.result))
        return results

    def _send_stream_request(self, msg_id: int) -> None:
        rate = self._streams.rate(msg_id)
        interval_us = 1e6 / rate if rate > 0 else -1.0
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
                try:
                    self._on_message(msg, time.monotonic())
                except Exception:  # a message our bookkeeping chokes on must not stop the link
                    self.bad_packets += 1
                    log.debug("message not handled", exc_info=True)

    def _on_message(self, msg: Any, arrival: float) -> None:
        mtype = msg.get_type()
        if mtype == "BAD_DATA":
            self.bad_packets += 1
            return
        if self._gate is not None and not self._gate.admit(msg, arrival):
            return
        self.received += 1
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        if mtype == "HEARTBEAT" and is_autopilot_heartbeat(msg):
            change = self._adoption.heartbeat(src, arrival)
            if change is not None:
                self._adopted(change)
        if src == self.autopilot:
            self._adoption.heard(src, arrival)
            self._streams.arrived(msg.get_msgId(), arrival)
        if self.replies is not None:
            self.replies.admitted(src == self.autopilot, arrival)
        self._dispatch(msg, mtype, src, arrival)

    def _adopted(self, change: AdoptionChange) -> None:
        if change.old is not None:
            self._streams.reset()  # the new one knows nothing of our requests
            if self.replies is not None:
                self.replies.autopilot_changed()
        self._autopilot_seen.set()
        with self._sub_lock:
            callbacks = list(self._adopted_callbacks)
        for callback in callbacks:
            try:
                callback(change.new, change.old)
            except Exception:
                log.exception("adoption callback failed")

    def _dispatch(self, msg: Any, mtype: str, src: Source, arrival: float) -> None:
        with self._sub_lock:
            subscribers = list(self._subscribers)
        kind = source_kind(src, self.autopilot)
        ignored = False
        for sub in subscribers:
            if sub.autopilot_only:
                if mtype in sub.gimbal_types:
                    wanted = kind != "foreign"
                elif sub.types is None or mtype in sub.types:
                    wanted = kind == "autopilot"
                else:
                    continue
                if not wanted:
                    ignored = True
                    continue
            elif sub.types is not None and mtype not in sub.types:
                continue
            try:
                sub.callback(msg, arrival)
            except Exception:
                log.exception("subscriber failed on %s", mtype)
        if ignored:
            self._ignore(mtype, src, arrival)

    def _ignore(self, mtype: str, src: Source, arrival: float) -> None:
        self.ignored[(src[0], src[1], mtype)] += 1
        last = self._ignored_warned.get(src)
        if last is not None and arrival - last < IGNORED_WARN_S:
            return
        self._ignored_warned[src] = arrival
        count = sum(n for (s, c, _), n in self.ignored.items() if (s, c) == src)
        adopted = self.autopilot
        if adopted is None:
            log.info(
                "ignoring %s from %d/%d: no autopilot adopted yet (%d ignored from it)",
                mtype,
                *src,
                count,
            )
        else:
            log.warning(
                "ignoring %s from %d/%d: not autopilot %d/%d (%d ignored from it)",
                mtype,
                *src,
                *adopted,
                count,
            )

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
            if self.link_ok:
                for msg_id in self._streams.due(now):
                    self._send_stream_request(msg_id)

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


def _types(types: Iterable[str] | None) -> frozenset[str] | None:
    return None if types is None else frozenset(types)
