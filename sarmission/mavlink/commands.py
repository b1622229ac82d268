"""Commands to the autopilot with ACK, retries and timeout; mission upload; an outbox.

:class:`CommandSender` sends one command at a time (a lock serialises callers, so an ACK always
belongs to the command waiting for it):

- COMMAND_INT / COMMAND_LONG: send, wait ``ack_timeout_s`` for a COMMAND_ACK from the autopilot
  with the same ``command``, re-send up to ``retries`` times (COMMAND_LONG with ``confirmation``
  0, 1, 2, ...). MAV_RESULT_IN_PROGRESS extends the wait without re-sending. So a command gets
  an answer or fails within ``(retries + 1) * ack_timeout_s``.
- A refusal carries the autopilot's reason when it gives one: ArduPilot (Copter 4.7 SITL,
  observed) answers a refused arming with MAV_RESULT_FAILED and, a millisecond later, STATUSTEXTs
  of severity CRITICAL ("Arm: Need Position Estimate"); a refused DO_REPOSITION (no EKF origin
  yet, or not in GUIDED without the change-mode flag) gets FAILED / DENIED and no text at all.
  So the autopilot's STATUSTEXTs of severity WARNING or worse that arrive from the command's
  send, at most :data:`REASON_WINDOW_S` before the refusing ACK, until :data:`REASON_WINDOW_S`
  after it, are quoted in the error: "... refused: MAV_RESULT_FAILED (autopilot: 'Arm: ...')",
  else "(no reason given)". A text in that window need not be about the command (ArduPilot
  repeats its "PreArm:" complaints every 30 s); it is quoted as what the autopilot said.
- STATUSTEXT has no acknowledgement. Text is sanitised to ASCII; up to 50 characters go in one
  message; longer text is split in 50-character chunks sharing a non-zero MAVLink 2 ``id`` with
  ``chunk_seq`` 0, 1, ...; a text whose length is a multiple of 50 ends with an empty chunk (the
  end marker); more than ``MAX_STATUSTEXT_CHUNKS`` chunks are truncated (the text ends in "~").
  It does not wait for the command lock: a text goes out while a command waits for its ACK.
- Mission upload (ArduPilot behaviour): item 0 is home and is overwritten by the autopilot, so
  a placeholder goes first; MISSION_COUNT, then answer every MISSION_REQUEST_INT *and*
  MISSION_REQUEST (ArduPilot asks with the latter) with MISSION_ITEM_INT, until MISSION_ACK.
  A silent autopilot gets MISSION_COUNT (before any request) or the last item again, ``retries``
  times.

:class:`Outbox` delivers actions whatever the link does. Commands are tried in order while the
link is up; with no ACK, or the link down, one stays pending and is tried again once the
autopilot is heard again; an explicit refusal (e.g. MAV_RESULT_DENIED) ends it. A STATUSTEXT,
which nothing acknowledges, is instead *sent* ``repeats`` times ``interval_s`` apart (sends wait
while the link is down), on a thread of its own so that repeats never hold up commands, and
never counted as delivered: with independent loss p, n sends reach the autopilot with
probability 1 - p^n (99.2 % for p = 0.3, n = 4). The caller persists actions (alert store) and
learns outcomes from ``on_delivered`` (accepted), ``on_refused`` and ``on_sent`` (one per send),
given to the outbox's constructor or to :meth:`Outbox.set_callbacks`. What it delivers is typed:
one dataclass per kind of command (:mod:`~sarmission.mavlink.outbox_commands`).
"""

from __future__ import annotations

import itertools
import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from sarmission.mavlink.connection import M, MavlinkLink
from sarmission.mavlink.mission_transfer import (
    MissionTransferError,
    WireItem,
    download_mission,
    insert_visits,
)
from sarmission.mavlink.outbox_commands import COMMAND_KINDS, OutboxCommand, StatusText

log = logging.getLogger(__name__)

STATUSTEXT_LEN = 50
MAX_STATUSTEXT_CHUNKS = 4
#: Seconds around a refusing ACK in which the autopilot's STATUSTEXTs are taken as its reason.
REASON_WINDOW_S = 1.0
#: Once a reason has arrived, seconds to wait for more (ArduPilot sends several at once).
REASON_SETTLE_S = 0.2
#: Most autopilot texts quoted in one refusal.
MAX_REASONS = 3
#: Least seconds between two STATUSTEXT sends of the outbox (at most 20 a second: a burst of
#: alerts must not crowd telemetry off a 57600-baud radio).
STATUSTEXT_MIN_GAP_S = 0.05


@dataclass(frozen=True)
class CommandResult:
    """Outcome of one command or upload.

    ``result``: MAV_RESULT (commands) or MAV_MISSION_RESULT (uploads); None when nothing
    answered (or STATUSTEXT, which has no answer: there ``accepted`` means sent).
    ``attempts``: messages sent for it. ``error``: "" when accepted, else a readable reason.
    ``reason``: for a refusal, what the autopilot said about it ("" when it said nothing).
    ``withheld``: never sent, the outbox's gate refused it (``error`` says why).
    """

    name: str
    accepted: bool
    result: int | None
    attempts: int
    error: str = ""
    reason: str = ""
    withheld: bool = False

    @property
    def no_answer(self) -> bool:
        """True when the autopilot did not answer (worth retrying later)."""
        return not self.accepted and self.result is None and not self.withheld


@dataclass(frozen=True)
class MissionItem:
    """One mission item: a MAV_CMD at ``lat``/``lon`` (degrees) and ``alt`` (metres in
    ``frame``, relative to home by default) with params 1-4."""

    command: int
    lat: float
    lon: float
    alt: float
    frame: int = M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    params: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    autocontinue: int = 1


def _wire(item: MissionItem) -> WireItem:
    return WireItem(
        item.frame,
        item.command,
        tuple(float(p) for p in item.params),
        round(item.lat * 1e7),
        round(item.lon * 1e7),
        float(item.alt),
        item.autocontinue,
    )


def _cmd_name(command: int) -> str:
    entry = M.enums["MAV_CMD"].get(command)
    return entry.name if entry is not None else f"MAV_CMD {command}"


def _result_name(enum: str, value: int) -> str:
    entry = M.enums[enum].get(value)
    return entry.name if entry is not None else str(value)


def _printable(text: str | bytes) -> str:
    """An untrusted STATUSTEXT as printable ASCII: NULs end it, anything else odd becomes
    "?", at most :data:`STATUSTEXT_LEN` characters."""
    if isinstance(text, bytes):
        text = text.decode("ascii", "replace")
    text = text.split("\x00", 1)[0]
    return "".join(c if " " <= c <= "~" else "?" for c in text[:STATUSTEXT_LEN]).strip()


class _AutopilotTexts:
    """The autopilot's STATUSTEXTs of severity WARNING or worse, with their arrival times,
    collected while a command is out: what it says about a refusal."""

    def __init__(self, link: MavlinkLink) -> None:
        self._link = link
        self._items: list[tuple[float, str]] = []
        self._cond = threading.Condition()
        self._unsubscribe = link.subscribe(self._on_text, ["STATUSTEXT"])

    def _on_text(self, msg: Any, arrival: float) -> None:
        if not self._link.from_autopilot(msg):
            return
        if not 0 <= int(getattr(msg, "severity", 255)) <= M.MAV_SEVERITY_WARNING:
            return
        text = _printable(getattr(msg, "text", ""))
        if text:
            with self._cond:
                self._items.append((arrival, text))
                self._cond.notify_all()

    def around(self, ack_time: float) -> str:
        """The texts from :data:`REASON_WINDOW_S` before ``ack_time`` until as long after it
        (waiting for them; :data:`REASON_SETTLE_S` after the last one is enough), quoted:
        ``'Arm: Need Position Estimate', 'Arm: Mode requires mission'``; "" for none."""
        deadline = ack_time + REASON_WINDOW_S
        with self._cond:
            while True:
                near = [x for x in self._items if x[0] >= ack_time - REASON_WINDOW_S]
                end = deadline
                if near:
                    end = min(deadline, max(near[-1][0], ack_time) + REASON_SETTLE_S)
                wait = end - time.monotonic()
                if wait <= 0:
                    break
                self._cond.wait(wait)
        texts = list(dict.fromkeys(x[1] for x in near if x[0] <= deadline))
        return ", ".join(f"'{t}'" for t in texts[:MAX_REASONS])

    def close(self) -> None:
        self._unsubscribe()


def _refusal(name: str, what: str, reason: str) -> str:
    """ "NAME refused: WHAT (autopilot: 'reason')" or "... (no reason given)"."""
    said = f"autopilot: {reason}" if reason else "no reason given"
    return f"{name} refused: {what} ({said})"


def _statustext_chunks(text: str) -> list[bytes]:
    data = text.encode("ascii", "replace")
    if len(data) <= STATUSTEXT_LEN:
        return [data]
    limit = STATUSTEXT_LEN * MAX_STATUSTEXT_CHUNKS
    if len(data) > limit:
        data = data[: limit - 1] + b"~"
    chunks = [data[i : i + STATUSTEXT_LEN] for i in range(0, len(data), STATUSTEXT_LEN)]
    if len(chunks[-1]) == STATUSTEXT_LEN and len(chunks) < 256:
        chunks.append(b"")
    return chunks


class CommandSender:
    """Commands over a :class:`MavlinkLink` to its autopilot, ACKed with retries.

    ``retries`` re-sends after the first attempt; ``ack_timeout_s`` per attempt (the mission
    file's ``[actions] retries`` and ``ack_timeout_s``).
    """

    def __init__(self, link: MavlinkLink, retries: int = 3, ack_timeout_s: float = 1.5) -> None:
        if retries < 0 or ack_timeout_s <= 0:
            raise ValueError("retries must be >= 0 and ack_timeout_s > 0")
        self.link = link
        self.retries = retries
        self.ack_timeout_s = ack_timeout_s
        self._lock = threading.Lock()
        self._text_lock = threading.Lock()
        self._text_ids = itertools.cycle(range(1, 65536))

    # -- generic commands --------------------------------------------------------------------
    def command_int(
        self,
        command: int,
        frame: int,
        params: Sequence[float] = (0.0, 0.0, 0.0, 0.0),
        x: int = 0,
        y: int = 0,
        z: float = 0.0,
    ) -> CommandResult:
        """COMMAND_INT with ``params`` 1-4, ``x``/``y`` (degE7 for global frames) and ``z``."""
        p = [float(v) for v in params] + [0.0] * (4 - len(params))

        def encode(attempt: int) -> Any:
            return self.link.mav.command_int_encode(
                self.link.target_system,
                self.link.target_component,
                frame,
                command,
                0,
                0,
                *p[:4],
                int(x),
                int(y),
                float(z),
            )

        return self._run_command(command, encode)

    def command_long(self, command: int, *params: float) -> CommandResult:
        """COMMAND_LONG with up to 7 params; ``confirmation`` counts the re-sends."""
        p = [float(v) for v in params] + [0.0] * (7 - len(params))

        def encode(attempt: int) -> Any:
            return self.link.mav.command_long_encode(
                self.link.target_system,
                self.link.target_component,
                command,
                min(attempt, 255),
                *p[:7],
            )

        return self._run_command(command, encode)

    def _run_command(self, command: int, encode: Callable[[int], Any]) -> CommandResult:
        name = _cmd_name(command)
        if self.link.autopilot is None:
            return CommandResult(name, False, None, 0, "no autopilot detected on the link")
        with (
            self._lock,
            self.link.expect(
                ["COMMAND_ACK"], lambda m: m.command == command and self._for_us(m)
            ) as acks,
        ):
            texts = _AutopilotTexts(self.link)
            try:
                attempts = 0
                for attempt in range(self.retries + 1):
                    attempts += 1
                    self.link.send(encode(attempt))
                    ack = self._wait_ack(acks)
                    if ack is None:
                        continue
                    result = int(ack.result)
                    if result == M.MAV_RESULT_ACCEPTED:
                        return CommandResult(name, True, result, attempts)
                    reason = texts.around(time.monotonic())
                    what = _result_name("MAV_RESULT", result)
                    return CommandResult(
                        name, False, result, attempts, _refusal(name, what, reason), reason
                    )
            finally:
                texts.close()
        total = attempts * self.ack_timeout_s
        return CommandResult(
            name,
            False,
            None,
            attempts,
            f"{name}: no COMMAND_ACK after {attempts} tries ({total:.1f} s)",
        )

    def _wait_ack(self, acks: Any) -> Any | None:
        deadline = time.monotonic() + self.ack_timeout_s
        while True:
            ack = acks.get(deadline - time.monotonic())
            if ack is None:
                return None
            if ack.result == M.MAV_RESULT_IN_PROGRESS:
                deadline = time.monotonic() + self.ack_timeout_s
                continue
            return ack

    def _for_us(self, msg: Any) -> bool:
        if not self.link.from_autopilot(msg):
            return False
        ts = getattr(msg, "target_system", 0)
        tc = getattr(msg, "target_component", 0)
        return ts in (0, self.link.source_system) and tc in (0, self.link.source_component)

    # -- helpers -----------------------------------------------------------------------------
    def reposition(self, lat: float, lon: float, alt: float) -> CommandResult:
        """MAV_CMD_DO_REPOSITION as COMMAND_INT: fly to ``lat``/``lon`` at ``alt`` metres above
        home and hold (frame GLOBAL_RELATIVE_ALT_INT; param1 -1 = default speed; param2
        MAV_DO_REPOSITION_FLAGS_CHANGE_MODE switches to guided; param4 yaw NaN = unchanged)."""
        return self.command_int(
            M.MAV_CMD_DO_REPOSITION,
            M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            (-1.0, float(M.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE), 0.0, math.nan),
            round(lat * 1e7),
            round(lon * 1e7),
            alt,
        )

    def set_roi(self, lat: float, lon: float, alt: float) -> CommandResult:
        """MAV_CMD_DO_SET_ROI_LOCATION as COMMAND_INT: point the camera at ``lat``/``lon``,
        ``alt`` metres above home (frame GLOBAL_RELATIVE_ALT_INT; param1 0 = all gimbals)."""
        return self.command_int(
            M.MAV_CMD_DO_SET_ROI_LOCATION,
            M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            (0.0, 0.0, 0.0, 0.0),
            round(lat * 1e7),
            round(lon * 1e7),
            alt,
        )

    def clear_roi(self) -> CommandResult:
        """MAV_CMD_DO_SET_ROI_NONE as COMMAND_LONG (param1 0 = all gimbals): the camera goes
        back to its mission or mount orientation."""
        return self.command_long(M.MAV_CMD_DO_SET_ROI_NONE, 0.0)

    def statustext(self, text: str, severity: int = M.MAV_SEVERITY_ALERT) -> CommandResult:
        """STATUSTEXT (chunked above 50 characters, see the module docstring). Not sent when
        the link is down; there is no acknowledgement, so "accepted" means sent."""
        if not self.link.link_ok:
            return CommandResult(
                "STATUSTEXT",
                False,
                None,
                0,
                f"link down: autopilot silent for {self.link.silence_s():.1f} s",
            )
        chunks = _statustext_chunks(text)
        with self._text_lock:
            text_id = next(self._text_ids) if len(chunks) > 1 else 0
            ok = True
            for seq, chunk in enumerate(chunks):
                ok &= self.link.send(self.link.mav.statustext_encode(severity, chunk, text_id, seq))
        if not ok:
            return CommandResult("STATUSTEXT", False, None, len(chunks), "transport refused")
        return CommandResult("STATUSTEXT", True, None, len(chunks))

    # -- mission upload ------------------------------------------------------------------------
    def upload_mission(self, items: Sequence[MissionItem]) -> CommandResult:
        """Replace the autopilot's mission with a placeholder home (item 0) and ``items``."""
        home = WireItem(M.MAV_FRAME_GLOBAL_INT, M.MAV_CMD_NAV_WAYPOINT)
        return self.upload_items([home, *(_wire(it) for it in items)])

    def upload_items(
        self, items: Sequence[WireItem], name: str = "MISSION_UPLOAD"
    ) -> CommandResult:
        """Upload ``items`` exactly as given, item 0 (home) included."""
        if self.link.autopilot is None:
            return CommandResult(name, False, None, 0, "no autopilot detected on the link")
        mav = self.link.mav
        ts, tc = self.link.target_system, self.link.target_component
        mtype = M.MAV_MISSION_TYPE_MISSION

        def item_msg(seq: int) -> Any:
            it = items[seq]
            return mav.mission_item_int_encode(
                ts,
                tc,
                seq,
                it.frame,
                it.command,
                0,
                it.autocontinue,
                *it.params,
                it.x,
                it.y,
                float(it.z),
                mtype,
            )

        def count_msg() -> Any:
            return mav.mission_count_encode(ts, tc, len(items), mtype)

        with (
            self._lock,
            self.link.expect(
                ["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"],
                lambda m: self._for_us(m) and getattr(m, "mission_type", 0) == mtype,
            ) as replies,
        ):
            texts = _AutopilotTexts(self.link)
            try:
                return self._upload(name, replies, texts, count_msg, item_msg, len(items))
            finally:
                texts.close()

    def mission_current(self) -> int | None:
        """The mission item the vehicle is flying to (MISSION_CURRENT, asked for with
        MAV_CMD_REQUEST_MESSAGE), None when the autopilot does not say."""
        with self.link.expect(["MISSION_CURRENT"], self.link.from_autopilot) as replies:
            ack = self.command_long(
                M.MAV_CMD_REQUEST_MESSAGE, float(M.MAVLINK_MSG_ID_MISSION_CURRENT)
            )
            if not ack.accepted:
                return None
            msg = replies.get(self.ack_timeout_s)
        return None if msg is None else int(msg.seq)

    def insert_visits(self, visits: Sequence[WireItem]) -> CommandResult:
        """Put ``visits`` into the pilot's mission before the item the vehicle flies to, and
        make the first visit current: download, insert (DO_JUMPs renumbered), upload the whole
        mission, MAV_CMD_DO_SET_MISSION_CURRENT. The pilot's items all stay; after the visits
        the vehicle resumes the survey where it was (in AUTO; in another mode the visits wait
        for AUTO)."""
        name = "MISSION_INSERT"
        if self.link.autopilot is None:
            return CommandResult(name, False, None, 0, "no autopilot detected on the link")
        try:
            with self._lock:
                items = download_mission(self.link, self.ack_timeout_s, self.retries)
        except MissionTransferError as exc:
            return CommandResult(name, False, None, 1, f"{name}: {exc}")
        current = self.mission_current()
        if current is None:
            return CommandResult(
                name, False, None, 1, f"{name}: the autopilot did not say its current mission item"
            )
        at = min(max(1, current), len(items))
        uploaded = self.upload_items(insert_visits(items, at, visits), name)
        if not uploaded.accepted:
            return uploaded
        made_current = self.command_long(M.MAV_CMD_DO_SET_MISSION_CURRENT, float(at))
        if not made_current.accepted:
            return CommandResult(
                name,
                False,
                made_current.result,
                uploaded.attempts + 1,
                f"{name}: visits inserted at item {at}, but {made_current.error}",
                made_current.reason,
            )
        log.info(
            "%d visit(s) inserted before item %d of the pilot's %d", len(visits), at, len(items) - 1
        )
        return CommandResult(name, True, M.MAV_RESULT_ACCEPTED, uploaded.attempts + 1)

    def _upload(
        self,
        name: str,
        replies: Any,
        texts: _AutopilotTexts,
        count_msg: Callable[[], Any],
        item_msg: Callable[[int], Any],
        n_items: int,
    ) -> CommandResult:
        """The upload's exchange, once MISSION_COUNT may go (see :meth:`upload_mission`)."""
        sent = 1
        last: Any = count_msg()
        self.link.send(last)
        silent = 0
        while True:
            reply = replies.get(self.ack_timeout_s)
            if reply is None:
                silent += 1
                if silent > self.retries:
                    return CommandResult(
                        name,
                        False,
                        None,
                        sent,
                        f"{name}: autopilot silent after "
                        f"{silent} timeouts of {self.ack_timeout_s:.1f} s",
                    )
                self.link.send(last)
                sent += 1
                continue
            silent = 0
            if reply.get_type() == "MISSION_ACK":
                if reply.type == M.MAV_MISSION_ACCEPTED:
                    return CommandResult(name, True, int(reply.type), sent)
                reason = texts.around(time.monotonic())
                what = _result_name("MAV_MISSION_RESULT", reply.type)
                return CommandResult(
                    name, False, int(reply.type), sent, _refusal(name, what, reason), reason
                )
            if not 0 <= reply.seq < n_items:
                continue
            last = item_msg(reply.seq)
            self.link.send(last)
            sent += 1


@dataclass(eq=False)
class Action:
    """Something for the outbox: the ``command`` to deliver and ``key``, the caller's id for it
    (e.g. its alert store row), handed back with every outcome.

    ``attempts`` counts tries of a command, and sends of a STATUSTEXT; a STATUSTEXT is sent
    ``repeats`` times, ``interval_s`` apart (``next_at``: ``time.monotonic()`` of its next send).
    """

    command: OutboxCommand
    key: object = None
    created: float = field(default_factory=time.monotonic)
    attempts: int = 0
    last_result: CommandResult | None = None
    repeats: int = 1
    interval_s: float = 1.0
    next_at: float = 0.0

    @property
    def is_text(self) -> bool:
        """A STATUSTEXT: sent ``repeats`` times, never acknowledged."""
        return isinstance(self.command, StatusText)

    @property
    def done(self) -> bool:
        """A STATUSTEXT sent all its repeats (commands: never; they leave by a callback)."""
        return self.is_text and self.attempts >= self.repeats


ActionCallback = Callable[[Action, CommandResult], None]
#: ``gate(command)``: why ``command`` may not go out now ("" when it may).
Gate = Callable[[OutboxCommand], str]


@dataclass(frozen=True)
class OutboxCallbacks:
    """Who hears what became of an action: ``delivered`` (accepted), ``refused`` (refused by
    the autopilot) and ``sent`` (each send of a STATUSTEXT); None: nobody."""

    delivered: ActionCallback | None = None
    refused: ActionCallback | None = None
    sent: ActionCallback | None = None


class Outbox:
    """Delivers :class:`Action` s through a :class:`CommandSender`, surviving link loss.

    Commands: a worker thread tries the oldest pending one whenever the link is up (checked
    every ``poll_s``). Accepted -> ``on_delivered(action, result)``; refused by the autopilot ->
    ``on_refused(action, result)``; no answer or link down -> stays pending.
    STATUSTEXT: a second thread sends each ``statustext_repeats`` times (unless ``submit`` says
    otherwise), ``repeat_interval_s`` apart, the earliest due first, at most one every
    :data:`STATUSTEXT_MIN_GAP_S`, only while the link is up; ``on_sent(action, result)`` after
    each send (``action.attempts`` sends so far; ``action.done`` after the last). The callbacks
    run on the outbox's threads. A ``gate`` (:meth:`set_gate`) is asked right before each
    command goes out (a command queued while the link was down meets the vehicle as it is
    then); one it refuses is not sent: ``on_refused`` with ``result.withheld``.
    """

    def __init__(
        self,
        sender: CommandSender,
        on_delivered: ActionCallback | None = None,
        on_refused: ActionCallback | None = None,
        poll_s: float = 0.2,
        *,
        on_sent: ActionCallback | None = None,
        statustext_repeats: int = 1,
        repeat_interval_s: float = 1.0,
    ) -> None:
        if statustext_repeats < 1 or not repeat_interval_s > 0:
            raise ValueError("statustext_repeats must be >= 1 and repeat_interval_s > 0")
        self.sender = sender
        self._callbacks = OutboxCallbacks(on_delivered, on_refused, on_sent)
        self._gate: Gate | None = None
        self.poll_s = poll_s
        self.statustext_repeats = statustext_repeats
        self.repeat_interval_s = repeat_interval_s
        self._pending: list[Action] = []  # commands, in order
        self._texts: list[Action] = []  # STATUSTEXTs with sends to go
        self._last_text_send = -math.inf
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._text_wake = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="mavlink-outbox", daemon=True)
        self._text_thread = threading.Thread(
            target=self._text_loop, name="mavlink-outbox-text", daemon=True
        )
        self._thread.start()
        self._text_thread.start()

    def set_callbacks(
        self,
        *,
        on_delivered: ActionCallback | None = None,
        on_refused: ActionCallback | None = None,
        on_sent: ActionCallback | None = None,
    ) -> None:
        """Replace who hears the outcomes (one owner, e.g. the action policy, which needs the
        outbox to exist before it can listen to it)."""
        self._callbacks = OutboxCallbacks(on_delivered, on_refused, on_sent)

    def set_gate(self, gate: Gate | None) -> None:
        """Ask ``gate(command)`` before each command is sent; a non-empty answer withholds it."""
        self._gate = gate

    def submit(
        self,
        command: OutboxCommand,
        *,
        key: object = None,
        repeats: int | None = None,
        interval_s: float | None = None,
    ) -> Action:
        """Queue ``command``; returns its :class:`Action` (delivered later). A
        :class:`~sarmission.mavlink.outbox_commands.StatusText` goes out ``repeats`` times
        ``interval_s`` apart (default: the outbox's)."""
        if not isinstance(command, COMMAND_KINDS):
            raise TypeError(f"not an outbox command: {command!r}")
        action = Action(command, key)
        if action.is_text:
            action.repeats = max(1, int(self.statustext_repeats if repeats is None else repeats))
            action.interval_s = self.repeat_interval_s if interval_s is None else interval_s
            with self._lock:
                self._texts.append(action)
            self._text_wake.set()
        else:
            with self._lock:
                self._pending.append(action)
            self._wake.set()
        return action

    def pending(self) -> list[Action]:
        """Actions not yet answered (commands) or not yet sent all their repeats
        (STATUSTEXT), oldest first."""
        with self._lock:
            return sorted(self._pending + self._texts, key=lambda a: a.created)

    # -- commands ----------------------------------------------------------------------------
    def _loop(self) -> None:
        while not self._stop.is_set():
            self._wake.wait(self.poll_s)
            self._wake.clear()
            try:
                self._step()
            except Exception:
                log.exception("outbox step failed")

    def _step(self) -> None:
        link = self.sender.link
        while not self._stop.is_set():
            with self._lock:
                if not self._pending:
                    return
                action = self._pending[0]
            if not link.link_ok:
                return
            why = self._gate(action.command) if self._gate is not None else ""
            if why:
                name = type(action.command).__name__
                result = CommandResult(name, False, None, 0, f"withheld: {why}", why, True)
                self._finish(action, result, self._callbacks.refused)
                continue
            result = action.command.send(self.sender)
            action.attempts += 1
            action.last_result = result
            if result.accepted:
                self._finish(action, result, self._callbacks.delivered)
            elif result.no_answer:
                log.info("outbox: %s not delivered yet (%s)", result.name, result.error)
                return
            else:
                self._finish(action, result, self._callbacks.refused)

    def _finish(self, action: Action, result: CommandResult, cb: ActionCallback | None) -> None:
        # leaves the pending list first: a delivered ROI is no longer "on its way" when its
        # delivery is handled (callers waiting for the outcome wait for the store, not the list)
        with self._lock:
            if action in self._pending:
                self._pending.remove(action)
        self._call(cb, action, result)

    # -- STATUSTEXT --------------------------------------------------------------------------
    def _text_loop(self) -> None:
        while not self._stop.is_set():
            try:
                wait = self._send_due_text()
            except Exception:
                log.exception("outbox text step failed")
                wait = self.poll_s
            if self._text_wake.wait(wait):
                self._text_wake.clear()

    def _send_due_text(self) -> float:
        """Send the STATUSTEXT due first, if any and the link is up; returns how long to wait
        before looking again."""
        now = time.monotonic()
        with self._lock:
            due = min(self._texts, key=lambda a: (a.next_at, a.created), default=None)
        if due is None:
            return self.poll_s
        if due.next_at > now:
            return min(due.next_at - now, self.poll_s)
        if now < self._last_text_send + STATUSTEXT_MIN_GAP_S:
            return self._last_text_send + STATUSTEXT_MIN_GAP_S - now
        if not self.sender.link.link_ok:
            return self.poll_s
        result = due.command.send(self.sender)
        if not result.accepted:  # link lost or transport refused: try again later
            log.info("outbox: STATUSTEXT not sent (%s)", result.error)
            return self.poll_s
        due.attempts += 1
        due.last_result = result
        self._last_text_send = time.monotonic()
        due.next_at = self._last_text_send + due.interval_s
        # recorded before it leaves the pending list: "not pending" means "stored as sent"
        self._call(self._callbacks.sent, due, result)
        if due.done:
            with self._lock:
                if due in self._texts:
                    self._texts.remove(due)
        return STATUSTEXT_MIN_GAP_S

    @staticmethod
    def _call(cb: ActionCallback | None, action: Action, result: CommandResult) -> None:
        if cb is not None:
            try:
                cb(action, result)
            except Exception:
                log.exception("outbox callback failed")

    def close(self) -> None:
        """Stop the workers (pending actions stay in :meth:`pending`)."""
        self._stop.set()
        self._wake.set()
        self._text_wake.set()
        for thread in (self._thread, self._text_thread):
            if thread is not threading.current_thread():
                thread.join(timeout=5.0)
