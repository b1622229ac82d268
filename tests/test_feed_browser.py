"""The operator page in a real headless Chromium: a new alert appears within a second of
``store.add`` and the Acknowledge button acknowledges it in the store.

Chromium is driven over the Chrome DevTools Protocol on ``--remote-debugging-pipe`` (JSON
messages separated by NUL bytes on file descriptors 3 and 4), so no client library is needed.
A screenshot of the page is written to ``/tmp/sarmission_feed.png``.
"""

from __future__ import annotations

import base64
import json
import os
import select
import socket
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from alert_samples import make_alert

from sarmission.alerts.feed import FeedServer
from sarmission.alerts.store import AlertStore

CHROMIUM = Path("/usr/bin/chromium")
TOKEN = "browser-test-token-0123456789abcdef"
SCREENSHOT = Path("/tmp/sarmission_feed.png")

pytestmark = pytest.mark.skipif(
    not CHROMIUM.exists(),
    reason="needs /usr/bin/chromium (apt-get install -y chromium chromium-driver)",
)


class Chromium:
    """Headless Chromium with one page, driven over the DevTools pipe."""

    def __init__(self, profile: Path) -> None:
        cmd_read, self._cmd_write = os.pipe()  # we write commands, Chromium reads fd 3
        self._res_read, res_write = os.pipe()  # Chromium writes fd 4, we read
        flags = [
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-dev-shm-usage",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--mute-audio",
            "--window-size=1280,900",
            f"--user-data-dir={profile}",
            "--remote-debugging-pipe",
            "about:blank",
        ]
        redirect = f'exec "$@" 3<&{cmd_read} 4>&{res_write} {cmd_read}<&- {res_write}>&-'
        self.proc = subprocess.Popen(
            ["bash", "-c", redirect, "chromium", str(CHROMIUM), *flags],
            pass_fds=(cmd_read, res_write),
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        os.close(cmd_read)
        os.close(res_write)
        self._buffer = b""
        self._next_id = 0
        self.session: str | None = None

    def call(self, method: str, timeout: float = 10.0, **params: Any) -> dict[str, Any]:
        """Send one CDP command (to the page session once attached) and return its result."""
        self._next_id += 1
        message: dict[str, Any] = {"id": self._next_id, "method": method, "params": params}
        if self.session is not None and not method.startswith("Target."):
            message["sessionId"] = self.session
        os.write(self._cmd_write, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            reply = self._read(deadline)
            if reply.get("id") == self._next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply["result"]

    def _read(self, deadline: float) -> dict[str, Any]:
        while b"\0" not in self._buffer:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self._res_read], [], [], left)[0]:
                raise TimeoutError("no reply from Chromium")
            chunk = os.read(self._res_read, 1 << 20)
            if not chunk:
                raise RuntimeError("Chromium closed the DevTools pipe")
            self._buffer += chunk
        message, self._buffer = self._buffer.split(b"\0", 1)
        return json.loads(message)

    def open_page(self, url: str) -> None:
        target = self.call("Target.createTarget", url="about:blank")["targetId"]
        self.session = self.call("Target.attachToTarget", targetId=target, flatten=True)[
            "sessionId"
        ]
        self.call("Page.navigate", url=url)

    def js(self, expression: str) -> Any:
        """Evaluate ``expression`` in the page and return its value."""
        result = self.call(
            "Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True
        )
        if "exceptionDetails" in result:
            raise RuntimeError(f"page error: {result['exceptionDetails']}")
        return result["result"].get("value")

    def wait_for(self, expression: str, timeout: float) -> float:
        """Poll until ``expression`` is truthy; returns the seconds it took."""
        t0 = time.monotonic()
        while not self.js(expression):
            if time.monotonic() - t0 > timeout:
                raise AssertionError(f"page never satisfied {expression!r} in {timeout} s")
            time.sleep(0.02)
        return time.monotonic() - t0

    def screenshot(self, path: Path) -> None:
        data = self.call("Page.captureScreenshot", format="png")["data"]
        path.write_bytes(base64.b64decode(data))

    def close(self) -> None:
        try:
            self.session = None
            self.call("Browser.close", timeout=3.0)
        except (OSError, RuntimeError, TimeoutError):
            pass
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self._cmd_write)
        os.close(self._res_read)


@pytest.fixture
def browser(tmp_path: Path) -> Iterator[Chromium]:
    chromium = Chromium(tmp_path / "profile")
    try:
        yield chromium
    finally:
        chromium.close()


@pytest.mark.parametrize("token", [None, TOKEN], ids=["no-token", "token"])
def test_new_alert_shows_within_a_second_and_ack_button_works(
    tmp_path: Path, browser: Chromium, token: str | None
) -> None:
    with AlertStore(tmp_path / "alerts.db") as store, \
            FeedServer(store, port=0, token=token) as feed:
        earlier = make_alert(1, lock_time=time.time() - 300, delivered={"mavlink": 1.0})
        store.add(earlier)
        store.acknowledge(earlier.alert_id, "jo")
        store.add(make_alert(2, positioned=False, lock_time=time.time() - 120))

        browser.open_page(feed.page_url)
        browser.wait_for("document.body?.dataset.live === '1'", timeout=15.0)
        # the token left the address bar at once; the cookie that replaced it is HttpOnly
        assert browser.js("location.href") == feed.url + "/"
        assert browser.js("document.cookie") == ""
        assert browser.js("document.querySelectorAll('article.alert').length") == 2
        browser.js("document.getElementById('operator').value = 'sam'")

        alert = make_alert(3, score=0.87)
        card = f"document.querySelector('[data-alert-id=\"{alert.alert_id}\"]')"
        t0 = time.monotonic()
        store.add(alert)
        browser.wait_for(f"!!{card}", timeout=1.0)
        assert time.monotonic() - t0 < 1.0

        text = browser.js(f"{card}.innerText")
        lat, lon = alert.position
        assert "swimmer" in text and "0.87" in text and "±4 m" in text
        assert f"{lat:.6f}, {lon:.6f}" in text
        assert browser.js(f"{card}.dataset.acknowledged") == "0"
        browser.wait_for(f"{card}.querySelector('img.thumb').naturalWidth > 0", timeout=3.0)
        # what the autopilot was told, as the store knows it: sends, never "delivered"
        store.record_sent(alert.alert_id, "mavlink")
        store.record_sent(alert.alert_id, "mavlink")
        store.record_ack(alert.alert_id, "mavlink_loiter", 4, "refused: MAV_RESULT_FAILED")
        browser.wait_for(f"{card}.innerText.includes('STATUSTEXT sent 2\u00d7 (no "
                         f"acknowledgement)')", timeout=5.0)
        browser.wait_for(f"{card}.innerText.includes('loiter refused: refused: "
                         f"MAV_RESULT_FAILED')", timeout=5.0)
        assert alert.short_id in browser.js(f"{card}.innerText")
        assert browser.js("document.getElementById('unacked').textContent") == "2"
        browser.screenshot(SCREENSHOT)

        browser.js(f"{card}.querySelector('button.ack').click()")
        deadline = time.monotonic() + 3.0
        while not store.get(alert.alert_id).acknowledged:
            assert time.monotonic() < deadline, "the button did not acknowledge the alert"
            time.sleep(0.02)
        assert store.get(alert.alert_id).ack_by == "sam"
        browser.wait_for(f"{card}.dataset.acknowledged === '1'", timeout=2.0)
        assert "Acknowledged\nby sam" in browser.js(f"{card}.innerText")
        assert browser.js("document.getElementById('unacked').textContent") == "1"


def test_page_without_the_token_is_refused_and_a_refused_stream_is_retried(
    tmp_path: Path, browser: Chromium
) -> None:
    with AlertStore(tmp_path / "alerts.db") as store, \
            FeedServer(store, port=0, token=TOKEN, max_streams=1) as feed:
        store.add(make_alert(1))
        browser.open_page(feed.url + "/")
        browser.wait_for("document.body?.innerText.includes('access token required')", 15.0)
        assert "swimmer" not in browser.js("document.body.innerText")

        # the only stream slot is taken: the page says so and retries until it gets one
        blocker = socket.create_connection(("127.0.0.1", feed.port), timeout=10)
        blocker.sendall(f"GET /events HTTP/1.0\r\nAuthorization: Bearer {TOKEN}\r\n"
                        f"Host: 127.0.0.1:{feed.port}\r\n\r\n".encode())
        try:
            assert blocker.recv(4096).startswith(b"HTTP/1.0 200")
            browser.call("Page.navigate", url=feed.page_url)
            browser.wait_for("document.getElementById('status')?.textContent"
                             ".includes('refused; retrying')", timeout=15.0)
            assert browser.js("document.body.dataset.live") == "0"
        finally:
            blocker.close()
        browser.wait_for("document.body.dataset.live === '1'", timeout=30.0)
        assert browser.js("document.querySelectorAll('article.alert').length") == 1
