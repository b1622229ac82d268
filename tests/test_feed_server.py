"""Operator feed over real sockets: JSON API, SSE, acknowledgement, JSON-lines follow."""

from __future__ import annotations

import http.client
import json
import threading
import time
import urllib.error
import urllib.request
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from alert_samples import make_alert
from conftest import wait_until

from sarmission.alerts.feed import FeedServer
from sarmission.alerts.store import AlertStore


@pytest.fixture
def store(tmp_path: Path) -> Iterator[AlertStore]:
    with AlertStore(tmp_path / "alerts.db") as s:
        yield s


@pytest.fixture
def feed(store: AlertStore) -> Iterator[FeedServer]:
    with FeedServer(store, port=0) as server:
        yield server


def get(feed: FeedServer, path: str) -> tuple[int, str, bytes]:
    try:
        with urllib.request.urlopen(feed.url + path, timeout=5) as r:
            return r.status, r.headers["Content-Type"], r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.headers["Content-Type"], e.read()


def post_json(feed: FeedServer, path: str, body: Any, content_type: str = "application/json"):
    request = urllib.request.Request(
        feed.url + path,
        data=json.dumps(body).encode(),
        headers={"Content-Type": content_type},
        method="POST",
    )
    try:
        with urllib.request.urlopen(request, timeout=5) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def open_stream(feed: FeedServer, path: str, headers: dict[str, str] | None = None):
    conn = http.client.HTTPConnection("127.0.0.1", feed.port, timeout=5)
    conn.request("GET", path, headers=headers or {})
    response = conn.getresponse()
    assert response.status == 200
    return conn, response


def read_sse(response: http.client.HTTPResponse, until: str) -> list[dict[str, str]]:
    """SSE events up to and including the first one named ``until``."""
    events, current = [], {}
    while True:
        line = response.readline().decode().rstrip("\n")
        if line == "":
            if "event" in current:
                events.append(current)
                if current["event"] == until:
                    return events
            current = {}
        elif not line.startswith(":"):
            key, _, value = line.partition(": ")
            current[key] = value


def test_localhost_by_default(store: AlertStore) -> None:
    server = FeedServer(store)
    assert server.host == "127.0.0.1"


def test_json_api(store: AlertStore, feed: FeedServer) -> None:
    a, b = make_alert(1, lock_time=1000.0), make_alert(2, positioned=False, lock_time=2000.0)
    store.add(a)
    store.add(b)

    status, ctype, body = get(feed, "/api/alerts")
    assert status == 200 and ctype == "application/json"
    docs = json.loads(body)
    assert [d["alert_id"] for d in docs] == [a.alert_id, b.alert_id]
    assert docs[0]["position"] == {"lat": a.position[0], "lon": a.position[1]}
    assert docs[1]["position"] is None and docs[1]["position_note"]
    assert docs[0]["thumbnail"] == f"/thumb/{a.alert_id}.jpg"

    assert [d["alert_id"] for d in json.loads(get(feed, "/api/alerts?since=1500")[2])] == [
        b.alert_id
    ]
    assert get(feed, "/api/alerts?since=yesterday")[0] == 400
    assert json.loads(get(feed, f"/api/alerts/{a.alert_id}")[2])["target_id"] == 1
    assert get(feed, "/api/alerts/unknown")[0] == 404

    status, ctype, jpeg = get(feed, docs[0]["thumbnail"])
    assert status == 200 and ctype == "image/jpeg" and jpeg == a.thumbnail
    assert jpeg.startswith(b"\xff\xd8")

    status, ctype, body = get(feed, "/alerts.geojson")
    assert status == 200 and ctype == "application/geo+json"
    assert json.loads(body)["features"][0]["geometry"]["coordinates"] == [
        a.position[1],
        a.position[0],
    ]
    status, _, body = get(feed, "/alerts.kml")
    assert status == 200 and ET.fromstring(body).tag.endswith("kml")

    status, _, body = get(feed, "/healthz")
    assert status == 200 and json.loads(body)["alerts"] == 2


def test_page_is_self_contained(feed: FeedServer) -> None:
    status, ctype, body = get(feed, "/")
    assert status == 200 and ctype.startswith("text/html")
    page = body.decode()
    assert "EventSource" in page and "/api/alerts/" in page
    assert all(f'"{verb}"' in page for verb in ("ack", "confirm", "dismiss"))
    assert "<svg" in page  # the map, drawn in the page
    assert "http://" not in page and "https://" not in page  # no CDN or remote assets


def test_bad_routes_are_json_404(feed: FeedServer) -> None:
    for path in ("/nope", "/thumb/missing.jpg", "/api/alerts/x/y/z"):
        status, ctype, body = get(feed, path)
        assert status == 404 and ctype == "application/json"
        assert json.loads(body)["error"]
    assert post_json(feed, "/nope", {})[0] == 404
    assert post_json(feed, "/api/alerts", {})[0] == 405


def test_sse_stream_receives_new_alert_and_ack(store: AlertStore, feed: FeedServer) -> None:
    old = make_alert(1)
    store.add(old)
    conn, response = open_stream(feed, "/events")
    try:
        assert response.headers["Content-Type"].startswith("text/event-stream")
        snapshot = read_sse(response, until="hello")
        assert [e["event"] for e in snapshot] == ["alert", "map", "hello"]
        assert json.loads(snapshot[0]["data"])["alert_id"] == old.alert_id

        new = make_alert(2)
        store.add(new)
        (event,) = read_sse(response, until="alert")  # pushed: the stream was already open
        assert json.loads(event["data"])["alert_id"] == new.alert_id
        last_id = event["id"]

        store.acknowledge(new.alert_id, "alice")
        (update,) = read_sse(response, until="update")
        assert json.loads(update["data"])["ack_by"] == "alice"
    finally:
        conn.close()

    # a reconnecting browser sends Last-Event-ID and gets only what it missed
    missed = make_alert(3)
    store.add(missed)
    conn, response = open_stream(feed, "/events", {"Last-Event-ID": last_id})
    try:
        # no snapshot of alerts; the map is state and comes again
        assert [e["event"] for e in read_sse(response, until="hello")] == ["map", "hello"]
        (update,) = read_sse(response, until="update")
        assert json.loads(update["data"])["alert_id"] == new.alert_id
        (event,) = read_sse(response, until="alert")
        assert json.loads(event["data"])["alert_id"] == missed.alert_id
    finally:
        conn.close()


def test_ack_via_post_changes_the_store(store: AlertStore, feed: FeedServer) -> None:
    alert = make_alert(1)
    store.add(alert)
    status, doc = post_json(feed, f"/api/alerts/{alert.alert_id}/ack", {"by": "bob"})
    assert status == 200 and doc["acknowledged"] and doc["ack_by"] == "bob"
    stored = store.get(alert.alert_id)
    assert stored.acknowledged and stored.ack_by == "bob"

    assert post_json(feed, "/api/alerts/missing/ack", {"by": "bob"})[0] == 404
    other = make_alert(2)
    store.add(other)
    # a cross-site form cannot send JSON: plain form posts are refused
    status, _ = post_json(
        feed, f"/api/alerts/{other.alert_id}/ack", {}, "application/x-www-form-urlencoded"
    )
    assert status == 415 and not store.get(other.alert_id).acknowledged
    assert get(feed, f"/api/alerts/{other.alert_id}/ack")[0] == 405


def test_jsonl_lists_and_follows(store: AlertStore, feed: FeedServer) -> None:
    first = make_alert(1)
    store.add(first)
    status, ctype, body = get(feed, "/alerts.jsonl")  # without follow: ends after the list
    assert status == 200 and ctype.startswith("application/x-ndjson")
    assert [json.loads(line)["alert_id"] for line in body.splitlines()] == [first.alert_id]

    conn, response = open_stream(feed, "/alerts.jsonl?follow=1")
    try:
        assert json.loads(response.readline())["alert_id"] == first.alert_id
        second = make_alert(2)
        timer = threading.Timer(0.2, store.add, (second,))
        timer.start()
        assert json.loads(response.readline())["alert_id"] == second.alert_id
        store.acknowledge(second.alert_id, "x")  # updates are not new lines
        third = make_alert(3)
        store.add(third)
        assert json.loads(response.readline())["alert_id"] == third.alert_id
    finally:
        conn.close()


def test_position_found_later_reaches_jsonl_and_sse(store: AlertStore, feed: FeedServer) -> None:
    blind = make_alert(1, positioned=False)
    store.add(blind)
    conn, response = open_stream(feed, "/alerts.jsonl?follow=1")
    sse_conn, sse = open_stream(feed, "/events")
    try:
        assert json.loads(response.readline())["position"] is None
        read_sse(sse, until="hello")
        store.attach_position(blind.alert_id, (-35.36, 149.17), 3.5, "ground plane")
        line = json.loads(response.readline())  # the same alert again, now with its position
        assert line["alert_id"] == blind.alert_id
        assert line["position"] == {"lat": -35.36, "lon": 149.17} and line["error_m"] == 3.5
        (update,) = read_sse(sse, until="update")
        assert json.loads(update["data"])["position"] == {"lat": -35.36, "lon": 149.17}
    finally:
        conn.close()
        sse_conn.close()


def test_client_disconnects_are_quiet_and_stop_is_prompt(
    store: AlertStore, feed: FeedServer, caplog: pytest.LogCaptureFixture
) -> None:
    threads = threading.active_count()
    for path in ("/events", "/alerts.jsonl?follow=1"):
        conn, response = open_stream(feed, path)
        response.close()
        conn.close()
    # their handler threads notice and end (the deadline only bounds a hang)
    assert wait_until(lambda: threading.active_count() == threads, 30.0)
    store.add(make_alert(1))
    time.sleep(0.3)
    assert not [r for r in caplog.records if r.levelname in ("ERROR", "CRITICAL")]
    conn, response = open_stream(feed, "/events")  # a stream still open at stop
    stopper = threading.Thread(target=feed.stop, daemon=True)
    stopper.start()
    stopper.join(30.0)
    assert not stopper.is_alive()  # stop does not wait for the open stream's client
    conn.close()
