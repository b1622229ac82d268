"""Command edge cases over real UDP on 127.0.0.1: MAV_RESULT_IN_PROGRESS and STATUSTEXT
chunking at its boundaries (49, 50, 51, 100, 200 and 260 characters)."""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest
from conftest import free_udp_port, wait_until
from link_peers import RawPeer
from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.mavlink.commands import CommandSender
from sarmission.mavlink.connection import MavlinkLink


class BusyAutopilot(RawPeer):
    """Answers every command other than stream requests with MAV_RESULT_IN_PROGRESS every
    0.1 s for ``busy_s`` seconds, then with ``final``."""

    def __init__(self, port: int, busy_s: float, final: int) -> None:
        self.busy_s = busy_s
        self.final = final
        super().__init__(port, system=1)

    def _on_command(self, msg: Any) -> None:
        if msg.command == M.MAV_CMD_SET_MESSAGE_INTERVAL:
            return
        threading.Thread(target=self._answer, args=(msg,), daemon=True).start()

    def _answer(self, msg: Any) -> None:
        end = time.monotonic() + self.busy_s
        while time.monotonic() < end:
            self._ack(msg, M.MAV_RESULT_IN_PROGRESS)
            time.sleep(0.1)
        self._ack(msg, self.final)

    def _ack(self, msg: Any, result: int) -> None:
        self.send(
            self.conn.mav.command_ack_encode(
                msg.command, result, 50, 0, msg.get_srcSystem(), msg.get_srcComponent()
            )
        )

    def commands(self, command: int) -> list[Any]:
        return [
            m
            for m in list(self.received)
            if m.get_type() == "COMMAND_LONG" and m.command == command
        ]


@pytest.mark.parametrize("final", [M.MAV_RESULT_ACCEPTED, M.MAV_RESULT_DENIED])
def test_in_progress_extends_the_wait_without_resending(final):
    """IN_PROGRESS answers for 2.5 s, longer than the 1 s ACK timeout: the command waits for the
    final answer, sent once, and reports that answer (not IN_PROGRESS)."""
    port = free_udp_port()
    with MavlinkLink(f"udpin:127.0.0.1:{port}") as link:
        peer = BusyAutopilot(port, busy_s=2.5, final=final)
        try:
            assert link.wait_autopilot(10.0)
            sender = CommandSender(link, retries=0, ack_timeout_s=1.0)
            result = sender.command_long(M.MAV_CMD_DO_SET_ROI_NONE)
            assert result.result == final
            assert result.accepted is (final == M.MAV_RESULT_ACCEPTED)
            assert result.attempts == 1
            assert len(peer.commands(M.MAV_CMD_DO_SET_ROI_NONE)) == 1
        finally:
            peer.close()


class TextListener(RawPeer):
    """An autopilot that keeps every STATUSTEXT it receives."""

    def texts(self) -> list[Any]:
        return [m for m in list(self.received) if m.get_type() == "STATUSTEXT"]


@pytest.fixture()
def text_link():
    port = free_udp_port()
    with MavlinkLink(f"udpin:127.0.0.1:{port}") as link:
        peer = TextListener(port, system=1)
        try:
            assert link.wait_autopilot(10.0)
            yield CommandSender(link), peer
        finally:
            peer.close()


def letters(n: int) -> str:
    """``n`` distinct-looking characters, so that a shifted chunk cannot match by chance."""
    return "".join("ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789"[i % 36] for i in range(n))


@pytest.mark.parametrize(
    ("length", "chunk_lengths"),
    [
        (49, [49]),
        (50, [50]),  # one message holds 50 characters: no id, no end marker
        (51, [50, 1]),
        (100, [50, 50, 0]),  # a multiple of 50 ends with an empty chunk
        (120, [50, 50, 20]),
        (200, [50, 50, 50, 50, 0]),
        (260, [50, 50, 50, 50, 0]),  # truncated to 200 characters, the last one "~"
    ],
)
def test_statustext_chunks(text_link, length, chunk_lengths):
    sender, peer = text_link
    text = letters(length)
    result = sender.statustext(text)
    assert result.accepted and result.attempts == len(chunk_lengths)
    assert wait_until(lambda: len(peer.texts()) >= len(chunk_lengths), 10.0)
    time.sleep(0.2)  # nothing more may follow
    chunks = peer.texts()
    assert [len(m.text) for m in chunks] == chunk_lengths
    assert [m.chunk_seq for m in chunks] == list(range(len(chunks)))
    ids = {m.id for m in chunks}
    assert len(ids) == 1
    assert (ids.pop() != 0) is (len(chunks) > 1)
    joined = "".join(m.text for m in chunks)
    assert joined == (text if length <= 200 else text[:199] + "~")
