"""The frame-size parser every ``--size`` option shares, and the free loopback port."""

from __future__ import annotations

import socket

import pytest

from sarmission.cli import main
from sarmission.commands.cli_helpers import (
    MAX_FRAME_SIDE,
    MIN_FRAME_SIDE,
    FrameSizeError,
    free_udp_port,
    parse_frame_size,
)


@pytest.mark.parametrize(
    "text, size",
    [
        ("960x540", (960, 540)),
        ("3840X2160", (3840, 2160)),
        (f"{MIN_FRAME_SIDE}x{MIN_FRAME_SIDE}", (MIN_FRAME_SIDE, MIN_FRAME_SIDE)),
        (f"{MAX_FRAME_SIDE}x{MIN_FRAME_SIDE}", (MAX_FRAME_SIDE, MIN_FRAME_SIDE)),
    ],
)
def test_a_size_is_read_as_width_and_height(text: str, size: tuple[int, int]) -> None:
    assert parse_frame_size(text) == size


@pytest.mark.parametrize(
    "text",
    [
        "",
        "big",
        "960",
        "960x",
        "x540",
        "960x540x3",
        "960.5x540",
        "960,540",
        f"{MIN_FRAME_SIDE - 1}x540",
        f"960x{MIN_FRAME_SIDE - 1}",
        "0x0",
        "-960x540",
        f"{MAX_FRAME_SIDE + 1}x540",
        "99999999x99999999",
    ],
)
def test_anything_else_is_refused_with_the_one_message(text: str) -> None:
    with pytest.raises(FrameSizeError) as error:
        parse_frame_size(text)
    assert str(error.value) == (
        f"expected a frame size WIDTHxHEIGHT with sides {MIN_FRAME_SIDE} to {MAX_FRAME_SIDE} px "
        f"(e.g. 960x540), got {text!r}"
    )
    assert isinstance(error.value, ValueError)  # the CLI's one-line error for direct callers


@pytest.mark.parametrize(
    "argv",
    [
        ["info", "--size", "20x20"],
        ["bench", "--size", "20x20"],
        ["demo", "--size", "20x20"],
        ["sim", "generate", "--size", "20x20", "--out", "unused"],
        ["run", "--connect", "udp:127.0.0.1:9", "--sim", "--sim-size", "20x20"],
    ],
)
def test_every_size_option_refuses_alike(
    argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "expected a frame size WIDTHxHEIGHT with sides" in err and "'20x20'" in err


def test_the_free_port_can_be_bound() -> None:
    port = free_udp_port()
    assert 0 < port < 65536
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", port))
