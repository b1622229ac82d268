"""``sarmission run --feed``: beyond loopback the console shows a generated token once and the
feed refuses requests without it; ``--feed-token-file`` supplies the token instead."""

from __future__ import annotations

import json
import re
import threading
import urllib.error
import urllib.request
from pathlib import Path

import pytest
import run_scripted
from conftest import free_udp_port, wait_until

TOKEN = "cli-test-token-0123456789abcdefgh"
SMALL = {"name": "feed-cli", "flight.takeoff": False, "camera.width": 320, "camera.height": 180}
SET_ARGS = [a for k, v in SMALL.items() for a in ("--set", f"{k}={json.dumps(v)}")]
FAR_TARGET = "[[1000.0, 1000.0]]"  # never in view: the run only serves the feed
ANNOUNCED = re.compile(r"operator feed on (http://[^/\s]+)/(\?token=(\S+))?")


def status(url: str, token: str | None = None) -> int:
    headers = {"Authorization": f"Bearer {token}"} if token else {}
    request = urllib.request.Request(url, headers=headers)
    try:
        with urllib.request.urlopen(request, timeout=5) as r:
            return r.status
    except urllib.error.HTTPError as e:
        return e.code


class FeedRun:
    """``run --sim --feed FEED`` in a thread, its console captured."""

    def __init__(
        self, tmp_path: Path, capsys: pytest.CaptureFixture[str], feed: str, *extra: str
    ) -> None:
        argv = [
            FAR_TARGET,
            "--connect",
            f"udp:127.0.0.1:{free_udp_port()}",
            "--sim",
            "--sim-fps",
            "5",
            "--alerts-db",
            str(tmp_path / "alerts.db"),
            "--connect-timeout",
            "5",
            "--feed",
            feed,
            *extra,
            "--duration",
            "8",
            *SET_ARGS,
        ]
        self.capsys = capsys
        self.console = ""
        self.outcome: list[int] = []
        self.runner = threading.Thread(target=lambda: self.outcome.append(run_scripted.main(argv)))
        self.runner.start()

    def announced(self) -> re.Match[str]:
        """The console's feed line, once printed."""

        def seen() -> re.Match[str] | None:
            self.console += self.capsys.readouterr().out
            return ANNOUNCED.search(self.console)

        wait_until(lambda: seen() or not self.runner.is_alive(), timeout=30, step=0.1)
        match = seen()
        if match is None:
            self.runner.join(60)
            raise AssertionError(f"no feed line on the console:\n{self.console}")
        return match

    def finish(self) -> str:
        """Wait for the run to end; returns the whole console."""
        self.runner.join(60)
        self.console += self.capsys.readouterr().out
        assert self.outcome == [0], self.console
        return self.console


def test_network_bind_prints_a_generated_token_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = FeedRun(tmp_path, capsys, "0.0.0.0:0")
    match = run.announced()
    base, token = match.group(1), match.group(3)
    port = base.rsplit(":", 1)[1]
    local = f"http://127.0.0.1:{port}"
    try:
        assert token and len(token) >= 32
        assert status(local + "/healthz") == 401
        assert status(local + "/healthz", "wrong" + token) == 401
        assert status(local + "/healthz", token) == 200
        assert status(f"{local}/?token={token}") == 200
    finally:
        console = run.finish()
    assert console.count(token) == 1


def test_token_file_is_required_and_not_printed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "feed.token"
    path.write_text(TOKEN + "\n")
    path.chmod(0o600)
    run = FeedRun(tmp_path, capsys, "127.0.0.1:0", "--feed-token-file", str(path))
    match = run.announced()
    base = match.group(1)
    try:
        assert match.group(2) is None
        assert status(base + "/api/alerts") == 401
        assert status(base + "/api/alerts", TOKEN) == 200
    finally:
        console = run.finish()
    assert TOKEN not in console
