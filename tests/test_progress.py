"""Progress of long commands: a bar on a terminal, plain lines in a log, nothing on request."""

from __future__ import annotations

import argparse
import io
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from sarmission.commands.progress import Progress, add_progress_option, progress_mode


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_progress_option(parser)
    return parser.parse_args(list(argv))


def test_the_mode_follows_the_terminal_and_the_option(monkeypatch):
    monkeypatch.setenv("TERM", "xterm")
    assert progress_mode(parse(), Terminal()) == "bar"
    assert progress_mode(parse(), io.StringIO()) == "lines"
    assert progress_mode(parse("--no-progress"), Terminal()) == "off"
    monkeypatch.setenv("TERM", "dumb")
    assert progress_mode(parse(), Terminal()) == "lines"


def test_lines_mode_writes_whole_lines_at_most_once_per_interval():
    log = io.StringIO()
    with Progress("detect", total=4, mode="lines", stream=log, interval_s=0.0) as bar:
        for _ in range(4):
            bar.update(1, dets=7)
    text = log.getvalue()
    assert "\r" not in text
    lines = text.splitlines()
    assert len(lines) == 4 and lines[-1].startswith("detect: 4/4 frames (100%), ")
    assert lines[-1].endswith("frames/s, dets 7")
    quiet = io.StringIO()
    with Progress("detect", total=1000, mode="lines", stream=quiet, interval_s=3600.0) as bar:
        for _ in range(1000):
            bar.update(1)
    assert quiet.getvalue() == ""  # nothing before the interval has passed


def test_bar_mode_draws_a_tqdm_bar_and_off_draws_nothing(capsys):
    screen = Terminal()
    with Progress("train", total=3, unit="batch", mode="bar", stream=screen) as bar:
        bar.update(3)
        bar.write("epoch 1 done")
    assert "train" in screen.getvalue() and "3/3" in screen.getvalue()
    assert capsys.readouterr().out == "epoch 1 done\n"
    silent = io.StringIO()
    with Progress("x", total=3, mode="off", stream=silent) as bar:
        bar.update(3)
    assert silent.getvalue() == ""


@pytest.fixture(scope="module")
def clip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("video") / "clip.mp4"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 30, (320, 240))
    rng = np.random.default_rng(0)
    for _ in range(8):
        writer.write(rng.integers(0, 256, (240, 320, 3), dtype=np.uint8))
    writer.release()
    return path


def test_a_command_writing_into_a_pipe_draws_no_bar(clip: Path, tmp_path: Path):
    """stderr to a file or pipe (a CI log): no tqdm redraws; --no-progress: nothing at all."""
    base = [
        sys.executable,
        "-m",
        "sarmission.cli",
        "detect",
        str(clip),
        "--out",
        str(tmp_path / "d.json"),
    ]
    piped = subprocess.run(base, capture_output=True, text=True, timeout=300)
    assert piped.returncode == 0, piped.stderr
    assert "\r" not in piped.stderr and "it/s" not in piped.stderr
    silent = subprocess.run(base + ["--no-progress"], capture_output=True, text=True, timeout=300)
    assert silent.returncode == 0 and silent.stderr == ""
    assert silent.stdout.startswith("8 frames, ")


@pytest.mark.parametrize(
    "command",
    [
        ["detect", "x.mp4"],
        ["replay", "x.mp4"],
        ["eval", "--annotations", "a.json"],
        ["train", "--train", "a.json", "--val", "b.json", "--out", "h.pt"],
        ["sim", "generate", "--out", "d"],
        ["bench"],
    ],
)
def test_every_long_command_takes_no_progress(command: list[str]):
    from sarmission.cli import build_parser

    assert build_parser().parse_args(command + ["--no-progress"]).no_progress is True
