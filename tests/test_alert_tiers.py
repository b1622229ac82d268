"""Alert store: candidates and confirmed alerts, operator decisions (double, contradicting,
racing, with skewed clocks), dismissed zones, the drone's track and the mission area."""

from __future__ import annotations

import sqlite3
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from alert_samples import make_alert

import sarmission.alerts.store as store_module
from sarmission.alerts.model import CHANNEL_MAVLINK, Alert
from sarmission.alerts.store import AlertStore, OperatorDecision

AREA = [(-35.360, 149.160), (-35.360, 149.170), (-35.370, 149.170), (-35.370, 149.160)]


def candidate(target_id: int = 1, **changes: object) -> Alert:
    return make_alert(target_id, tier="candidate", **changes)


def race(*calls: Callable[[], Any]) -> list[Any]:
    """Run ``calls`` in threads released together; their results in the order given."""
    barrier = threading.Barrier(len(calls))
    results: list[Any] = [None] * len(calls)

    def run(k: int) -> None:
        barrier.wait()
        results[k] = calls[k]()

    threads = [threading.Thread(target=run, args=(k,)) for k in range(len(calls))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return results


def kinds(store: AlertStore, after: int = 0) -> list[tuple[str, str | None, str]]:
    return [(e.kind, e.by, e.detail) for e in store.events(after)]


def test_tier_and_decision_are_checked_and_in_the_json() -> None:
    with pytest.raises(ValueError, match="tier"):
        make_alert(1, tier="maybe")
    with pytest.raises(ValueError, match="decision"):
        make_alert(1, decision="ignored")
    doc = candidate(error_m=12.0).to_json_dict()
    assert (doc["tier"], doc["evidence"], doc["discarded"], doc["decision"]) == (
        "candidate",
        "",
        None,
        None,
    )
    assert (doc["decided_by"], doc["decided_at"], doc["confirmed_at"]) == (None, None, None)
    assert doc["dismiss_radius_m"] == 24.0
    assert make_alert(1).to_json_dict()["tier"] == "confirmed"  # the default: as before tiers


def test_candidate_round_trips_and_the_system_promotes_it_once(tmp_path: Path) -> None:
    db = tmp_path / "a.db"
    alert = candidate()
    with AlertStore(db) as store:
        store.add(alert)
        assert store.get(alert.alert_id) == alert
        assert store.pending_candidates("test-mission") == [alert]
        promoted = store.promote(alert.alert_id, "held 4.1 s within 3 m", when=1234.5)
        assert promoted is not None
        assert (promoted.tier, promoted.evidence, promoted.confirmed_at) == (
            "confirmed",
            "held 4.1 s within 3 m",
            1234.5,
        )
        again = store.promote(alert.alert_id, "other evidence", when=2000.0)
        assert again == promoted  # idempotent: the first confirmation stands
        assert kinds(store) == [("new", None, ""), ("confirmed", None, "held 4.1 s within 3 m")]
        assert store.pending_candidates("test-mission") == []
        with pytest.raises(KeyError):
            store.promote("missing", "x")
    with AlertStore(db) as store:
        assert store.get(alert.alert_id) == promoted


def test_discard_only_touches_an_undecided_candidate(tmp_path: Path) -> None:
    with AlertStore(tmp_path / "a.db") as store:
        foam, decided, confirmed = candidate(1), candidate(2), make_alert(3)
        for a in (foam, decided, confirmed):
            store.add(a)
        got = store.discard(foam.alert_id, "drifts 3.2 m/s: not a person", when=50.0)
        assert got is not None and got.discarded == "drifts 3.2 m/s: not a person"
        assert got.evidence == got.discarded and got.discarded_at == 50.0
        assert got.tier == "candidate" and not got.awaiting_review
        assert store.discard(foam.alert_id, "again") == got  # already discarded: unchanged
        assert store.discard(confirmed.alert_id, "too late") is None
        store.decide(decided.alert_id, "confirmed", "ana")
        assert store.discard(decided.alert_id, "too late") is None
        assert store.get(decided.alert_id).discarded is None
        with pytest.raises(ValueError):
            store.discard(foam.alert_id, " ")
        with pytest.raises(KeyError):
            store.discard("missing", "x")
        # new evidence after a discard confirms it; the reason stays in the log
        again = store.promote(foam.alert_id, "seen again for 5 s")
        assert again is not None and again.tier == "confirmed" and again.discarded is None
        assert [k for k in kinds(store) if k[0] in ("discarded", "confirmed")][0] == (
            "discarded",
            None,
            "drifts 3.2 m/s: not a person",
        )


def test_operator_decisions_double_contradicting_and_unknown(tmp_path: Path) -> None:
    db = tmp_path / "a.db"
    alert = candidate()
    with AlertStore(db) as store:
        store.add(alert)
        t0 = time.time()
        first = store.record_decision(alert.alert_id, "confirmed", " ana ")
        t1 = time.time()
        assert first.changed and first.alert.decision == "confirmed"
        assert first.alert.decided_by == "ana" and t0 <= first.alert.decided_at <= t1
        # the operator's confirmation confirms the candidate, and says who did
        assert first.alert.tier == "confirmed"
        assert first.alert.confirmed_at == first.alert.decided_at
        assert kinds(store, after=1) == [
            ("decided", "ana", "confirmed"),
            ("confirmed", "ana", "confirmed by operator ana"),
        ]
        twice = store.record_decision(alert.alert_id, "confirmed", "bo")
        assert not twice.changed and twice.alert == first.alert  # idempotent, still ana's
        assert store.last_event_seq() == 3
        # a change of mind: the newer decision wins, both are kept
        dismissed = store.decide(alert.alert_id, "dismissed", "bo")
        assert dismissed.dismissed and dismissed.decided_by == "bo"
        assert dismissed.tier == "confirmed"  # the tier records what the evidence said
        assert [(d.decision, d.by) for d in store.decisions(alert.alert_id)] == [
            ("confirmed", "ana"),
            ("dismissed", "bo"),
        ]
        assert not store.record_decision(alert.alert_id, "dismissed", "cy").changed
        with pytest.raises(KeyError):
            store.decide("no-such-alert", "dismissed", "ana")
        with pytest.raises(ValueError, match="decision"):
            store.decide(alert.alert_id, "ignore", "ana")  # type: ignore[arg-type]
        with pytest.raises(ValueError, match="name"):
            store.decide(alert.alert_id, "confirmed", "  ")
        with pytest.raises(ValueError, match="finite"):
            store.decide(alert.alert_id, "confirmed", "ana", when=float("nan"))
        assert store.get(alert.alert_id).decided_by == "bo"  # nothing changed by the refusals
    with AlertStore(db) as store:  # durable, history included
        assert store.get(alert.alert_id).dismissed
        history = store.decisions(alert.alert_id)
        assert [h.decision for h in history] == ["confirmed", "dismissed"]
        assert isinstance(history[0], OperatorDecision)


def test_dismiss_always_wins_over_a_later_promotion_whatever_the_clocks(tmp_path: Path) -> None:
    with AlertStore(tmp_path / "a.db") as store:
        alert = candidate()
        store.add(alert)
        # the operator's device is an hour behind, the controller's clock an hour ahead
        store.decide(alert.alert_id, "dismissed", "ana", when=time.time() - 3600)
        assert store.promote(alert.alert_id, "held 5 s", when=time.time() + 3600) is None
        got = store.get(alert.alert_id)
        assert got.tier == "candidate" and got.dismissed and got.confirmed_at is None
        # the other order: a dismissal after the promotion stands, and stops the autopilot
        late = candidate(3)
        store.add(late)
        assert store.promote(late.alert_id, "held 5 s").tier == "confirmed"
        assert late.alert_id in {a.alert_id for a in store.undelivered("mavlink_loiter")}
        store.decide(late.alert_id, "dismissed", "ana", when=time.time() - 3600)
        assert late.alert_id not in {a.alert_id for a in store.undelivered("mavlink_loiter")}
        assert store.promote(late.alert_id, "held 6 s") is None
        # and the operator's confirmation is not undone by a discard from any clock
        other = candidate(2)
        store.add(other)
        store.decide(other.alert_id, "confirmed", "ana", when=time.time() + 3600)
        assert store.discard(other.alert_id, "timed out", when=time.time() - 3600) is None
        assert store.get(other.alert_id).tier == "confirmed"


def test_dismiss_racing_a_promotion_from_another_connection(tmp_path: Path) -> None:
    db = tmp_path / "a.db"
    with AlertStore(db) as feed_side, AlertStore(db) as controller_side:
        outcomes = set()
        for i in range(20):
            alert = candidate(i)
            controller_side.add(alert)
            seq0 = feed_side.last_event_seq()
            dismissal, promoted = race(
                lambda a=alert: feed_side.record_decision(a.alert_id, "dismissed", "ana"),
                lambda a=alert: controller_side.promote(a.alert_id, "held 4 s"),
            )
            final = feed_side.get(alert.alert_id)
            log = [e.kind for e in feed_side.events(seq0)]
            assert final.dismissed and dismissal.changed  # the dismissal always holds
            if promoted is None:  # the dismissal committed first
                assert log == ["decided"] and final.tier == "candidate"
                outcomes.add("dismissed first")
            else:  # the promotion committed first: both stand, both logged in that order
                assert log == ["confirmed", "decided"] and final.tier == "confirmed"
                outcomes.add("promoted first")
            assert alert.alert_id not in {a.alert_id for a in feed_side.undelivered("cot")}
            assert final.position[:2] == feed_side.dismissed_zones("test-mission")[-1][:2]
        assert outcomes  # at least one order was seen; each is checked above


def test_two_threads_deciding_at_once_on_one_store(tmp_path: Path) -> None:
    with AlertStore(tmp_path / "a.db") as store:
        for i in range(10):
            alert = candidate(i)
            store.add(alert)
            seq0 = store.last_event_seq()
            race(
                lambda a=alert: store.decide(a.alert_id, "confirmed", "ana"),
                lambda a=alert: store.decide(a.alert_id, "dismissed", "bo"),
            )
            decided = [e for e in store.events(seq0) if e.kind == "decided"]
            assert sorted(e.detail for e in decided) == ["confirmed", "dismissed"]  # both kept
            final = store.get(alert.alert_id)
            assert final.decision == decided[-1].detail  # the later commit is the state
            assert final.decided_by == decided[-1].by
            assert final.tier == "confirmed"  # the confirmation happened, whichever came last

        # many operators dismissing one alert at once: one decision, the rest unchanged
        alert = candidate(99)
        store.add(alert)
        seq0 = store.last_event_seq()
        results = race(
            *(
                lambda k=k: store.record_decision(alert.alert_id, "dismissed", f"op{k}")
                for k in range(8)
            )
        )
        assert sorted(r.changed for r in results) == [False] * 7 + [True]
        assert [e.kind for e in store.events(seq0)] == ["decided"]


def test_dismissed_zones_rule_and_restart(tmp_path: Path) -> None:
    db = tmp_path / "a.db"
    with AlertStore(db) as store:
        small = make_alert(1, error_m=4.2)  # 2 x 4.2 < 10: the 10 m floor
        large = candidate(2, error_m=12.0)  # 2 x 12 = 24 m
        unknown = make_alert(3, error_m=None)  # error unknown: 25 m
        blind = candidate(4, positioned=False)  # no position: nothing to suppress
        other = make_alert(5, mission_id="other-mission")
        kept = make_alert(6)  # not dismissed
        undone = candidate(7)  # dismissed, then confirmed
        for a in (small, large, unknown, blind, other, kept, undone):
            store.add(a)
        for a in (small, large, unknown, blind, other, undone):
            store.decide(a.alert_id, "dismissed", "ana")
        store.decide(undone.alert_id, "confirmed", "bo")
        expected = [(*small.position, 10.0), (*large.position, 24.0), (*unknown.position, 25.0)]
        assert store.dismissed_zones("test-mission") == expected
        assert store.dismissed_zones("other-mission") == [(*other.position, 10.0)]
        assert store.dismissed_zones("nothing") == []
    with AlertStore(db) as store:
        assert store.dismissed_zones("test-mission") == expected
        # a dismissed alert whose position is found later suppresses from then on
        assert store.attach_position(blind.alert_id, (-35.3, 149.2), 2.0, "found")
        assert store.dismissed_zones("test-mission")[-1] == (-35.3, 149.2, 10.0)


def test_only_confirmed_alerts_not_dismissed_are_still_to_go_to_the_autopilot(
    tmp_path: Path,
) -> None:
    with AlertStore(tmp_path / "a.db") as store:
        plain, cand, promoted, by_operator, dismissed = (
            make_alert(1),
            candidate(2),
            candidate(3),
            candidate(4),
            make_alert(5),
        )
        for a in (plain, cand, promoted, by_operator, dismissed):
            store.add(a)
        store.promote(promoted.alert_id, "held")
        store.decide(by_operator.alert_id, "confirmed", "ana")
        store.decide(dismissed.alert_id, "dismissed", "ana")
        expected = [plain.alert_id, promoted.alert_id, by_operator.alert_id]
        assert [a.alert_id for a in store.undelivered("mavlink_loiter")] == expected
        assert [a.alert_id for a in store.undelivered(CHANNEL_MAVLINK, repeats=3)] == expected
        # known fixes keep every target, candidates and dismissed ones included
        assert set(store.known_fixes("test-mission")) == {1, 2, 3, 4, 5}


def test_subscribers_see_tier_changes_and_decisions_with_who_and_why(tmp_path: Path) -> None:
    with AlertStore(tmp_path / "a.db") as store:
        a, b = candidate(1), candidate(2)
        store.add(a)
        store.add(b)
        sub = store.subscribe()
        store.promote(a.alert_id, "held 4 s")
        store.discard(b.alert_id, "glint")
        store.decide(b.alert_id, "dismissed", "ana")
        events = sub.get(timeout=2.0)
        assert [(e.kind, e.alert.alert_id, e.by, e.detail) for e in events] == [
            ("confirmed", a.alert_id, None, "held 4 s"),
            ("discarded", b.alert_id, None, "glint"),
            ("decided", b.alert_id, "ana", "dismissed"),
        ]
        assert events[-1].alert.dismissed


def test_drone_track_is_bounded_per_mission(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(store_module, "DRONE_POINTS_KEPT", 50)
    monkeypatch.setattr(store_module, "_TRIM_EVERY", 10)
    db = tmp_path / "a.db"
    with AlertStore(db) as store:
        for i in range(200):
            store.record_drone("m", 1000.0 + i, -35.36 + i * 1e-5, 149.16, 60.0)
            if i % 20 == 0:
                store.record_drone("other", 1000.0 + i, -35.0, 149.0, None)
        track = store.drone_track("m")
        assert 50 <= len(track) <= 60
        assert track[-1] == (1199.0, pytest.approx(-35.36 + 199e-5), 149.16, 60.0)
        assert [p.t for p in track] == sorted(p.t for p in track)
        assert len(store.drone_track("other")) == 10  # the other mission keeps its own
        assert [p.t for p in store.drone_track("m", since=1195.0)] == [
            1195.0,
            1196.0,
            1197.0,
            1198.0,
            1199.0,
        ]
        last, points = store.drone_points_after("m")
        assert len(points) == len(track)
        store.record_drone("m", 1200.0, -35.37, 149.17, 61.0)
        newer, points = store.drone_points_after("m", last)
        assert newer > last and points == [(1200.0, -35.37, 149.17, 61.0)]
        assert store.drone_points_after("m", newer) == (newer, [])
        for bad in (
            (float("nan"), -35.0, 149.0, 1.0),
            (1.0, 95.0, 149.0, 1.0),
            (1.0, -35.0, 149.0, float("inf")),
        ):
            with pytest.raises(ValueError):
                store.record_drone("m", *bad)
    with AlertStore(db) as store:
        assert store.drone_track("m")[-1].t == 1200.0


def test_mission_area_and_current_mission(tmp_path: Path) -> None:
    db = tmp_path / "a.db"
    with AlertStore(db) as store:
        assert store.current_mission() is None and store.mission_area("m") is None
        store.set_mission_area("first", AREA)
        assert store.current_mission() == "first"
        store.add(make_alert(1, mission_id="second"))
        assert store.current_mission() == "second"
        store.record_drone("third", 1.0, -35.0, 149.0, 10.0)
        assert store.current_mission() == "third"
        store.set_mission_area("first", AREA[:3])  # replaced
        assert store.mission_area("first") == AREA[:3]
        for bad in (
            [],
            AREA[:2],
            [(-35.0, 149.0), (91.0, 149.0), (-35.1, 149.1)],
            [(-35.0, float("nan"))] * 3,
        ):
            with pytest.raises(ValueError):
                store.set_mission_area("first", bad)
        assert store.mission_area("first") == AREA[:3]
    with AlertStore(db) as store:
        assert store.mission_area("first") == AREA[:3]


def test_fresh_and_upgraded_stores_have_the_same_tables(tmp_path: Path) -> None:
    def columns(path: Path) -> dict[str, list[str]]:
        with sqlite3.connect(path) as conn:
            tables = [
                r[0]
                for r in conn.execute(
                    "SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name"
                )
            ]
            result = {
                t: sorted(r[1] for r in conn.execute(f"PRAGMA table_info({t})")) for t in tables
            }
        conn.close()
        return result

    AlertStore(tmp_path / "fresh.db").close()
    old = tmp_path / "old.db"
    with sqlite3.connect(old) as conn:
        from test_alert_store import _SCHEMA_1  # the oldest schema there was

        conn.executescript(_SCHEMA_1)
    conn.close()
    AlertStore(old).close()
    assert columns(tmp_path / "fresh.db") == columns(old)


def test_a_change_returns_the_alert_as_its_own_commit_left_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Another operator's dismissal commits (from another connection) right after this
    store's confirmation or acknowledgement: the caller gets the alert as its own change left
    it, never a card contradicting what it just did."""
    db = tmp_path / "a.db"
    with AlertStore(db) as feed_side, AlertStore(db) as other_feed:
        alert = candidate(1)
        feed_side.add(alert)
        notify = feed_side._notify

        def dismissal_right_after_commit() -> None:
            notify()
            if other_feed.get(alert.alert_id).decision != "dismissed":
                other_feed.record_decision(alert.alert_id, "dismissed", "bo")

        monkeypatch.setattr(feed_side, "_notify", dismissal_right_after_commit)
        decided = feed_side.record_decision(alert.alert_id, "confirmed", "ana")
        assert decided.changed
        assert (decided.alert.decision, decided.alert.decided_by) == ("confirmed", "ana")
        assert decided.alert.tier == "confirmed"
        assert feed_side.get(alert.alert_id).decision == "dismissed"  # bo's came after

        monkeypatch.setattr(feed_side, "_notify", notify)
        second = candidate(2)
        feed_side.add(second)
        monkeypatch.setattr(
            feed_side,
            "_notify",
            lambda: (notify(), other_feed.record_decision(second.alert_id, "dismissed", "bo")),
        )
        acked = feed_side.acknowledge(second.alert_id, "ana")
        assert acked.ack_by == "ana" and acked.decision is None
        assert feed_side.get(second.alert_id).dismissed
        monkeypatch.setattr(feed_side, "_notify", notify)
