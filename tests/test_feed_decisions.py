"""Operator decisions and the map over real HTTP: confirm/dismiss routes (double, contradicting,
racing, unknown ids), candidates and tier changes on SSE and JSON lines, ``/api/map`` and the
stream's ``map`` / ``track`` / ``area`` events."""

from __future__ import annotations

import json
import sqlite3
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from alert_samples import make_alert
from test_feed_server import get, open_stream, post_json, read_sse

import sarmission.alerts.store as store_module
from sarmission.alerts.feed import FeedServer
from sarmission.alerts.feed_map import MapFollower, thin
from sarmission.alerts.store import AlertStore, DronePoint

AREA = [(-35.360, 149.160), (-35.360, 149.170), (-35.370, 149.170), (-35.370, 149.160)]


@pytest.fixture
def store(tmp_path: Path) -> Iterator[AlertStore]:
    with AlertStore(tmp_path / "alerts.db") as s:
        yield s


@pytest.fixture
def feed(store: AlertStore) -> Iterator[FeedServer]:
    with FeedServer(store, port=0) as server:
        yield server


def decide(feed: FeedServer, alert_id: str, verb: str, by: str = "ana") -> tuple[int, dict]:
    return post_json(feed, f"/api/alerts/{alert_id}/{verb}", {"by": by})


def test_confirm_and_dismiss_through_the_feed(store: AlertStore, feed: FeedServer) -> None:
    cand = make_alert(1, tier="candidate")
    store.add(cand)
    status, doc = decide(feed, cand.alert_id, "confirm")
    assert status == 200 and doc["unchanged"] is False
    assert (doc["decision"], doc["decided_by"], doc["tier"]) == ("confirmed", "ana", "confirmed")
    status, doc = decide(feed, cand.alert_id, "confirm", by="bo")  # a second, identical one
    assert status == 200 and doc["unchanged"] is True and doc["decided_by"] == "ana"
    status, doc = decide(feed, cand.alert_id, "dismiss", by="bo")  # a change of mind
    assert status == 200 and doc["unchanged"] is False and doc["decision"] == "dismissed"
    status, doc = decide(feed, cand.alert_id, "dismiss", by="cy")  # a double dismiss
    assert status == 200 and doc["unchanged"] is True and doc["decided_by"] == "bo"
    assert [(d.decision, d.by) for d in store.decisions(cand.alert_id)] == [
        ("confirmed", "ana"),
        ("dismissed", "bo"),
    ]
    # the system never promotes what an operator dismissed
    dismissed = make_alert(2, tier="candidate")
    store.add(dismissed)
    assert decide(feed, dismissed.alert_id, "dismiss")[0] == 200
    assert store.promote(dismissed.alert_id, "held 4 s") is None

    for verb in ("confirm", "dismiss"):
        status, doc = decide(feed, "no-such-alert", verb)
        assert status == 404 and doc["error"] == "no alert no-such-alert"
        status, doc = post_json(feed, f"/api/alerts/{cand.alert_id}/{verb}", {})
        assert status == 400 and "who decides" in doc["error"]
        assert get(feed, f"/api/alerts/{cand.alert_id}/{verb}")[0] == 405
    assert len(store.decisions(cand.alert_id)) == 2  # the refusals changed nothing


def test_a_change_the_store_cannot_record_is_a_503_to_retry(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """Another process holds the store's write lock past the store's wait (or the file cannot
    be written): the operator gets one line of JSON saying nothing was recorded and to retry,
    the log one warning without a traceback; once the lock is released the retry records."""
    monkeypatch.setattr(store_module, "BUSY_TIMEOUT_S", 0.3)
    db = tmp_path / "alerts.db"
    with AlertStore(db) as store, FeedServer(store, port=0) as feed:
        alert = make_alert(1, tier="candidate")
        store.add(alert)
        holder = sqlite3.connect(db, isolation_level=None)
        holder.execute("BEGIN IMMEDIATE")
        with caplog.at_level("INFO", logger="sarmission.alerts.feed"):
            status, doc = decide(feed, alert.alert_id, "dismiss")
            assert status == 503
            assert "decision was not recorded" in doc["error"] and "retry" in doc["error"]
            assert "busy: another process holds a lock" in doc["error"]
            status, doc = post_json(feed, f"/api/alerts/{alert.alert_id}/ack", {"by": "ana"})
            assert status == 503 and "acknowledgement was not recorded" in doc["error"]
        holder.execute("ROLLBACK")
        holder.close()
        failed = [r for r in caplog.records if r.levelname != "INFO"]
        assert [r.levelname for r in failed] == ["WARNING", "WARNING"]
        assert all(r.exc_info is None and "\n" not in r.getMessage() for r in failed)
        assert "not recorded" in failed[0].getMessage()
        assert store.get(alert.alert_id).decision is None  # nothing of it stands
        status, doc = decide(feed, alert.alert_id, "dismiss")
        assert status == 200 and doc["decision"] == "dismissed"

        def read_only(*args: object) -> None:
            raise sqlite3.OperationalError("attempt to write a readonly database")

        monkeypatch.setattr(store, "record_decision", read_only)
        status, doc = decide(feed, alert.alert_id, "confirm")
        assert status == 503 and "cannot be written" in doc["error"]


def test_decisions_racing_over_http(store: AlertStore, feed: FeedServer) -> None:
    alert = make_alert(1, tier="candidate")
    store.add(alert)
    barrier = threading.Barrier(2)
    answers: dict[str, tuple[int, dict]] = {}

    def send(verb: str) -> None:
        barrier.wait()
        answers[verb] = decide(feed, alert.alert_id, verb, by=verb + "er")

    threads = [threading.Thread(target=send, args=(v,)) for v in ("confirm", "dismiss")]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert {v: a[0] for v, a in answers.items()} == {"confirm": 200, "dismiss": 200}
    history = store.decisions(alert.alert_id)
    assert sorted(h.decision for h in history) == ["confirmed", "dismissed"]  # nothing lost
    final = store.get(alert.alert_id)
    assert (final.decision, final.decided_by) == (history[-1].decision, history[-1].by)


def test_candidates_and_tier_changes_reach_sse_and_jsonl(
    store: AlertStore, feed: FeedServer
) -> None:
    store.add(make_alert(9))  # so the map's mission does not change during the test
    conn, sse = open_stream(feed, "/events")
    lines_conn, lines = open_stream(feed, "/alerts.jsonl?follow=1")
    try:
        read_sse(sse, until="hello")
        assert json.loads(lines.readline())["target_id"] == 9
        a, b = make_alert(1, tier="candidate"), make_alert(2, tier="candidate")
        store.add(a)
        store.add(b)
        new = [json.loads(e["data"]) for e in read_sse(sse, until="alert")]
        new += [json.loads(e["data"]) for e in read_sse(sse, until="alert")]
        assert [(d["alert_id"], d["tier"]) for d in new] == [
            (a.alert_id, "candidate"),
            (b.alert_id, "candidate"),
        ]
        assert [json.loads(lines.readline())["tier"] for _ in range(2)] == ["candidate"] * 2

        store.promote(a.alert_id, "held 4.2 s within 3 m")
        store.discard(b.alert_id, "drifts 3 m/s")
        store.decide(b.alert_id, "dismissed", "ana")
        # one update per change, in order; each carries the alert as it is when read
        updates = [json.loads(read_sse(sse, until="update")[-1]["data"]) for _ in range(3)]
        relined = [json.loads(lines.readline()) for _ in range(3)]
        for docs in (updates, relined):
            assert [d["alert_id"] for d in docs] == [a.alert_id, b.alert_id, b.alert_id]
            assert (docs[0]["tier"], docs[0]["evidence"]) == ("confirmed", "held 4.2 s within 3 m")
            assert (
                docs[2]["tier"],
                docs[2]["discarded"],
                docs[2]["decision"],
                docs[2]["decided_by"],
            ) == ("candidate", "drifts 3 m/s", "dismissed", "ana")
    finally:
        conn.close()
        lines_conn.close()


def test_api_map(store: AlertStore, feed: FeedServer) -> None:
    status, _, body = get(feed, "/api/map")
    assert status == 200 and json.loads(body) == {
        "mission_id": None,
        "area": None,
        "track": [],
        "alerts": [],
        "dismissed": [],
    }
    store.set_mission_area("test-mission", AREA)
    for i in range(5):
        store.record_drone("test-mission", 1000.0 + i, -35.365 + i * 1e-4, 149.165, 60.0)
    confirmed, cand, gone = (
        make_alert(1),
        make_alert(2, tier="candidate"),
        make_alert(3, tier="candidate", error_m=8.0),
    )
    for a in (confirmed, cand, gone):
        store.add(a)
    store.decide(gone.alert_id, "dismissed", "ana")
    store.add(make_alert(4, mission_id="older"))  # the newest alert, but another mission
    store.record_drone("test-mission", 1005.0, -35.3645, 149.165, 60.0)  # the drone flies this

    doc = json.loads(get(feed, "/api/map")[2])
    assert doc["mission_id"] == "test-mission"
    assert doc["area"] == [list(v) for v in AREA]
    assert doc["track"][0] == [1000.0, -35.365, 149.165] and len(doc["track"]) == 6
    assert [(a["target_id"], a["tier"], a["decision"]) for a in doc["alerts"]] == [
        (1, "confirmed", None),
        (2, "candidate", None),
        (3, "candidate", "dismissed"),
    ]
    assert doc["dismissed"] == [[*gone.position, 16.0]]
    since = json.loads(get(feed, "/api/map?since=1004")[2])
    assert [p[0] for p in since["track"]] == [1004.0, 1005.0]
    older = json.loads(get(feed, "/api/map?mission=older")[2])
    assert [a["target_id"] for a in older["alerts"]] == [4] and older["area"] is None
    for bad in (
        "/api/map?mission=",
        "/api/map?mission=" + "m" * 129,
        "/api/map?since=nan",
        "/api/map?mission=a&mission=b",
        "/api/map?zoom=3",
        "/api/map?mission=%07",
    ):
        status, ctype, body = get(feed, bad)
        assert status == 400 and ctype == "application/json" and b"\n" not in body.strip(), bad


def test_stream_carries_the_map_then_only_its_changes(store: AlertStore, feed: FeedServer) -> None:
    store.set_mission_area("test-mission", AREA)
    store.record_drone("test-mission", 1000.0, -35.365, 149.165, 60.0)
    conn, sse = open_stream(feed, "/events")
    try:
        first = read_sse(sse, until="hello")
        (snapshot,) = [json.loads(e["data"]) for e in first if e["event"] == "map"]
        assert snapshot == {
            "mission_id": "test-mission",
            "area": [list(v) for v in AREA],
            "track": [[1000.0, -35.365, 149.165]],
        }
        seq = store.last_event_seq()
        recorded = [[1001.0 + i, -35.365 + i * 1e-5, 149.165] for i in range(30)]
        for t, lat, lon in recorded:
            store.record_drone("test-mission", t, lat, lon, 60.0)
        assert store.last_event_seq() == seq  # the track is polled, not logged as events
        received: list[list[float]] = []
        while len(received) < len(recorded):
            event = read_sse(sse, until="track")[-1]
            received += json.loads(event["data"])["track"]
            assert "id" not in event  # state, not a place in the log
        assert received == recorded
        store.set_mission_area("test-mission", AREA[:3])
        area = json.loads(read_sse(sse, until="area")[-1]["data"])
        assert area == {"mission_id": "test-mission", "area": [list(v) for v in AREA[:3]]}
        store.record_drone("next-mission", 2000.0, -35.0, 149.0, 50.0)  # a new flight
        again = json.loads(read_sse(sse, until="map")[-1]["data"])
        assert again == {
            "mission_id": "next-mission",
            "area": None,
            "track": [[2000.0, -35.0, 149.0]],
        }
    finally:
        conn.close()


def test_map_follower_sends_at_most_one_update_per_interval(store: AlertStore) -> None:
    now = [0.0]
    follower = MapFollower(store, interval_s=1.0, clock=lambda: now[0])
    assert follower.poll() == [("map", {"mission_id": None, "area": None, "track": []})]
    store.record_drone("m", 1.0, -35.0, 149.0, 10.0)
    now[0] = 0.5
    assert follower.poll() == []  # too soon: waits for the interval
    now[0] = 1.0
    assert [name for name, _ in follower.poll()] == ["map"]  # the store turned to mission m
    for i in range(10):
        store.record_drone("m", 2.0 + i, -35.0, 149.0, 10.0)
    now[0] = 1.9
    assert follower.poll() == []
    now[0] = 2.0
    ((name, data),) = follower.poll()
    assert name == "track" and len(data["track"]) == 10  # ten points, one event
    now[0] = 3.0
    assert follower.poll() == []  # nothing new


def test_thin_keeps_the_newest_point() -> None:
    points = [DronePoint(float(i), 0.0, 0.0, None) for i in range(10_001)]
    kept = thin(points, 4000)
    assert len(kept) <= 4000 and kept[0] == points[0] and kept[-1] == points[-1]
    assert thin(points[:5], 4000) == points[:5]
