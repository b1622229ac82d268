"""Commands to the autopilot with ACK, retries and timeout; mission upload; an outbox.

:class:`CommandSender` sends one thing at a time (a lock serialises callers, so an ACK always
belongs to the command waiting for it):

- COMMAND_INT / COMMAND_LONG: send, wait ``ack_timeout_s`` for a COMMAND_ACK from the autopilot
  with the same ``command``, re-send up to ``retries`` times (COMMAND_LONG with ``confirmation``
  0, 1, 2, ...). MAV_RESULT_IN_PROGRESS extends the wait without re-sending. So a command gets
  an answer or fails within ``(retries + 1) * ack_timeout_s``.
- STATUSTEXT has no acknowledgement. Text is sanitised to ASCII; up to 50 characters go in one
  message; longer text is split in 50-character chunks sharing a non-zero MAVLink 2 ``id`` with
  ``chunk_seq`` 0, 1, ...; a text whose length is a multiple of 50 ends with an empty chunk (the
  end marker); more than ``MAX_STATUSTEXT_CHUNKS`` chunks are truncated (the text ends in "~").
- Mission upload (ArduPilot behaviour): item 0 is home and is overwritten by the autopilot, so
  a placeholder goes first; MISSION_COUNT, then answer every MISSION_REQUEST_INT *and*
  MISSION_REQUEST (ArduPilot asks with the latter) with MISSION_ITEM_INT, until MISSION_ACK.
  A silent autopilot gets MISSION_COUNT (before any request) or the last item again, ``retries``
  times.

:class:`Outbox` delivers actions whatever the link does: an action is tried when the link is up;
if the link is down, or no ACK came, it stays pending and is tried again (in order) once the
autopilot is heard again. A STATUSTEXT counts as delivered when the autopilot is heard at least
``STATUSTEXT_CONFIRM_S`` after it was sent; if the link is lost first, it is sent again. An
explicit refusal (e.g. MAV_RESULT_DENIED) ends the action. The caller persists actions (alert
store) and learns the outcome from the ``on_delivered`` / ``on_refused`` callbacks.
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

log = logging.getLogger(__name__)

STATUSTEXT_LEN = 50
MAX_STATUSTEXT_CHUNKS = 4
STATUSTEXT_CONFIRM_S = 0.3


@dataclass(frozen=True)
class CommandResult:
    """Outcome of one command or upload.

    ``result``: MAV_RESULT (commands) or MAV_MISSION_RESULT (uploads); None when nothing
    answered (or STATUSTEXT, which has no answer). ``attempts``: messages sent for it.
    ``error``: "" when accepted, else a readable reason.
    """

    name: str
    accepted: bool
    result: int | None
    attempts: int
    error: str = ""

    @property
    def no_answer(self) -> bool:
        """True when the autopilot did not answer (worth retrying later)."""
        return not self.accepted and self.result is None


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


def _cmd_name(command: int) -> str:
    entry = M.enums["MAV_CMD"].get(command)
    return entry.name if entry is not None else f"MAV_CMD {command}"


def _result_name(enum: str, value: int) -> str:
    entry = M.enums[enum].get(value)
    return entry.name if entry is not None else str(value)


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
                return CommandResult(
                    name,
                    False,
                    result,
                    attempts,
                    f"{name} refused: {_result_name('MAV_RESULT', result)}",
                )
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
        with self._lock:
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
        name = "MISSION_UPLOAD"
        if self.link.autopilot is None:
            return CommandResult(name, False, None, 0, "no autopilot detected on the link")
        home = MissionItem(M.MAV_CMD_NAV_WAYPOINT, 0.0, 0.0, 0.0, frame=M.MAV_FRAME_GLOBAL_INT)
        all_items = [home, *items]
        mav = self.link.mav
        ts, tc = self.link.target_system, self.link.target_component
        mtype = M.MAV_MISSION_TYPE_MISSION

        def item_msg(seq: int) -> Any:
            it = all_items[seq]
            return mav.mission_item_int_encode(
                ts,
                tc,
                seq,
                it.frame,
                it.command,
                0,
                it.autocontinue,
                *it.params,
                round(it.lat * 1e7),
                round(it.lon * 1e7),
                float(it.alt),
                mtype,
            )

        def count_msg() -> Any:
            return mav.mission_count_encode(ts, tc, len(all_items), mtype)

        with (
            self._lock,
            self.link.expect(
                ["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"],
                lambda m: self._for_us(m) and getattr(m, "mission_type", 0) == mtype,
            ) as replies,
        ):
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
                    return CommandResult(
                        name,
                        False,
                        int(reply.type),
                        sent,
                        f"{name} refused: {_result_name('MAV_MISSION_RESULT', reply.type)}",
                    )
                if not 0 <= reply.seq < len(all_items):
                    continue
                last = item_msg(reply.seq)
                self.link.send(last)
                sent += 1


@dataclass(eq=False)
class Action:
    """Something for the outbox: ``kind`` is a :class:`CommandSender` method name
    ("statustext", "reposition", "set_roi", "upload_mission", "command_int", "command_long")
    called with ``args``. ``key`` is the caller's id (e.g. its alert store row)."""

    kind: str
    args: tuple[Any, ...]
    key: Any = None
    created: float = field(default_factory=time.monotonic)
    attempts: int = 0
    last_result: CommandResult | None = None
    sent_at: float | None = None  # STATUSTEXT sent, waiting to hear the autopilot after it


ActionCallback = Callable[[Action, CommandResult], None]


class Outbox:
    """Delivers :class:`Action` s in order through a :class:`CommandSender`, surviving link loss.

    A worker thread tries the oldest pending action whenever the link is up (checked every
    ``poll_s``). Outcomes: accepted -> ``on_delivered(action, result)``; refused by the
    autopilot -> ``on_refused(action, result)``; no answer or link down -> stays pending.
    """

    def __init__(
        self,
        sender: CommandSender,
        on_delivered: ActionCallback | None = None,
        on_refused: ActionCallback | None = None,
        poll_s: float = 0.2,
    ) -> None:
        self.sender = sender
        self.on_delivered = on_delivered
        self.on_refused = on_refused
        self.poll_s = poll_s
        self._pending: list[Action] = []
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="mavlink-outbox", daemon=True)
        self._thread.start()

    def submit(self, kind: str, *args: Any, key: Any = None) -> Action:
        """Queue ``sender.<kind>(*args)``; returns the :class:`Action` (delivered later)."""
        if kind not in (
            "statustext",
            "reposition",
            "set_roi",
            "clear_roi",
            "upload_mission",
            "command_int",
            "command_long",
        ):
            raise ValueError(f"unknown action kind {kind!r}")
        action = Action(kind, tuple(args), key)
        with self._lock:
            self._pending.append(action)
        self._wake.set()
        return action

    def pending(self) -> list[Action]:
        """Actions not yet delivered or refused, oldest first."""
        with self._lock:
            return list(self._pending)

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
            if action.sent_at is not None:  # a STATUSTEXT waiting for proof the link was up
                heard = link.last_heard
                if heard is not None and heard >= action.sent_at + STATUSTEXT_CONFIRM_S:
                    assert action.last_result is not None
                    self._finish(action, action.last_result, self.on_delivered)
                    continue
                if link.link_ok:
                    return  # wait a little longer
                action.sent_at = None  # link lost right after sending: send again
            if not link.link_ok:
                return
            result: CommandResult = getattr(self.sender, action.kind)(*action.args)
            action.attempts += 1
            action.last_result = result
            if result.accepted and action.kind == "statustext":
                action.sent_at = time.monotonic()
                return
            if result.accepted:
                self._finish(action, result, self.on_delivered)
            elif result.no_answer:
                log.info("outbox: %s not delivered yet (%s)", action.kind, result.error)
                return
            else:
                self._finish(action, result, self.on_refused)

    def _finish(self, action: Action, result: CommandResult, cb: ActionCallback | None) -> None:
        with self._lock:
            if action in self._pending:
                self._pending.remove(action)
        if cb is not None:
            try:
                cb(action, result)
            except Exception:
                log.exception("outbox callback failed")

    def close(self) -> None:
        """Stop the worker (pending actions stay in :meth:`pending`)."""
        self._stop.set()
        self._wake.set()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
