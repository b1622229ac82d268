"""The operator page's two tiers and map in a real headless Chromium, at desktop and phone size.

The map is checked twice: in the DOM (how many markers of each kind, area, track, scale bar,
north arrow) and in a screenshot written under ``tmp_path``, whose pixels at each marker's
centre must have that kind's colour and whose map region must hold as many red and amber discs
as there are alerts and candidates. Confirm and Dismiss buttons must change the store; a tap
on a marker highlights its card.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest
from alert_samples import make_alert
from chromium import NEEDS_CHROMIUM, Chromium

from sarmission.alerts.feed import FeedServer
from sarmission.alerts.model import Alert
from sarmission.alerts.page_cards import SETTLE_S
from sarmission.alerts.page_map import MARKER_COLOURS
from sarmission.alerts.store import AlertStore

pytestmark = NEEDS_CHROMIUM

MISSION = "sea-1"
LAT0, LON0 = -35.36, 149.16
M_PER_DEG_LAT = 111_195.0
M_PER_DEG_LON = M_PER_DEG_LAT * math.cos(math.radians(LAT0))


def at(east_m: float, north_m: float) -> tuple[float, float]:
    """``(lat, lon)`` of a point ``east_m``, ``north_m`` from the scene's centre."""
    return LAT0 + north_m / M_PER_DEG_LAT, LON0 + east_m / M_PER_DEG_LON


class Scene:
    """A mission in the store: area, track, and alerts of every kind, spread 200 m apart."""

    def __init__(self, store: AlertStore) -> None:
        self.store = store
        # an older mission's alert, far away: not on this mission's map
        store.add(make_alert(50, mission_id="old-mission", position=at(5000, 5000)))
        store.set_mission_area(
            MISSION, [at(-400, -300), at(400, -300), at(400, 300), at(-400, 300)]
        )

        def add(target_id: int, where: tuple[float, float] | None, **kw: object) -> Alert:
            alert = make_alert(
                target_id, mission_id=MISSION, position=where, positioned=where is not None, **kw
            )
            store.add(alert)
            return alert

        self.alert1 = add(1, at(-200, 150), lock_time=time.time() - 200)
        self.alert2 = add(2, at(0, 150), lock_time=time.time() - 190)
        store.acknowledge(self.alert2.alert_id, "jo")
        self.cand1 = add(3, at(200, 150), tier="candidate", score=0.64)
        self.cand2 = add(4, at(-200, -50), tier="candidate", score=0.58)
        self.gone = add(5, at(0, -50), tier="candidate", error_m=8.0)
        store.decide(self.gone.alert_id, "dismissed", "jo")
        self.foam = add(6, at(200, -50), tier="candidate")
        store.discard(self.foam.alert_id, "drifts 3.1 m/s: not a person")
        self.blind = add(7, None)
        for i in range(40):  # a survey leg east, then north
            east, north = (-350 + i * 35, -250) if i < 20 else (350, -250 + (i - 19) * 22)
            store.record_drone(MISSION, 1000.0 + i, *at(east, north), 60.0)


@pytest.fixture
def browser(tmp_path: Path) -> Iterator[Chromium]:
    chromium = Chromium(tmp_path / "profile")
    try:
        yield chromium
    finally:
        chromium.close()


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[Scene, FeedServer]]:
    with AlertStore(tmp_path / "alerts.db") as store, FeedServer(store, port=0) as feed:
        yield Scene(store), feed


def open_at(browser: Chromium, feed: FeedServer, width: int, height: int, mobile: bool) -> None:
    browser.open_page(feed.page_url)
    browser.call(
        "Emulation.setDeviceMetricsOverride",
        width=width,
        height=height,
        deviceScaleFactor=1,
        mobile=mobile,
    )
    browser.wait_for("document.body?.dataset.live === '1'", timeout=15.0)


def markers(browser: Chromium) -> dict[str, int]:
    return browser.js(
        "Object.fromEntries(['alert', 'candidate', 'dismissed', 'discarded'].map("
        "k => [k, document.querySelectorAll('#map .marker.' + k).length]))"
    )


def settled(browser: Chromium, expected: dict[str, int]) -> None:
    """Wait until the map was drawn at its current size with the expected markers."""
    browser.wait_for(
        "(() => { const s = document.getElementById('map'); return !mapView.pending && "
        "s.getAttribute('viewBox') === '0 0 ' + s.clientWidth + ' ' + s.clientHeight; })()",
        timeout=10.0,
    )
    deadline = time.monotonic() + 10.0
    while markers(browser) != expected:
        assert time.monotonic() < deadline, f"map shows {markers(browser)}, not {expected}"
        time.sleep(0.05)


def centres(browser: Chromium, kind: str) -> list[tuple[int, int]]:
    return [
        tuple(p)
        for p in browser.js(
            f"[...document.querySelectorAll('#map .marker.{kind} .centre')].map(c => {{"
            "const r = c.getBoundingClientRect(); "
            "return [Math.round(r.x + r.width / 2), Math.round(r.y + r.height / 2)]; })"
        )
    ]


def rect(browser: Chromium, selector: str) -> tuple[int, int, int, int]:
    x, y, w, h = browser.js(
        f"(() => {{ const r = document.querySelector('{selector}')"
        ".getBoundingClientRect(); return [r.x, r.y, r.width, r.height]; })()"
    )
    return round(x), round(y), round(w), round(h)


def rgb(hex_colour: str) -> np.ndarray:
    return np.array([int(hex_colour[i : i + 2], 16) for i in (1, 3, 5)])


def colour_at(image: np.ndarray, x: int, y: int) -> np.ndarray:
    """The median RGB of the 3x3 pixels around ``(x, y)``."""
    patch = image[y - 1 : y + 2, x - 1 : x + 2, ::-1].reshape(-1, 3)
    return np.median(patch, axis=0)


def discs(image: np.ndarray, region: tuple[int, int, int, int], colour: str) -> int:
    """How many blobs of at least 60 pixels of ``colour`` (within 12 per channel) ``region``
    of the screenshot holds."""
    x, y, w, h = region
    crop = image[y : y + h, x : x + w, ::-1].astype(int)
    mask = (np.abs(crop - rgb(colour)) <= 12).all(axis=2).astype(np.uint8)
    n, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    return sum(1 for i in range(1, n) if stats[i, cv2.CC_STAT_AREA] >= 60)


def check_screenshot(browser: Chromium, path: Path, expected: dict[str, int]) -> None:
    """Write a screenshot to ``path`` and check the markers' colours in its pixels."""
    browser.screenshot(path)
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    assert image is not None and image.shape[1] == browser.js("innerWidth")
    for kind in ("alert", "candidate", "dismissed"):
        points = centres(browser, kind)
        assert len(points) == expected[kind]
        for x, y in points:
            got = colour_at(image, x, y)
            assert (np.abs(got - rgb(MARKER_COLOURS[kind])) <= 12).all(), (kind, x, y, got)
    region = rect(browser, "#map")
    assert discs(image, region, MARKER_COLOURS["alert"]) == expected["alert"]
    assert discs(image, region, MARKER_COLOURS["candidate"]) == expected["candidate"]


def click_at(browser: Chromium, x: int, y: int) -> None:
    """A real mouse click at viewport pixel ``(x, y)``."""
    for kind in ("mousePressed", "mouseReleased"):
        browser.call("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left", clickCount=1)


def card(alert: Alert) -> str:
    return f"document.querySelector('article[data-alert-id=\"{alert.alert_id}\"]')"


def wait_store(condition: object, what: str, timeout: float = 5.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():  # type: ignore[operator]
        assert time.monotonic() < deadline, what
        time.sleep(0.02)


def test_desktop_map_tiers_and_decisions(
    tmp_path: Path, browser: Chromium, served: tuple[Scene, FeedServer]
) -> None:
    scene, feed = served
    store = scene.store
    open_at(browser, feed, 1280, 800, mobile=False)
    expected = {"alert": 2, "candidate": 2, "dismissed": 1, "discarded": 0}
    settled(browser, expected)
    # the map: area, the whole track with the drone at its end, scale bar and north arrow
    assert browser.js("document.querySelectorAll('#map polygon.area').length") == 1
    assert browser.js("document.querySelector('#map polyline.track').points.length") == 40
    assert browser.js("document.querySelectorAll('#map .drone').length") == 1
    assert browser.js(
        "/^[0-9.]+ k?m$/.test(document.querySelector('#map .scale text').textContent)"
    )
    assert browser.js("document.querySelector('#map .north').textContent") == "N"
    # the list: tiers at a glance, the discarded candidate hidden, the blind alert listed
    assert browser.js(f"{card(scene.cand1)}.dataset.kind") == "candidate"
    assert "Unconfirmed" in browser.js(f"{card(scene.cand1)}.innerText")
    assert "Dismissed by jo" in browser.js(f"{card(scene.gone)}.innerText")
    assert browser.js(f"getComputedStyle({card(scene.foam)}).display") == "none"
    assert browser.js(f"!!{card(scene.blind)}")
    assert browser.js("document.getElementById('review').textContent") == "2"
    assert browser.js("document.querySelectorAll('.alert.fresh[data-kind=candidate]').length") == 0
    check_screenshot(browser, tmp_path / "map_desktop.png", expected)

    browser.js("document.getElementById('show-discarded').click()")
    settled(browser, {**expected, "discarded": 1})
    assert "drifts 3.1 m/s" in browser.js(f"{card(scene.foam)}.innerText")
    browser.js("document.getElementById('show-discarded').click()")
    settled(browser, expected)

    # a click on a marker highlights its card
    ((x, y),) = [
        p
        for p, a in zip(
            centres(browser, "candidate"),
            browser.js(
                "[...document.querySelectorAll('#map .marker.candidate')].map(g => g.dataset.alert)"
            ),
            strict=True,
        )
        if a == scene.cand2.alert_id
    ]
    click_at(browser, x, y)
    browser.wait_for(f"{card(scene.cand2)}.classList.contains('highlight')", timeout=3.0)
    assert browser.js("document.querySelectorAll('article.highlight').length") == 1

    # no name, no decision: the page asks for one
    browser.js("document.getElementById('operator').value = ''")
    browser.js(f"{card(scene.cand1)}.querySelector('button.dismiss').click()")
    browser.wait_for(f"{card(scene.cand1)}.innerText.includes('enter your name')", timeout=3.0)
    assert store.get(scene.cand1.alert_id).decision is None

    browser.js("document.getElementById('operator').value = 'sam'")
    browser.js(f"{card(scene.cand1)}.querySelector('button.confirm').click()")
    wait_store(lambda: store.get(scene.cand1.alert_id).decision == "confirmed", "not confirmed")
    confirmed = store.get(scene.cand1.alert_id)
    assert (confirmed.decided_by, confirmed.tier) == ("sam", "confirmed")
    browser.wait_for(f"{card(scene.cand1)}.dataset.kind === 'alert'", timeout=3.0)
    browser.js(f"{card(scene.cand2)}.querySelector('button.dismiss').click()")
    wait_store(lambda: store.get(scene.cand2.alert_id).dismissed, "not dismissed")
    assert store.get(scene.cand2.alert_id).decided_by == "sam"
    browser.wait_for(f"{card(scene.cand2)}.innerText.includes('Dismissed by sam')", timeout=3.0)
    expected = {"alert": 3, "candidate": 0, "dismissed": 2, "discarded": 0}
    settled(browser, expected)

    # live: a new candidate arrives amber and quiet, its confirmation turns it red
    newcomer = make_alert(8, mission_id=MISSION, position=at(-100, 50), tier="candidate")
    store.add(newcomer)
    settled(browser, {**expected, "candidate": 1})
    assert not browser.js(f"{card(newcomer)}.classList.contains('fresh')")
    store.promote(newcomer.alert_id, "held 4.2 s within 3 m")
    settled(browser, {**expected, "alert": 4})
    browser.wait_for(f"{card(newcomer)}.innerText.includes('held 4.2 s within 3 m')", 3.0)
    store.record_drone(MISSION, 1100.0, *at(300, 250), 60.0)
    browser.wait_for("document.querySelector('#map polyline.track').points.length === 41", 5.0)
    check_screenshot(browser, tmp_path / "map_desktop_after.png", {**expected, "alert": 4})


def test_phone_map_above_a_scrolling_list(
    tmp_path: Path, browser: Chromium, served: tuple[Scene, FeedServer]
) -> None:
    scene, feed = served
    open_at(browser, feed, 390, 844, mobile=True)
    expected = {"alert": 2, "candidate": 2, "dismissed": 1, "discarded": 0}
    settled(browser, expected)
    assert browser.js("innerWidth") == 390
    assert browser.js("document.documentElement.scrollWidth") <= 390  # no sideways scrolling
    mx, my, mw, mh = rect(browser, "#map")
    lx, ly, lw, lh = rect(browser, ".list")
    assert my + mh <= ly + 1 and mw >= 370 and mh >= 220 and lh >= 250  # map above the list
    assert browser.js("getComputedStyle(document.querySelector('.list')).overflowY") == "auto"
    sizes = browser.js(
        "[...document.querySelectorAll('.side button')].filter(b => "
        "b.offsetParent).map(b => [b.offsetWidth, b.offsetHeight])"
    )
    assert sizes and all(w >= 44 and h >= 44 for w, h in sizes)
    check_screenshot(browser, tmp_path / "map_phone.png", expected)

    # tap the dismissed zone's marker: its card is highlighted and scrolled into the list's view
    ((x, y),) = centres(browser, "dismissed")
    click_at(browser, x, y)
    browser.wait_for(f"{card(scene.gone)}.classList.contains('highlight')", timeout=3.0)
    _, cy, _, ch = rect(browser, f'article[data-alert-id="{scene.gone.alert_id}"]')
    assert ly - 1 <= cy and cy + min(ch, 100) <= ly + lh + 1

    browser.js("document.getElementById('operator').value = 'kim'")
    browser.js(f"{card(scene.cand2)}.querySelector('button.confirm').click()")
    wait_store(
        lambda: scene.store.get(scene.cand2.alert_id).decision == "confirmed",
        "not confirmed from the phone",
    )
    settled(browser, {**expected, "alert": 3, "candidate": 1})


def test_live_candidates_settle_before_they_are_shown(
    browser: Chromium, served: tuple[Scene, FeedServer]
) -> None:
    """A candidate arriving live stays off the list, the count and the map for SETTLE_S; one the
    evidence discards meanwhile never shows, one still waiting shows after it."""
    scene, feed = served
    store = scene.store
    open_at(browser, feed, 1280, 800, mobile=False)
    expected = {"alert": 2, "candidate": 2, "dismissed": 1, "discarded": 0}
    settled(browser, expected)
    assert browser.js("document.getElementById('review').textContent") == "2"

    waiting = make_alert(20, mission_id=MISSION, position=at(-100, 50), tier="candidate")
    clutter = make_alert(21, mission_id=MISSION, position=at(100, 50), tier="candidate")
    arrived = time.monotonic()
    store.add(waiting)
    store.add(clutter)
    browser.wait_for(f"{card(waiting)} !== null && {card(clutter)} !== null", timeout=3.0)
    store.discard(clutter.alert_id, "mean score 0.41 below 0.85")
    browser.wait_for(f"{card(clutter)}.dataset.kind === 'discarded'", timeout=3.0)
    visible = f"{card(waiting)}.offsetParent !== null"
    early = browser.js(visible), browser.js("document.getElementById('review').textContent")
    assert time.monotonic() - arrived < SETTLE_S - 0.5, "too slow to check the settling card"
    assert early == (False, "2")
    assert markers(browser) == expected

    browser.wait_for(visible, timeout=SETTLE_S + 3.0)
    assert time.monotonic() - arrived >= SETTLE_S - 0.1
    settled(browser, {**expected, "candidate": 3})
    assert browser.js("document.getElementById('review').textContent") == "3"
    assert not browser.js(f"{card(clutter)}.offsetParent !== null")  # discarded: hidden
