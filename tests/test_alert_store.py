"""Alert store: durable across a killed process, idempotent, acks, deliveries, restarts, and
clear errors (never overwrites) for files that are not an alert store."""

from __future__ import annotations

import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from alert_samples import make_alert

import sarmission.alerts.store as store_module
from sarmission.alerts.model import CHANNEL_MAVLINK, Refusal, Sends
from sarmission.alerts.store import SCHEMA_VERSION, AlertStore, _events_table
from sarmission.errors import SarmissionError

_WRITER = textwrap.dedent(
    """
    import sys, time
    from sarmission.alerts.model import Alert
    from sarmission.alerts.store import AlertStore

    store = AlertStore(sys.argv[1])
    for i in range(10_000):
        alert = Alert(mission_id="m", target_id=i, class_name="swimmer", score=0.9,
                      lock_time=time.time(), frame_index=i, position=(-35.0 - i * 1e-6, 149.0),
                      thumbnail=bytes(2000))
        store.add(alert)
        print(alert.alert_id, flush=True)  # only after add() has returned
    """
)


def test_alerts_survive_sigkill_of_the_writing_process(tmp_path: Path) -> None:
    db = tmp_path / "alerts.db"
    child = subprocess.Popen(
        [sys.executable, "-c", _WRITER, str(db)], stdout=subprocess.PIPE, text=True
    )
    assert child.stdout is not None
    confirmed = [child.stdout.readline().strip() for _ in range(25)]
    os.kill(child.pid, signal.SIGKILL)  # mid-stream: it is busy adding more
    child.wait(timeout=10)
    assert child.returncode == -signal.SIGKILL
    assert all(confirmed)

    with AlertStore(db) as store:
        stored = {a.alert_id for a in store.list()}
        assert set(confirmed) <= stored
        assert store._conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"


def test_durability_settings(tmp_path: Path) -> None:
    with AlertStore(tmp_path / "a.db") as store:
        assert store._conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
        assert store._conn.execute("PRAGMA synchronous").fetchone()[0] == 2  # FULL
        assert store._conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION


def test_round_trip_and_idempotent_add(tmp_path: Path) -> None:
    alert = make_alert(3)
    with AlertStore(tmp_path / "a.db") as store:
        assert store.add(alert) is True
        assert store.add(alert) is False
        assert store.add(make_alert(3, alert_id=alert.alert_id, score=0.1)) is False
        assert store.count() == 1
        assert store.get(alert.alert_id) == alert
        assert store.get("nope") is None
        assert [e.kind for e in store.events()] == ["new"]
    with AlertStore(tmp_path / "a.db") as store:  # reopened
        assert store.list() == [alert]


def test_alert_without_position_round_trips(tmp_path: Path) -> None:
    alert = make_alert(1, positioned=False, drone_position=None, thumbnail=None)
    with AlertStore(tmp_path / "a.db") as store:
        store.add(alert)
        got = store.get(alert.alert_id)
    assert got == alert
    assert got.position is None and got.position_note.startswith("telemetry stale")


def test_list_since_filters_on_lock_time(tmp_path: Path) -> None:
    with AlertStore(tmp_path / "a.db") as store:
        old, new = make_alert(1, lock_time=1000.0), make_alert(2, lock_time=2000.0)
        store.add(old)
        store.add(new)
        assert store.list() == [old, new]
        assert store.list(since=1500.0) == [new]


def test_acknowledge(tmp_path: Path) -> None:
    with AlertStore(tmp_path / "a.db") as store:
        alert = make_alert(1)
        store.add(alert)
        assert not store.get(alert.alert_id).acknowledged
        acked = store.acknowledge(alert.alert_id, "alice", when=1234.5)
        assert acked.acknowledged and acked.ack_by == "alice" and acked.ack_time == 1234.5
        again = store.acknowledge(alert.alert_id, "bob")  # the first acknowledgement stands
        assert again.ack_by == "alice"
        assert [e.kind for e in store.events()] == ["new", "ack"]
        with pytest.raises(KeyError):
            store.acknowledge("missing", "alice")
        with pytest.raises(ValueError):
            store.acknowledge(alert.alert_id, "  ")


def test_statustext_is_recorded_as_sent_never_as_delivered(tmp_path: Path) -> None:
    db = tmp_path / "a.db"
    alerts = [make_alert(i) for i in range(3)]
    with AlertStore(db) as store:
        for a in alerts:
            store.add(a)
        sub = store.subscribe()
        for t in (50.0, 51.0, 52.0):
            sends = store.record_sent(alerts[1].alert_id, CHANNEL_MAVLINK, when=t)
        assert sends == Sends(3, 50.0, 52.0)
        store.record_sent(alerts[2].alert_id, CHANNEL_MAVLINK, when=53.0)
        assert [e.kind for e in sub.get(timeout=1.0)] == ["sent"] * 4
        with pytest.raises(ValueError, match="no acknowledgement"):
            store.mark_delivered(alerts[1].alert_id, CHANNEL_MAVLINK)
        with pytest.raises(ValueError, match="no acknowledgement"):
            store.record_ack(alerts[1].alert_id, CHANNEL_MAVLINK, 0)
        with pytest.raises(KeyError):
            store.record_sent("missing", CHANNEL_MAVLINK)
    with AlertStore(db) as store:  # after a restart, send again what was sent too few times
        assert [a.alert_id for a in store.undelivered(CHANNEL_MAVLINK, repeats=3)] == [
            alerts[0].alert_id,
            alerts[2].alert_id,
        ]
        assert [a.alert_id for a in store.undelivered(CHANNEL_MAVLINK)] == [alerts[0].alert_id]
        sent = store.get(alerts[1].alert_id)
        assert sent.mavlink_sent and sent.delivered == {} and sent.refused == {}
        assert sent.sent == {CHANNEL_MAVLINK: Sends(3, 50.0, 52.0)}
        doc = sent.to_json_dict()
        assert doc["delivered"] == {} and doc["sent"] == {
            CHANNEL_MAVLINK: {"count": 3, "first": 50.0, "last": 52.0}
        }
        assert not store.get(alerts[0].alert_id).mavlink_sent


def test_command_answers_accepted_and_refused(tmp_path: Path) -> None:
    db = tmp_path / "a.db"
    alerts = [make_alert(i) for i in range(3)]
    reason = "MAV_CMD_DO_REPOSITION refused: MAV_RESULT_FAILED (no reason given)"
    with AlertStore(db) as store:
        for a in alerts:
            store.add(a)
        assert store.record_ack(alerts[1].alert_id, "mavlink_loiter", 0, when=50.0)
        assert not store.record_ack(alerts[1].alert_id, "mavlink_loiter", 0, when=60.0)
        assert not store.record_ack(alerts[1].alert_id, "mavlink_loiter", 4, "late", when=70.0)
        assert store.record_ack(alerts[2].alert_id, "mavlink_loiter", 4, reason, when=55.0)
        with pytest.raises(KeyError):
            store.record_ack("missing", "mavlink_loiter", 0)
        assert [e.kind for e in store.events()] == ["new"] * 3 + ["delivered", "refused"]
    with AlertStore(db) as store:
        # a refusal is an answer: only the unanswered one is to be sent again
        assert [a.alert_id for a in store.undelivered("mavlink_loiter")] == [alerts[0].alert_id]
        assert len(store.undelivered("cot")) == 3
        assert store.get(alerts[1].alert_id).delivered == {"mavlink_loiter": 50.0}
        refused = store.get(alerts[2].alert_id)
        assert refused.delivered == {}
        assert refused.refused == {"mavlink_loiter": Refusal(55.0, 4, reason)}
        assert refused.to_json_dict()["refused"] == {
            "mavlink_loiter": {"time": 55.0, "result": 4, "reason": reason}
        }
        # a later acceptance replaces a refusal, and then stands
        assert store.record_ack(alerts[2].alert_id, "mavlink_loiter", 0, when=80.0)
        assert store.get(alerts[2].alert_id).delivered == {"mavlink_loiter": 80.0}
        assert store.get(alerts[2].alert_id).refused == {}


def test_alert_with_sends_and_answers_round_trips(tmp_path: Path) -> None:
    alert = make_alert(
        4,
        delivered={"mavlink_roi": 12.5},
        refused={"mavlink_loiter": Refusal(13.25, 4, "refused (no reason given)")},
        sent={CHANNEL_MAVLINK: Sends(2, 11.0, 12.0)},
    )
    with AlertStore(tmp_path / "a.db") as store:
        store.add(alert)
        assert store.get(alert.alert_id) == alert
        assert store.list() == [alert]


def test_position_found_later_is_attached_once_and_logged(tmp_path: Path) -> None:
    with AlertStore(tmp_path / "a.db") as store:
        blind, placed = make_alert(1, positioned=False), make_alert(2)
        store.add(blind)
        store.add(placed)
        sub = store.subscribe()
        assert store.attach_position(blind.alert_id, (-35.36, 149.17), 3.5, "ground plane")
        got = store.get(blind.alert_id)
        assert got.position == (-35.36, 149.17) and got.error_m == 3.5
        assert got.position_note == "ground plane"
        assert [(e.kind, e.alert.position) for e in sub.get(timeout=1.0)] == [
            ("position", (-35.36, 149.17))
        ]
        # only the first position is attached; an alert placed from the start keeps its own
        assert not store.attach_position(blind.alert_id, (-35.0, 149.0), 1.0, "again")
        assert not store.attach_position(placed.alert_id, (-35.0, 149.0), 1.0, "again")
        assert store.get(blind.alert_id).position == (-35.36, 149.17)
        assert store.get(placed.alert_id) == placed
        assert store.known_targets("test-mission")[1] == (-35.36, 149.17)
        with pytest.raises(KeyError):
            store.attach_position("missing", (0.0, 0.0), None, "")
        with pytest.raises(ValueError):
            store.attach_position(placed.alert_id, (95.0, 0.0), None, "")
        assert [e.kind for e in store.events()] == ["new", "new", "position"]


#: The alert store as schema 2 wrote it (STATUSTEXT "delivered" once sent).
_SCHEMA_2 = """
CREATE TABLE alerts (
    seq INTEGER PRIMARY KEY AUTOINCREMENT, alert_id TEXT NOT NULL UNIQUE,
    mission_id TEXT NOT NULL, target_id INTEGER NOT NULL, class_name TEXT NOT NULL,
    score REAL NOT NULL, lock_time REAL NOT NULL, frame_index INTEGER NOT NULL, lat REAL,
    lon REAL, position_note TEXT NOT NULL, error_m REAL, target_hae_m REAL, drone_lat REAL,
    drone_lon REAL, drone_alt_m REAL, track TEXT NOT NULL, pixel_track TEXT NOT NULL,
    thumbnail BLOB, ack_time REAL, ack_by TEXT, added_time REAL NOT NULL);
CREATE INDEX alerts_by_target ON alerts (mission_id, target_id);
CREATE TABLE deliveries (
    alert_id TEXT NOT NULL REFERENCES alerts (alert_id), channel TEXT NOT NULL,
    time REAL NOT NULL, PRIMARY KEY (alert_id, channel)) WITHOUT ROWID;
CREATE TABLE events (
    seq INTEGER PRIMARY KEY AUTOINCREMENT,
    kind TEXT NOT NULL CHECK (kind IN ('new', 'ack', 'delivered', 'position')),
    alert_id TEXT NOT NULL REFERENCES alerts (alert_id), time REAL NOT NULL);
PRAGMA application_id = 1396789825;
PRAGMA user_version = 2;
"""

#: Schema 1: schema 2 without the ``position`` event.
_SCHEMA_1 = _SCHEMA_2.replace("'delivered', 'position'", "'delivered'").replace(
    "user_version = 2", "user_version = 1"
)


def _insert_old_alert(
    conn: sqlite3.Connection,
    alert_id: str,
    target_id: int,
    positioned: bool = True,
    ack_by: str | None = None,
) -> None:
    """One alert row as schemas 1-3 wrote it."""
    conn.execute(
        "INSERT INTO alerts (alert_id, mission_id, target_id, class_name, score, lock_time, "
        "frame_index, lat, lon, position_note, error_m, target_hae_m, drone_lat, drone_lon, "
        "drone_alt_m, track, pixel_track, thumbnail, ack_time, ack_by, added_time) VALUES "
        "(?, 'm', ?, 'swimmer', 0.9, 1000.0, 7, ?, ?, ?, ?, NULL, -35.363, 149.165, 60.0, "
        "'[[1.0, -35.36, 149.16]]', '[[7, 10.5, 20.5]]', X'FFD8', ?, ?, 1001.0)",
        (
            alert_id,
            target_id,
            -35.36 if positioned else None,
            149.16 if positioned else None,
            "" if positioned else "telemetry stale (2.4 s)",
            3.5 if positioned else None,
            1100.0 if ack_by else None,
            ack_by,
        ),
    )


def test_schema_1_store_is_upgraded_in_place(tmp_path: Path) -> None:
    db = tmp_path / "a.db"
    with sqlite3.connect(db) as conn:
        conn.executescript(_SCHEMA_1)
        _insert_old_alert(conn, "blind", 1, positioned=False, ack_by="alice")
        conn.executemany(
            "INSERT INTO events (kind, alert_id, time) VALUES (?, ?, ?)",
            [("new", "blind", 1001.0), ("ack", "blind", 1100.0)],
        )
        with pytest.raises(sqlite3.IntegrityError):
            conn.execute(
                "INSERT INTO events (kind, alert_id, time) VALUES ('position', ?, 0)", ("blind",)
            )
    conn.close()
    with AlertStore(db) as store:
        assert store._conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION == 8
        assert [(e.seq, e.kind) for e in store.events()] == [(1, "new"), (2, "ack")]
        assert store.attach_position("blind", (-35.36, 149.17), 3.5, "ground plane")
        assert [(e.seq, e.kind) for e in store.events(after=2)] == [(3, "position")]
        assert store._conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        assert store.get("blind").tier == "confirmed"


#: The alert store as schema 3 wrote it: acks and sends, no tiers or decisions.
_SCHEMA_3 = (
    _SCHEMA_2.replace(
        """CREATE TABLE deliveries (
    alert_id TEXT NOT NULL REFERENCES alerts (alert_id), channel TEXT NOT NULL,
    time REAL NOT NULL, PRIMARY KEY (alert_id, channel)) WITHOUT ROWID;""",
        """CREATE TABLE acks (
    alert_id TEXT NOT NULL REFERENCES alerts (alert_id), channel TEXT NOT NULL,
    time REAL NOT NULL, result INTEGER NOT NULL, reason TEXT NOT NULL DEFAULT '',
    PRIMARY KEY (alert_id, channel)) WITHOUT ROWID;
CREATE TABLE sends (
    alert_id TEXT NOT NULL REFERENCES alerts (alert_id), channel TEXT NOT NULL,
    count INTEGER NOT NULL CHECK (count > 0), first REAL NOT NULL, last REAL NOT NULL,
    PRIMARY KEY (alert_id, channel)) WITHOUT ROWID;""",
    )
    .replace("'delivered', 'position'", "'delivered', 'refused', 'sent', 'position'")
    .replace("user_version = 2", "user_version = 3")
)


def test_schema_3_store_keeps_its_alerts_as_confirmed_without_decisions(tmp_path: Path) -> None:
    db = tmp_path / "old.db"
    with sqlite3.connect(db) as conn:
        conn.executescript(_SCHEMA_3)
        _insert_old_alert(conn, "old0", 5, ack_by="alice")
        _insert_old_alert(conn, "old1", 6)
        conn.execute("INSERT INTO acks VALUES ('old0', 'mavlink_loiter', 1003.0, 0, '')")
        conn.execute("INSERT INTO sends VALUES ('old0', 'mavlink', 2, 1002.0, 1004.0)")
        conn.executemany(
            "INSERT INTO events (kind, alert_id, time) VALUES (?, ?, ?)",
            [
                ("new", "old0", 1001.0),
                ("sent", "old0", 1002.0),
                ("delivered", "old0", 1003.0),
                ("sent", "old0", 1004.0),
                ("new", "old1", 1005.0),
            ],
        )
    conn.close()
    with AlertStore(db) as store:
        assert store._conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
        assert store._conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        old0, old1 = store.list()
        assert (old0.tier, old0.evidence, old0.decision, old0.discarded, old0.ack_by) == (
            "confirmed",
            "",
            None,
            None,
            "alice",
        )
        assert old0.sent[CHANNEL_MAVLINK] == Sends(2, 1002.0, 1004.0)
        assert old0.delivered == {"mavlink_loiter": 1003.0}
        assert [(e.kind, e.by, e.detail) for e in store.events()] == [
            ("new", None, ""),
            ("sent", None, ""),
            ("delivered", None, ""),
            ("sent", None, ""),
            ("new", None, ""),
        ]
        assert [a.alert_id for a in store.undelivered("mavlink_loiter")] == ["old1"]
        # what schema 4 added works on the upgraded file
        assert store.decide("old1", "dismissed", "bo").dismissed
        assert store.dismissed_zones("m") == [(-35.36, 149.16, 10.0)]
        assert store.undelivered("mavlink_loiter") == []
        store.record_drone("m", 1010.0, -35.361, 149.161, 50.0)
        store.set_mission_area("m", [(-35.0, 149.0), (-35.0, 149.1), (-35.1, 149.1)])
        assert [e.kind for e in store.events(after=5)] == ["decided"]
    with AlertStore(db) as store:  # opening the upgraded file again changes nothing
        assert store.get("old1").decided_by == "bo"
        assert store.drone_track("m") == [(1010.0, -35.361, 149.161, 50.0)]
        assert store.mission_area("m") == [(-35.0, 149.0), (-35.0, 149.1), (-35.1, 149.1)]


def test_schema_2_store_keeps_its_data_and_statustext_delivered_becomes_sent_once(
    tmp_path: Path,
) -> None:
    db = tmp_path / "old.db"
    with sqlite3.connect(db) as conn:
        conn.executescript(_SCHEMA_2)
        for i, (tid, ack_by) in enumerate([(5, "alice"), (6, None)]):
            conn.execute(
                "INSERT INTO alerts (alert_id, mission_id, target_id, class_name, score, "
                "lock_time, frame_index, lat, lon, position_note, error_m, target_hae_m, "
                "drone_lat, drone_lon, drone_alt_m, track, pixel_track, thumbnail, ack_time, "
                "ack_by, added_time) VALUES (?, 'm', ?, 'swimmer', 0.9, ?, ?, -35.36, 149.16, "
                "'', 3.5, NULL, -35.363, 149.165, 60.0, '[[1.0, -35.36, 149.16]]', "
                "'[[7, 10.5, 20.5]]', X'FFD8', ?, ?, ?)",
                (f"old{i}", tid, 1000.0 + i, 7 + i, 1100.0 if ack_by else None, ack_by, 1001.0 + i),
            )
        conn.executemany(
            "INSERT INTO deliveries VALUES (?, ?, ?)",
            [("old0", "mavlink", 1002.0), ("old0", "mavlink_loiter", 1003.0)],
        )
        conn.executemany(
            "INSERT INTO events (kind, alert_id, time) VALUES (?, ?, ?)",
            [
                ("new", "old0", 1001.0),
                ("delivered", "old0", 1002.0),
                ("delivered", "old0", 1003.0),
                ("ack", "old0", 1100.0),
                ("new", "old1", 1002.0),
            ],
        )
    conn.close()
    with AlertStore(db) as store:
        assert store._conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
        assert store._conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        old0, old1 = store.list()
        assert (
            old0.alert_id,
            old0.target_id,
            old0.position,
            old0.error_m,
            old0.ack_by,
            old0.thumbnail,
            old0.track,
            old0.pixel_track,
        ) == (
            "old0",
            5,
            (-35.36, 149.16),
            3.5,
            "alice",
            b"\xff\xd8",
            [(1.0, -35.36, 149.16)],
            [(7, 10.5, 20.5)],
        )
        # the STATUSTEXT was sent once, as far as anyone knew; the loiter was acknowledged
        assert old0.sent == {CHANNEL_MAVLINK: Sends(1, 1002.0, 1002.0)}
        assert old0.delivered == {"mavlink_loiter": 1003.0}
        assert CHANNEL_MAVLINK not in old0.to_json_dict()["delivered"]
        assert old1.sent == {} and old1.delivered == {} and not old1.acknowledged
        assert [a.alert_id for a in store.undelivered(CHANNEL_MAVLINK, repeats=5)] == [
            "old0",
            "old1",
        ]
        assert [a.alert_id for a in store.undelivered("mavlink_loiter")] == ["old1"]
        assert [e.kind for e in store.events()] == ["new", "delivered", "delivered", "ack", "new"]
        store.record_sent("old0", CHANNEL_MAVLINK, when=1200.0)  # the new event kinds work
        store.record_ack("old1", "mavlink_loiter", 4, "refused", when=1201.0)
        assert store.get("old0").sent[CHANNEL_MAVLINK] == Sends(2, 1002.0, 1200.0)
        assert [e.kind for e in store.events(after=5)] == ["sent", "refused"]
    with AlertStore(db) as store:  # opening the upgraded file again changes nothing
        assert store.get("old0").sent[CHANNEL_MAVLINK].count == 2


def test_known_targets_per_mission(tmp_path: Path) -> None:
    with AlertStore(tmp_path / "a.db") as store:
        first = make_alert(7)
        store.add(first)
        store.add(make_alert(7, positioned=False))  # a later alert without a fix keeps the old
        store.add(make_alert(8, positioned=False))
        store.add(make_alert(9, mission_id="other-mission"))
        known = store.known_targets("test-mission")
    assert known == {7: first.position, 8: None}


def test_concurrent_writers_and_readers(tmp_path: Path) -> None:
    with AlertStore(tmp_path / "a.db") as store:

        def writer(base: int) -> None:
            for i in range(20):
                alert = make_alert(base + i, thumbnail=None)
                store.add(alert)
                store.acknowledge(alert.alert_id, f"op{base}")
                store.list(since=0.0)

        threads = [threading.Thread(target=writer, args=(k * 100,)) for k in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        alerts = store.list()
        assert len(alerts) == 80 and all(a.acknowledged for a in alerts)
        assert [e.seq for e in store.events()] == list(range(1, 161))


def test_subscription_sees_new_alerts_and_acks(tmp_path: Path) -> None:
    with AlertStore(tmp_path / "a.db") as store:
        store.add(make_alert(1))
        sub = store.subscribe()  # from now on
        alert = make_alert(2)
        threading.Timer(0.2, store.add, (alert,)).start()
        events = sub.get(timeout=30.0)  # wakes on the change; the timeout bounds a hang
        assert [(e.kind, e.alert.alert_id) for e in events] == [("new", alert.alert_id)]
        store.acknowledge(alert.alert_id, "op")
        assert [e.kind for e in sub.get(timeout=1.0)] == ["ack"]
        assert sub.get(timeout=0.1) == []


def test_subscription_sees_writes_from_another_connection(tmp_path: Path) -> None:
    db = tmp_path / "a.db"
    with AlertStore(db, poll_interval_s=0.05) as reader, AlertStore(db) as writer:
        sub = reader.subscribe()
        alert = make_alert(1)
        writer.add(alert)
        events = sub.get(timeout=2.0)
        assert [e.alert.alert_id for e in events] == [alert.alert_id]


def test_not_a_database_is_refused_and_left_alone(tmp_path: Path) -> None:
    junk = tmp_path / "alerts.db"
    junk.write_bytes(b"this is a mission log, not SQLite\n" * 200)
    before = junk.read_bytes()
    with pytest.raises(SarmissionError, match="not a usable sarmission alert store"):
        AlertStore(junk)
    assert junk.read_bytes() == before


def test_foreign_sqlite_database_is_refused_and_left_alone(tmp_path: Path) -> None:
    db = tmp_path / "other.db"
    with sqlite3.connect(db) as conn:
        conn.execute("CREATE TABLE waypoints (lat REAL, lon REAL)")
        conn.execute("INSERT INTO waypoints VALUES (1, 2)")
    conn.close()
    before = db.read_bytes()
    with pytest.raises(SarmissionError, match="another application"):
        AlertStore(db)
    assert db.read_bytes() == before
    assert not (tmp_path / "other.db-wal").exists()


def test_damaged_store_is_refused(tmp_path: Path) -> None:
    db = tmp_path / "a.db"
    with AlertStore(db) as store:
        for i in range(20):
            store.add(make_alert(i))
    data = bytearray(db.read_bytes())
    page = 4096
    data[2 * page : 4 * page] = b"\xab" * (2 * page)
    db.write_bytes(bytes(data))
    with pytest.raises(SarmissionError, match="sarmission alert store|damaged"):
        AlertStore(db)


def test_newer_schema_is_refused(tmp_path: Path) -> None:
    db = tmp_path / "a.db"
    AlertStore(db).close()
    with sqlite3.connect(db) as conn:
        conn.execute(f"PRAGMA user_version={SCHEMA_VERSION + 1}")
    conn.close()
    with pytest.raises(SarmissionError, match="newer"):
        AlertStore(db)


def test_a_store_locked_by_another_process_is_called_busy_not_unusable(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A store another connection holds exclusively is busy, and said so (not "move it
    away"); one another connection is merely writing opens at once (reads go on in WAL)."""
    monkeypatch.setattr(store_module, "BUSY_TIMEOUT_S", 0.3)
    db = tmp_path / "a.db"
    AlertStore(db).close()
    holder = sqlite3.connect(db, isolation_level=None)
    holder.execute("BEGIN IMMEDIATE")  # another process in the middle of a write
    AlertStore(db).close()  # opens: waiting for its write lock would time out and refuse
    holder.execute("ROLLBACK")
    holder.execute("PRAGMA locking_mode=EXCLUSIVE")
    holder.execute("BEGIN EXCLUSIVE")
    holder.execute("COMMIT")  # the lock stays with the holder until it closes
    with pytest.raises(SarmissionError) as refused:
        AlertStore(db)
    assert "is busy: another process holds a lock on it" in str(refused.value)
    assert "not a usable" not in str(refused.value) and "move it away" not in str(refused.value)
    holder.close()
    AlertStore(db).close()


def test_readers_do_not_wait_behind_a_change_waiting_for_another_process(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Another process holds the write lock: a change through the store waits for it, while
    reads (the feed's pages, /healthz) go on at once with what is committed."""
    monkeypatch.setattr(store_module, "BUSY_TIMEOUT_S", 3.0)
    db = tmp_path / "a.db"
    with AlertStore(db) as store:
        alert = make_alert(1)
        store.add(alert)
        holder = sqlite3.connect(db, isolation_level=None)
        holder.execute("BEGIN IMMEDIATE")
        results: list[object] = []
        writer = threading.Thread(
            target=lambda: results.append(store.acknowledge(alert.alert_id, "ana"))
        )
        writer.start()
        time.sleep(0.3)  # the acknowledgement is now waiting for the holder's lock
        assert store.count() == 1 and store.get(alert.alert_id).ack_by is None
        assert [a.alert_id for a in store.list()] == [alert.alert_id]
        assert store.last_event_seq() == 1
        # the writer still waits: reads queued behind it would have outlasted its timeout
        assert writer.is_alive()
        holder.execute("ROLLBACK")
        holder.close()
        writer.join(5.0)
        assert results[0].ack_by == "ana" and store.get(alert.alert_id).ack_by == "ana"


def _make_read_only(path: Path) -> Callable[[], None]:
    """Make ``path`` unwritable (immutable as root, read-only permissions otherwise); returns
    the undo. Skips the test where neither works."""
    if os.geteuid() != 0:
        path.chmod(0o444)
        return lambda: path.chmod(0o644)
    if subprocess.run(["chattr", "+i", str(path)], capture_output=True).returncode != 0:
        pytest.skip("chattr +i is not available here")
    return lambda: subprocess.run(["chattr", "-i", str(path)], check=True)


def test_a_store_that_cannot_be_written_is_refused_when_opened(tmp_path: Path) -> None:
    """Not at the first alert of the mission: at open, in words, and left untouched."""
    db = tmp_path / "a.db"
    with AlertStore(db) as store:
        store.add(make_alert(1))
    before = db.read_bytes()
    undo = _make_read_only(db)
    try:
        with pytest.raises(SarmissionError, match=r"alert store .*a\.db cannot be written"):
            AlertStore(db)
        assert db.read_bytes() == before
    finally:
        undo()
    with AlertStore(db) as store:
        assert store.count() == 1


def test_directory_is_refused(tmp_path: Path) -> None:
    with pytest.raises(SarmissionError, match="directory"):
        AlertStore(tmp_path)


def test_known_fixes_carry_the_error_of_each_latest_position(tmp_path: Path) -> None:
    with AlertStore(tmp_path / "a.db") as store:
        store.add(make_alert(1, error_m=6.5))
        store.add(make_alert(2, positioned=False))
        store.add(make_alert(3, error_m=None))
        known = store.known_fixes("test-mission")
    assert known[1][2] == pytest.approx(6.5) and known[1][:2] == make_alert(1).position
    assert known[2] is None
    assert known[3][2] is None


#: The alert columns each schema added.
_COLUMNS_ADDED = {
    5: ("position_time",),
    6: ("drift_north", "drift_east"),
    7: ("confidence",),
    8: ("confidence_low", "confidence_high", "evidence_logit"),
}


def as_older_schema(db: Path, version: int) -> None:
    """Turn the store ``db`` into one of schema ``version``: the alert columns it did not have
    yet dropped."""
    conn = sqlite3.connect(db)
    for added, columns in _COLUMNS_ADDED.items():
        for column in columns if added > version else ():
            conn.execute(f"ALTER TABLE alerts DROP COLUMN {column}")
    conn.execute(f"PRAGMA user_version = {version}")
    conn.commit()
    conn.close()


def test_schema_4_store_gains_the_time_a_position_rests_on(tmp_path: Path) -> None:
    """A store written before positions had a time (schema 4: the current tables without
    ``position_time``) opens with its alerts' times unknown, and refines with one."""
    db = tmp_path / "old.db"
    with AlertStore(db) as store:
        store.add(make_alert(1, position_time=1.7e9))
    as_older_schema(db, 4)
    with AlertStore(db) as store:
        assert store._conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
        (old,) = store.list()
        assert old.position_time is None and old.position is not None
        assert store.refine_position(old.alert_id, old.position, 2.0, "ground plane", "", 1.8e9)
        assert store.get(old.alert_id).position_time == 1.8e9
        assert store.get(old.alert_id).to_json_dict()["position_time"] == 1.8e9


def test_schema_5_store_gains_the_drift(tmp_path: Path) -> None:
    """A store written before alerts had a drift (schema 5) opens with it unknown; a refinement
    stores one, read back with its course and speed; an impossible one is refused."""
    db = tmp_path / "old.db"
    with AlertStore(db) as store:
        store.add(make_alert(1, drift_ne=(0.3, -0.4)))
        assert store.list()[0].drift_ne == (0.3, -0.4)
    as_older_schema(db, 5)
    with AlertStore(db) as store:
        assert store._conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
        (old,) = store.list()
        assert old.drift_ne is None and old.to_json_dict()["drift"] is None
        assert old.format_drift() == ""
        assert store.refine_position(
            old.alert_id, old.position, 2.0, "ground plane", "", 1.8e9, (-0.3, 0.0)
        )
        drift = store.get(old.alert_id).to_json_dict()["drift"]
        assert drift == {"north_m_s": -0.3, "east_m_s": 0.0, "speed_m_s": 0.3, "course_deg": 180.0}
        assert store.get(old.alert_id).format_drift() == "drifting 0.3 m/s to 180°"
        for bad in ((float("nan"), 0.0), (30.0, 0.0)):
            with pytest.raises(ValueError, match="drift"):
                store.refine_position(
                    old.alert_id, old.position, 2.0, "ground plane", "", 1.9e9, bad
                )
        assert store.get(old.alert_id).drift_ne == (-0.3, 0.0)
        assert store.refine_position(old.alert_id, old.position, 2.0, "ground plane", "", 2e9)
        assert store.get(old.alert_id).drift_ne is None  # an estimate without one


def test_schema_6_store_gains_the_confidence(tmp_path: Path) -> None:
    """A store written before confirmations had a calibrated confidence (schema 6) opens with it
    unknown; a promotion with the evidence's log-odds stores a rated confidence; log-odds not
    finite or absurd are refused and leave the candidate as it was."""
    db = tmp_path / "old.db"
    with AlertStore(db) as store:
        store.add(make_alert(1, confidence=0.25))
        assert store.list()[0].confidence == 0.25
        store.add(make_alert(2, tier="candidate"))
        store.add(make_alert(3, tier="candidate"))
    as_older_schema(db, 6)
    with AlertStore(db) as store:
        assert store._conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
        old = {a.target_id: a for a in store.list()}
        assert old[1].confidence is None and old[1].to_json_dict()["confidence"] is None
        for bad in (float("inf"), 1e6, float("nan")):
            with pytest.raises(ValueError, match="log-odds"):
                store.promote(old[2].alert_id, "evidence", 1.7e9, bad)
        assert store.get(old[2].alert_id).tier == "candidate"
        promoted = store.promote(old[2].alert_id, "evidence", 1.7e9, 0.0)
        assert promoted is not None and promoted.evidence_logit == 0.0
        assert promoted.confidence == pytest.approx(0.5)
        assert store.promote(old[3].alert_id, "evidence", 1.7e9).confidence is None


def test_schema_7_store_gains_the_range_and_the_rated_event(tmp_path: Path) -> None:
    """A store of schema 7 (a confidence without its range, no ``rated`` event) opens with its
    alerts' confidence kept and the range unknown, and its log can then hold ``rated``."""
    db = tmp_path / "old.db"
    with AlertStore(db) as store:
        store.add(make_alert(1, confidence=0.25))
        store.add(make_alert(2, tier="candidate"))
        store.add(make_alert(3, tier="candidate"))
    as_older_schema(db, 7)
    conn = sqlite3.connect(db)
    conn.execute(_events_table("events_old", 7))
    conn.execute("INSERT INTO events_old SELECT * FROM events")
    conn.execute("DROP TABLE events")
    conn.execute("ALTER TABLE events_old RENAME TO events")
    conn.commit()
    conn.close()
    with AlertStore(db) as store:
        assert store._conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
        old = {a.target_id: a for a in store.list()}
        assert old[1].confidence == 0.25 and old[1].confidence_range is None
        assert old[1].evidence_logit is None
        assert [e.kind for e in store.events()] == ["new"] * 3
        store.promote(old[2].alert_id, "evidence", 1.7e9, -1.0)
        store.promote(old[3].alert_id, "evidence", 1.7e9, -1.0)
        store.decide(old[2].alert_id, "confirmed", "ops")
        assert "rated" in [e.kind for e in store.events()]
