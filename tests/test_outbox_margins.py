"""The command sender's and the outbox's margins, each probed at its boundary, against a scripted
link (no sockets): 1 + ``retries`` tries with COMMAND_LONG's ``confirmation`` counting them and
staying at 255 (a uint8), COMMAND_ACKs only from the autopilot and addressed to us (or to
everyone, 0), the autopilot's texts of severity WARNING or worse within REASON_WINDOW_S (1 s) of
a refusal and at most MAX_REASONS (3) of them, STATUSTEXT sends at least STATUSTEXT_MIN_GAP_S
(0.05 s) apart and a text's repeats at least its interval apart, the one due first going first,
and a command without an answer kept for later. Times between sends are only bounded below:
a busy machine makes them longer, never shorter."""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest
from conftest import wait_until
from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.mavlink.commands import (
    MAX_REASONS,
    REASON_WINDOW_S,
    STATUSTEXT_MIN_GAP_S,
    CommandSender,
    Outbox,
)
from sarmission.mavlink.outbox_commands import Reposition, StatusText

AUTOPILOT = (1, 1)
US = (1, 191)


class _Sink:
    def __init__(self) -> None:
        self.data = b""

    def write(self, data: bytes) -> None:
        self.data += data


def received(msg: Any, source: tuple[int, int] = AUTOPILOT) -> Any:
    """``msg`` as it arrives from ``source``: encoded, then parsed."""
    sink = _Sink()
    M.MAVLink(sink, srcSystem=source[0], srcComponent=source[1]).send(msg)
    (parsed,) = M.MAVLink(None).parse_buffer(sink.data)
    return parsed


class _Queue:
    def __init__(self, link: ScriptedLink, types, predicate) -> None:
        self.link, self.types, self.predicate = link, set(types), predicate
        self.items: list[Any] = []

    def get(self, timeout: float) -> Any | None:  # answers come with the send: no waiting
        return self.items.pop(0) if self.items else None

    def __enter__(self) -> _Queue:
        self.link.queues.append(self)
        return self

    def __exit__(self, *exc: object) -> None:
        self.link.queues.remove(self)


class ScriptedLink:
    """What CommandSender and Outbox use of a MavlinkLink. ``answer(msg)`` returns what the
    link hears back for each message sent: ``(message, source, arrival offset s)``."""

    autopilot = AUTOPILOT
    target_system, target_component = AUTOPILOT
    source_system, source_component = US
    link_ok = True

    def __init__(self, answer=lambda msg: []) -> None:
        self.answer = answer
        self.mav = M.MAVLink(_Sink(), srcSystem=US[0], srcComponent=US[1])
        self.sent: list[tuple[float, Any]] = []
        self.queues: list[_Queue] = []
        self.subscribers: list[Any] = []
        self._lock = threading.Lock()

    def send(self, msg: Any) -> bool:
        with self._lock:
            self.sent.append((time.monotonic(), msg))
        now = time.monotonic()
        for reply, source, offset in self.answer(msg):
            reply = received(reply, source)
            for callback, types in list(self.subscribers):
                if reply.get_type() in types:
                    callback(reply, now + offset)
            for queue in list(self.queues):
                if reply.get_type() in queue.types and queue.predicate(reply):
                    queue.items.append(reply)
        return True

    def expect(self, types, predicate=None) -> _Queue:
        return _Queue(self, types, predicate or (lambda m: True))

    def subscribe(self, callback, types):
        entry = (callback, set(types))
        self.subscribers.append(entry)
        return lambda: self.subscribers.remove(entry)

    def from_autopilot(self, msg: Any) -> bool:
        return (msg.get_srcSystem(), msg.get_srcComponent()) == self.autopilot

    def silence_s(self) -> float:
        return 0.0

    def sends(self, mtype: str) -> list[tuple[float, Any]]:
        with self._lock:
            return [(t, m) for t, m in self.sent if m.get_type() == mtype]


def ack(command: int, result: int, target=US) -> Any:
    return M.MAVLink_command_ack_message(command, result, 0, 0, *target)


def text(severity: int, words: str) -> Any:
    return M.MAVLink_statustext_message(severity, words.encode(), 0, 0)


def test_retries_and_confirmation_count_up_to_255():
    link = ScriptedLink()  # a silent autopilot
    result = CommandSender(link, retries=3, ack_timeout_s=0.01).command_long(
        M.MAV_CMD_DO_SET_ROI_NONE
    )
    assert not result.accepted and result.no_answer and result.attempts == 4
    assert [m.confirmation for _, m in link.sends("COMMAND_LONG")] == [0, 1, 2, 3]

    link = ScriptedLink()
    result = CommandSender(link, retries=257, ack_timeout_s=0.01).command_long(
        M.MAV_CMD_DO_SET_ROI_NONE
    )
    assert result.attempts == 258
    assert [m.confirmation for _, m in link.sends("COMMAND_LONG")] == [*range(256), 255, 255]


@pytest.mark.parametrize(
    ("source", "target", "ours"),
    [
        (AUTOPILOT, US, True),
        (AUTOPILOT, (0, 0), True),
        (AUTOPILOT, (US[0], 0), True),
        (AUTOPILOT, (0, US[1]), True),
        (AUTOPILOT, (255, 190), False),
        (AUTOPILOT, (US[0], 190), False),
        (AUTOPILOT, (2, US[1]), False),
        ((2, 1), US, False),
        ((1, 154), US, False),
    ],
)
def test_only_the_autopilot_acks_addressed_to_us_count(source, target, ours):
    command = M.MAV_CMD_DO_SET_ROI_NONE
    link = ScriptedLink(lambda msg: [(ack(command, M.MAV_RESULT_ACCEPTED, target), source, 0.0)])
    result = CommandSender(link, retries=1, ack_timeout_s=0.01).command_long(command)
    assert result.accepted is ours
    assert result.attempts == (1 if ours else 2)


def refusal_reason(*texts: tuple[int, str, float], source=AUTOPILOT) -> str:
    """The error of a refused command whose ACK comes with ``texts``: ``(severity, words,
    arrival relative to the ACK in s)``."""
    command = M.MAV_CMD_DO_SET_MODE

    def answer(msg):
        return [(text(sev, words), source, offset) for sev, words, offset in texts] + [
            (ack(command, M.MAV_RESULT_FAILED), AUTOPILOT, 0.0)
        ]

    result = CommandSender(ScriptedLink(answer), retries=0, ack_timeout_s=0.01).command_long(
        command, 1.0
    )
    assert result.result == M.MAV_RESULT_FAILED
    return result.error.split("(", 1)[1].rstrip(")")


def test_reason_texts_within_the_window_around_the_refusal():
    w = M.MAV_SEVERITY_WARNING
    before, after = REASON_WINDOW_S - 0.2, REASON_WINDOW_S + 0.2
    assert refusal_reason(
        (w, "inside before", -before),
        (w, "outside before", -after),
        (w, "inside after", before),
        (w, "outside after", after),
    ) == ("autopilot: 'inside before', 'inside after'")


def test_reason_severity_count_and_sender():
    notice, warning, critical = (
        M.MAV_SEVERITY_NOTICE,
        M.MAV_SEVERITY_WARNING,
        M.MAV_SEVERITY_CRITICAL,
    )
    assert refusal_reason((notice, "chatter", 0.0), (warning, "warned", 0.0)) == (
        "autopilot: 'warned'"
    )
    four = [(critical, f"text {k}", 0.0) for k in range(MAX_REASONS + 1)]
    assert refusal_reason(*four) == "autopilot: " + ", ".join(
        f"'text {k}'" for k in range(MAX_REASONS)
    )
    assert refusal_reason((critical, "a camera", 0.0), source=(1, 100)) == "no reason given"


def make_outbox(link: ScriptedLink, **kwargs) -> tuple[Outbox, list, list, list]:
    delivered, refused, sent = [], [], []
    outbox = Outbox(
        CommandSender(link, retries=0, ack_timeout_s=0.01),
        on_delivered=lambda a, r: delivered.append(a.key),
        on_refused=lambda a, r: refused.append(a.key),
        on_sent=lambda a, r: sent.append(a.key),
        poll_s=0.02,
        **kwargs,
    )
    return outbox, delivered, refused, sent


def test_statustexts_keep_the_least_gap_and_their_interval():
    link = ScriptedLink()
    outbox, _, _, sent = make_outbox(link)

    def next_one(action, result) -> None:  # a new alert the moment the last one went out
        sent.append(action.key)
        if isinstance(action.key, int) and action.key < 3:
            outbox.submit(StatusText(f"alert {action.key + 1}"), key=action.key + 1)

    outbox.set_callbacks(on_sent=next_one)
    try:
        outbox.submit(StatusText("alert 0"), key=0)
        assert wait_until(lambda: len(sent) == 4, 10.0)
        times = [t for t, _ in link.sends("STATUSTEXT")]
        gaps = [b - a for a, b in zip(times, times[1:], strict=False)]
        assert all(g >= STATUSTEXT_MIN_GAP_S - 1e-3 for g in gaps), gaps

        outbox.submit(StatusText("repeated"), key="r", repeats=3, interval_s=0.3)
        assert wait_until(lambda: sent.count("r") == 3, 10.0)
        times = [t for t, m in link.sends("STATUSTEXT") if m.text == "repeated"]
        assert len(times) == 3
        assert all(b - a >= 0.3 - 1e-3 for a, b in zip(times, times[1:], strict=False))
    finally:
        outbox.close()


def test_the_text_due_first_goes_first():
    link = ScriptedLink()
    link.link_ok = False  # both wait; then both are due at once
    outbox, _, _, sent = make_outbox(link)
    try:
        outbox.submit(StatusText("first"), key="a", repeats=2, interval_s=60.0)
        outbox.submit(StatusText("second"), key="b")
        link.link_ok = True
        assert wait_until(lambda: len(sent) == 2, 10.0)
        assert sent == ["a", "b"]  # "a" again only in a minute
    finally:
        outbox.close()


def test_a_command_without_an_answer_stays_and_goes_when_answered():
    answering = threading.Event()
    command = M.MAV_CMD_DO_REPOSITION

    def answer(msg):
        return [(ack(command, M.MAV_RESULT_ACCEPTED), AUTOPILOT, 0.0)] if answering.is_set() else []

    link = ScriptedLink(answer)
    outbox, delivered, refused, _ = make_outbox(link)
    try:
        action = outbox.submit(Reposition(54.17, 7.89, 40.0), key="r")
        assert wait_until(lambda: action.attempts >= 3, 10.0)  # tried again and again
        assert refused == [] and delivered == [] and outbox.pending() == [action]
        answering.set()
        assert wait_until(lambda: delivered == ["r"], 10.0)
        assert refused == [] and outbox.pending() == []
    finally:
        outbox.close()
