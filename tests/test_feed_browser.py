"""The operator page in a real headless Chromium: a new alert appears on the open page after
``store.add`` (pushed, no reload) and the Acknowledge button acknowledges it in the store.

Chromium is driven over the DevTools pipe by the shared :mod:`chromium` helper. A screenshot
of the page is written under the test's ``tmp_path``. How fast an alert reaches the page is a
benchmark's business, not a test's: the waits here only bound a hung test.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from alert_samples import make_alert
from chromium import NEEDS_CHROMIUM, Chromium

from sarmission.alerts.feed import FeedServer
from sarmission.alerts.store import AlertStore

TOKEN = "browser-test-token-0123456789abcdef"

pytestmark = NEEDS_CHROMIUM


@pytest.fixture
def browser(tmp_path: Path) -> Iterator[Chromium]:
    chromium = Chromium(tmp_path / "profile")
    try:
        yield chromium
    finally:
        chromium.close()


@pytest.mark.parametrize("token", [None, TOKEN], ids=["no-token", "token"])
def test_new_alert_shows_live_and_ack_button_works(
    tmp_path: Path, browser: Chromium, token: str | None
) -> None:
    with (
        AlertStore(tmp_path / "alerts.db") as store,
        FeedServer(store, port=0, token=token) as feed,
    ):
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
        assert browser.js("document.getElementById('taught').hidden") is True  # none rated
        browser.js("document.getElementById('operator').value = 'sam'")

        alert = make_alert(3, score=0.87, confidence=0.12)
        card = f"document.querySelector('[data-alert-id=\"{alert.alert_id}\"]')"
        store.add(alert)
        browser.wait_for(f"!!{card}", timeout=15.0)
        assert browser.js("document.querySelectorAll('article.alert').length") == 3

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
        browser.wait_for(
            f"{card}.innerText.includes('STATUSTEXT sent 2\u00d7 (no acknowledgement)')",
            timeout=5.0,
        )
        browser.wait_for(
            f"{card}.innerText.includes('loiter refused: refused: MAV_RESULT_FAILED')", timeout=5.0
        )
        assert alert.short_id in browser.js(f"{card}.innerText")
        # sent to the team's TAK, then refined: the card moves and says how old the place is
        store.record_sent(alert.alert_id, "cot")
        browser.wait_for(f"{card}.innerText.includes('TAK sent 1\u00d7')", timeout=5.0)
        moved = (lat + 1e-4, lon)
        fixed = alert.lock_time + 30.0
        store.refine_position(
            alert.alert_id, moved, 2.0, "ground plane", "refined", fixed, (0.0, 0.4)
        )
        browser.wait_for(f"{card}.innerText.includes('{moved[0]:.6f}')", timeout=5.0)
        as_of = time.strftime("%H:%M:%S", time.gmtime(fixed))
        assert f"as of {as_of} UTC" in browser.js(f"{card}.innerText")
        assert "drifting 0.4 m/s to 090\u00b0" in browser.js(f"{card}.innerText")
        assert "±2 m" in browser.js(f"{card}.innerText")
        # the head's score and what it means: a low confidence is set apart
        assert "12 % likely a person" in browser.js(f"{card}.innerText")
        assert browser.js(f"{card}.querySelector('.likely.low') !== null") is True
        assert "likely" not in browser.js(
            f"document.querySelector('[data-alert-id=\"{earlier.alert_id}\"]').innerText"
        )
        assert browser.js("document.getElementById('unacked').textContent") == "2"
        browser.screenshot(tmp_path / "feed.png")

        browser.js(f"{card}.querySelector('button.ack').click()")
        deadline = time.monotonic() + 3.0
        while not store.get(alert.alert_id).acknowledged:
            assert time.monotonic() < deadline, "the button did not acknowledge the alert"
            time.sleep(0.02)
        assert store.get(alert.alert_id).ack_by == "sam"
        browser.wait_for(f"{card}.dataset.acknowledged === '1'", timeout=2.0)
        assert "Acknowledged\nby sam" in browser.js(f"{card}.innerText")
        assert browser.js("document.getElementById('unacked').textContent") == "1"
        # rated by the mission's calibration: shown with its range while that is wide, and
        # rated again, live, when the operator decides on another alert
        rated = [make_alert(k, tier="candidate") for k in (4, 5)]
        for a in rated:
            store.add(a)
            store.promote(a.alert_id, "held 3 s", None, -2.0)
        waiting = f"document.querySelector('[data-alert-id=\"{rated[1].alert_id}\"]')"
        shown = store.get(rated[1].alert_id).format_confidence()
        assert ", between " in shown  # e.g. "20 % likely a person, between 1 and 75 %"
        browser.wait_for(f"!!{waiting} && {waiting}.innerText.includes({shown!r})", timeout=5.0)
        assert browser.js(f"{waiting}.querySelector('.likely.wide') !== null") is True
        taught = "document.getElementById('taught')"
        assert browser.js(f"{taught}.hidden") is False
        assert "learnt from 0 of your decisions" in browser.js(f"{taught}.innerText")
        store.decide(rated[0].alert_id, "confirmed", "sam")
        again = store.get(rated[1].alert_id).format_confidence()
        assert again != shown
        browser.wait_for(f"{waiting}.innerText.includes({again!r})", timeout=5.0)
        browser.wait_for(f"{taught}.innerText.includes('learnt from 1 of')", timeout=5.0)


def test_page_without_the_token_is_refused_and_a_refused_stream_is_retried(
    tmp_path: Path, browser: Chromium
) -> None:
    with (
        AlertStore(tmp_path / "alerts.db") as store,
        FeedServer(store, port=0, token=TOKEN, max_streams=1) as feed,
    ):
        store.add(make_alert(1))
        browser.open_page(feed.url + "/")
        browser.wait_for("document.body?.innerText.includes('access token required')", 15.0)
        assert "swimmer" not in browser.js("document.body.innerText")

        # the only stream slot is taken: the page says so and retries until it gets one
        blocker = socket.create_connection(("127.0.0.1", feed.port), timeout=10)
        blocker.sendall(
            f"GET /events HTTP/1.0\r\nAuthorization: Bearer {TOKEN}\r\n"
            f"Host: 127.0.0.1:{feed.port}\r\n\r\n".encode()
        )
        try:
            assert blocker.recv(4096).startswith(b"HTTP/1.0 200")
            browser.call("Page.navigate", url=feed.page_url)
            browser.wait_for(
                "document.getElementById('status')?.textContent.includes('refused; retrying')",
                timeout=15.0,
            )
            assert browser.js("document.body.dataset.live") == "0"
        finally:
            blocker.close()
        browser.wait_for("document.body.dataset.live === '1'", timeout=30.0)
        assert browser.js("document.querySelectorAll('article.alert').length") == 1
