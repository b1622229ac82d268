"""Progress of the long commands: a bar on a terminal, a line now and then in a log, or nothing.

A tqdm bar redraws itself many times a second; written to a file or a pipe (a CI log, a
``systemd`` journal, ``2> run.log``) every redraw stays, megabytes of them. So a command shows a
bar only when stderr is a terminal; otherwise :class:`Progress` writes one plain line every
:data:`LINE_INTERVAL_S` seconds (``detect: 120/300 frames (40%), 9.8 frames/s``), and
``--no-progress`` silences both. Library code that draws its own tqdm bars (evaluation, training,
the simulator's renderer) is asked for one only when :func:`bars_wanted` says so.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from typing import Any, Literal, TextIO

Mode = Literal["bar", "lines", "off"]
#: Seconds between two progress lines when stderr is not a terminal.
LINE_INTERVAL_S = 30.0


def add_progress_option(parser: argparse.ArgumentParser) -> None:
    """``--no-progress``."""
    parser.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress display (default: a bar on a terminal, a line every "
        f"{LINE_INTERVAL_S:.0f} s otherwise)",
    )


def progress_mode(args: argparse.Namespace | None = None, stream: TextIO | None = None) -> Mode:
    """``off`` with ``--no-progress``, ``bar`` when ``stream`` (stderr) is a terminal, else
    ``lines``."""
    if args is not None and getattr(args, "no_progress", False):
        return "off"
    stream = stream or sys.stderr
    try:
        interactive = stream.isatty() and os.environ.get("TERM") != "dumb"
    except (AttributeError, ValueError):  # a closed or replaced stream
        interactive = False
    return "bar" if interactive else "lines"


def bars_wanted(args: argparse.Namespace | None = None) -> bool:
    """Whether library code may draw its own tqdm bar (only on a terminal)."""
    return progress_mode(args) == "bar"


class Progress:
    """Progress of one loop over ``total`` items (None: unknown), shown per ``mode``.

    ``update(n, **info)`` after each item (``info`` shows beside the count), ``write(line)``
    for a console line that must not break the bar, ``close()`` (or a ``with`` block) at the end.
    """

    def __init__(
        self,
        desc: str,
        total: int | None = None,
        unit: str = "frame",
        mode: Mode = "lines",
        stream: TextIO | None = None,
        interval_s: float = LINE_INTERVAL_S,
    ) -> None:
        self.desc, self.total, self.unit, self.mode = desc, total, unit, mode
        self.stream = stream or sys.stderr
        self.interval_s = interval_s
        self.n = 0
        self._info: dict[str, Any] = {}
        self._start = self._last_line = time.monotonic()
        self._bar = None
        if mode == "bar":
            from tqdm import tqdm

            self._bar = tqdm(
                total=total, desc=desc, unit=unit, file=self.stream, dynamic_ncols=True
            )

    def update(self, n: int = 1, **info: Any) -> None:
        """``n`` more items done; ``info`` (e.g. ``dets=12``) is shown with the count."""
        self.n += n
        if info:
            self._info.update(info)
        if self._bar is not None:
            self._bar.update(n)
            if info:
                self._bar.set_postfix(self._info, refresh=False)
        elif self.mode == "lines":
            now = time.monotonic()
            if now - self._last_line >= self.interval_s:
                self._last_line = now
                print(self._line(now), file=self.stream, flush=True)

    def _line(self, now: float) -> str:
        elapsed = max(now - self._start, 1e-9)
        count = f"{self.n}/{self.total}" if self.total else f"{self.n}"
        share = f" ({100 * self.n / self.total:.0f}%)" if self.total else ""
        info = "".join(f", {k} {v}" for k, v in self._info.items())
        return (
            f"{self.desc}: {count} {self.unit}s{share}, {self.n / elapsed:.1f} {self.unit}s/s{info}"
        )

    def write(self, line: str) -> None:
        """Print ``line`` on stdout without breaking the bar."""
        if self._bar is not None:
            self._bar.write(line, file=sys.stdout)
        else:
            print(line, flush=True)

    def close(self) -> None:
        """End the display (the bar stays on screen with its final count)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def progress_for(
    args: argparse.Namespace | None, desc: str, total: int | None = None, unit: str = "frame"
) -> Progress:
    """A :class:`Progress` in the mode the command line and the terminal ask for."""
    return Progress(desc, total, unit, progress_mode(args))
