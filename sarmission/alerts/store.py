"""Durable alert store on SQLite.

A confirmed alert must survive a crash: the database runs in WAL mode with ``synchronous=FULL``,
so :meth:`AlertStore.add` returns only once the alert is on disk. Every change (new alert,
operator acknowledgement, a command accepted or refused by the autopilot, an alert sent on a
channel without acknowledgement, a position found after the alert) also appends a row to an
``events`` log; :meth:`AlertStore.subscribe` follows that log, which is how the operator feed
learns of changes, including ones written by another process on the same file.

What the store says of the autopilot is what is known, per alert and channel: a command's answer
(``acks``: time, MAV_RESULT and reason; result 0 is acceptance, i.e. delivered) or, for a
STATUSTEXT, which MAVLink never acknowledges, how often it was sent (``sends``: count, first and
last time). It never calls a STATUSTEXT delivered.

The file is marked with an SQLite ``application_id`` and a schema version (``user_version``).
A file that is not an SQLite database, belongs to another application, or is damaged raises
:class:`~sarmission.errors.SarmissionError` and is left untouched. A store of an older schema is
upgraded in place when opened (schema 2 added the ``position`` event; schema 3 replaced
``deliveries`` by ``acks`` and ``sends``: an old "delivered" STATUSTEXT became "sent 1 time",
since that was all that was known).
"""

from __future__ import annotations

import json
import sqlite3
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from sarmission.alerts.model import (
    UNACKNOWLEDGED_CHANNELS,
    Alert,
    Refusal,
    Sends,
    check_position,
)
from sarmission.errors import SarmissionError

#: "SARA" in ASCII, stored in the database header to recognise our files.
APPLICATION_ID = 0x53415241
SCHEMA_VERSION = 3

#: ``ack``: an operator acknowledged the alert; ``delivered`` / ``refused``: the autopilot
#: accepted / refused a command for it; ``sent``: it went out once more on a channel without
#: acknowledgement.
EventKind = Literal["new", "ack", "delivered", "refused", "sent", "position"]
_EVENT_KINDS = {
    2: ("new", "ack", "delivered", "position"),
    3: ("new", "ack", "delivered", "refused", "sent", "position"),
}


def _events_table(name: str, schema: int = SCHEMA_VERSION) -> str:
    """The event log's table definition (of ``schema``), under ``name``."""
    kinds = ", ".join(f"'{k}'" for k in _EVENT_KINDS[schema])
    return f"""
CREATE TABLE {name} (
    seq      INTEGER PRIMARY KEY AUTOINCREMENT,
    kind     TEXT NOT NULL CHECK (kind IN ({kinds})),
    alert_id TEXT NOT NULL REFERENCES alerts (alert_id),
    time     REAL NOT NULL
)"""


_ACKS_AND_SENDS = """
CREATE TABLE acks (
    alert_id TEXT NOT NULL REFERENCES alerts (alert_id),
    channel  TEXT NOT NULL,
    time     REAL NOT NULL,
    result   INTEGER NOT NULL,
    reason   TEXT NOT NULL DEFAULT '',
    PRIMARY KEY (alert_id, channel)
) WITHOUT ROWID;
CREATE TABLE sends (
    alert_id TEXT NOT NULL REFERENCES alerts (alert_id),
    channel  TEXT NOT NULL,
    count    INTEGER NOT NULL CHECK (count > 0),
    first    REAL NOT NULL,
    last     REAL NOT NULL,
    PRIMARY KEY (alert_id, channel)
) WITHOUT ROWID
"""


_SCHEMA = """
CREATE TABLE alerts (
    seq           INTEGER PRIMARY KEY AUTOINCREMENT,
    alert_id      TEXT NOT NULL UNIQUE,
    mission_id    TEXT NOT NULL,
    target_id     INTEGER NOT NULL,
    class_name    TEXT NOT NULL,
    score         REAL NOT NULL,
    lock_time     REAL NOT NULL,
    frame_index   INTEGER NOT NULL,
    lat           REAL,
    lon           REAL,
    position_note TEXT NOT NULL,
    error_m       REAL,
    target_hae_m  REAL,
    drone_lat     REAL,
    drone_lon     REAL,
    drone_alt_m   REAL,
    track         TEXT NOT NULL,
    pixel_track   TEXT NOT NULL,
    thumbnail     BLOB,
    ack_time      REAL,
    ack_by        TEXT,
    added_time    REAL NOT NULL
);
CREATE INDEX alerts_by_target ON alerts (mission_id, target_id);
""" + _ACKS_AND_SENDS + ";" + _events_table("events")

_UNACKED_SQL = ", ".join(f"'{c}'" for c in sorted(UNACKNOWLEDGED_CHANNELS))

#: Statements taking a store from schema ``n`` to ``n + 1``.
_UPGRADES: dict[int, str] = {
    1: _events_table("events_2", 2) + """;
INSERT INTO events_2 (seq, kind, alert_id, time) SELECT seq, kind, alert_id, time FROM events;
DROP TABLE events;
ALTER TABLE events_2 RENAME TO events
""",
    # Schema 2 recorded a STATUSTEXT as "delivered" once sent: all that was known is one send.
    2: _ACKS_AND_SENDS + f""";
INSERT INTO acks (alert_id, channel, time, result)
    SELECT alert_id, channel, time, 0 FROM deliveries WHERE channel NOT IN ({_UNACKED_SQL});
INSERT INTO sends (alert_id, channel, count, first, last)
    SELECT alert_id, channel, 1, time, time FROM deliveries WHERE channel IN ({_UNACKED_SQL});
DROP TABLE deliveries;
""" + _events_table("events_3", 3) + """;
INSERT INTO events_3 (seq, kind, alert_id, time) SELECT seq, kind, alert_id, time FROM events;
DROP TABLE events;
ALTER TABLE events_3 RENAME TO events
""",
}

def _execute_script(conn: sqlite3.Connection, script: str) -> None:
    """Run ``;``-separated statements inside the open transaction (``executescript`` would
    commit it first)."""
    for statement in script.split(";"):
        if statement.strip():
            conn.execute(statement)


_SELECT = """
SELECT a.alert_id, a.mission_id, a.target_id, a.class_name, a.score, a.lock_time,
       a.frame_index, a.lat, a.lon, a.position_note, a.error_m, a.target_hae_m,
       a.drone_lat, a.drone_lon, a.drone_alt_m, a.track, a.pixel_track, a.thumbnail,
       a.ack_time, a.ack_by
FROM alerts a
"""
#: Alert ids per query of acks and sends (below SQLite's limit on bound parameters).
_ID_BATCH = 500


@dataclass(frozen=True)
class AlertEvent:
    """One change in the store: ``kind`` is ``"new"``, ``"ack"`` (operator), ``"delivered"`` /
    ``"refused"`` (a command accepted / refused by the autopilot), ``"sent"`` (sent once more on
    a channel without acknowledgement) or ``"position"`` (a position attached to an alert that
    had none); ``seq`` is its position in the store's event log; ``alert`` is the alert as it
    is now."""

    seq: int
    kind: EventKind
    alert: Alert


class AlertStore:
    """Alerts in an SQLite file at ``path`` (created if missing). Thread-safe: one connection,
    serialised by a lock. ``poll_interval_s`` bounds how late subscribers see changes written by
    another process (changes made through this object wake them at once)."""

    def __init__(self, path: str | Path, poll_interval_s: float = 0.25) -> None:
        self.path = Path(path)
        self.poll_interval_s = poll_interval_s
        if self.path.is_dir():
            raise SarmissionError(f"alert store {self.path} is a directory, not a database file")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.RLock()
        self._changed = threading.Condition()
        self._generation = 0
        self._closed = False
        try:
            self._conn = sqlite3.connect(
                self.path, check_same_thread=False, isolation_level=None, timeout=10.0
            )
        except sqlite3.Error as exc:
            raise SarmissionError(f"cannot open alert store {self.path}: {exc}") from exc
        try:
            self._open_schema()
        except sqlite3.DatabaseError as exc:
            self._conn.close()
            raise SarmissionError(
                f"{self.path} is not a usable sarmission alert store ({exc}); "
                "it was left untouched - move it away or choose another path"
            ) from exc
        except SarmissionError:
            self._conn.close()
            raise

    # ------------------------------------------------------------------ opening

    def _open_schema(self) -> None:
        conn = self._conn
        # Inspect before writing anything, so a foreign or damaged file is never modified.
        app_id = conn.execute("PRAGMA application_id").fetchone()[0]
        version = conn.execute("PRAGMA user_version").fetchone()[0]
        n_objects = conn.execute("SELECT count(*) FROM sqlite_master").fetchone()[0]
        fresh = app_id == 0 and version == 0 and n_objects == 0
        if not fresh:
            if app_id != APPLICATION_ID:
                raise SarmissionError(
                    f"{self.path} is an SQLite database of another application "
                    f"(application_id {app_id:#x}, {n_objects} schema objects); "
                    "refusing to use or overwrite it"
                )
            if version > SCHEMA_VERSION:
                raise SarmissionError(
                    f"{self.path} has alert store schema {version}, newer than this "
                    f"version of sarmission supports ({SCHEMA_VERSION})"
                )
            check = conn.execute("PRAGMA quick_check").fetchone()[0]
            if check != "ok":
                raise SarmissionError(f"{self.path} is damaged: {check}")
        mode = conn.execute("PRAGMA journal_mode=WAL").fetchone()[0]
        if mode.lower() != "wal":
            raise SarmissionError(f"{self.path}: cannot enable WAL journaling (got {mode!r})")
        conn.execute("PRAGMA synchronous=FULL")
        conn.execute("PRAGMA foreign_keys=ON")
        if fresh:
            with self._transaction():
                # Another process may have created it between our check and the write lock.
                if conn.execute("PRAGMA user_version").fetchone()[0] == 0:
                    _execute_script(conn, _SCHEMA)
                    conn.execute(f"PRAGMA application_id={APPLICATION_ID}")
                    conn.execute(f"PRAGMA user_version={SCHEMA_VERSION}")
        elif version < SCHEMA_VERSION:
            with self._transaction():
                # Another process may have upgraded it between our check and the write lock.
                version = conn.execute("PRAGMA user_version").fetchone()[0]
                for step in range(version, SCHEMA_VERSION):
                    _execute_script(conn, _UPGRADES[step])
                conn.execute(f"PRAGMA user_version={SCHEMA_VERSION}")

    @contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        """A write transaction (``BEGIN IMMEDIATE``); committed, hence durable, on exit."""
        with self._lock:
            self._conn.execute("BEGIN IMMEDIATE")
            try:
                yield self._conn
            except BaseException:
                self._conn.execute("ROLLBACK")
                raise
            self._conn.execute("COMMIT")

    def _notify(self) -> None:
        with self._changed:
            self._generation += 1
            self._changed.notify_all()

    # ------------------------------------------------------------------ writing

    def add(self, alert: Alert) -> bool:
        """Store ``alert``; durable on disk when this returns. Idempotent on ``alert_id``:
        adding an id already stored changes nothing and returns False (True when stored now)."""
        with self._transaction() as conn:
            cur = conn.execute(
                "INSERT OR IGNORE INTO alerts (alert_id, mission_id, target_id, class_name, "
                "score, lock_time, frame_index, lat, lon, position_note, error_m, target_hae_m, "
                "drone_lat, drone_lon, drone_alt_m, track, pixel_track, thumbnail, ack_time, "
                "ack_by, added_time) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, "
                "?, ?, ?, ?)",
                (
                    alert.alert_id,
                    alert.mission_id,
                    int(alert.target_id),
                    alert.class_name,
                    float(alert.score),
                    float(alert.lock_time),
                    int(alert.frame_index),
                    *(alert.position if alert.position is not None else (None, None)),
                    alert.position_note,
                    alert.error_m,
                    alert.target_hae_m,
                    *(alert.drone_position if alert.drone_position is not None else (None,) * 3),
                    json.dumps([list(p) for p in alert.track]),
                    json.dumps([list(p) for p in alert.pixel_track]),
                    alert.thumbnail,
                    alert.ack_time,
                    alert.ack_by,
                    time.time(),
                ),
            )
            if cur.rowcount == 0:
                return False
            conn.executemany(
                "INSERT INTO acks (alert_id, channel, time, result, reason) "
                "VALUES (?, ?, ?, ?, ?)",
                [(alert.alert_id, ch, t, 0, "") for ch, t in alert.delivered.items()]
                + [(alert.alert_id, ch, r.time, r.result, r.reason)
                   for ch, r in alert.refused.items() if ch not in alert.delivered],
            )
            conn.executemany(
                "INSERT INTO sends (alert_id, channel, count, first, last) VALUES (?, ?, ?, ?, ?)",
                [(alert.alert_id, ch, n.count, n.first, n.last)
                 for ch, n in alert.sent.items() if n.count > 0],
            )
            self._log(conn, "new", alert.alert_id)
        self._notify()
        return True

    def acknowledge(self, alert_id: str, by: str, when: float | None = None) -> Alert:
        """Mark the alert acknowledged by ``by`` at ``when`` (default now) and return it.
        The first acknowledgement stands; later ones change nothing. Unknown id: KeyError."""
        if not by.strip():
            raise ValueError("acknowledge needs the name of who acknowledged")
        with self._transaction() as conn:
            self._require(conn, alert_id)
            cur = conn.execute(
                "UPDATE alerts SET ack_time = ?, ack_by = ? "
                "WHERE alert_id = ? AND ack_time IS NULL",
                (time.time() if when is None else when, by.strip(), alert_id),
            )
            if cur.rowcount:
                self._log(conn, "ack", alert_id)
        if cur.rowcount:
            self._notify()
        alert = self.get(alert_id)
        assert alert is not None
        return alert

    def record_ack(self, alert_id: str, channel: str, result: int, reason: str = "",
                   when: float | None = None) -> bool:
        """Record the autopilot's answer to the command sent for the alert on ``channel``:
        ``result`` is its MAV_RESULT (or MAV_MISSION_RESULT; 0, accepted, means delivered),
        ``reason`` the readable refusal. An acceptance is final (its first time is kept); a
        refusal is replaced by a later answer. Returns whether anything changed.

        A channel without acknowledgement (STATUSTEXT) has none to record: ValueError.
        Unknown id: KeyError."""
        if channel in UNACKNOWLEDGED_CHANNELS:
            raise ValueError(f"channel {channel!r} has no acknowledgement; use record_sent")
        result = int(result)
        with self._transaction() as conn:
            self._require(conn, alert_id)
            cur = conn.execute(
                "INSERT INTO acks (alert_id, channel, time, result, reason) "
                "VALUES (?, ?, ?, ?, ?) ON CONFLICT (alert_id, channel) DO UPDATE SET "
                "time = excluded.time, result = excluded.result, reason = excluded.reason "
                "WHERE acks.result != 0",
                (alert_id, channel, time.time() if when is None else when, result,
                 "" if result == 0 else reason),
            )
            if cur.rowcount:
                self._log(conn, "delivered" if result == 0 else "refused", alert_id)
        if cur.rowcount:
            self._notify()
        return bool(cur.rowcount)

    def mark_delivered(self, alert_id: str, channel: str, when: float | None = None) -> None:
        """Record that the autopilot accepted the command of ``channel`` (see
        :meth:`record_ack`); the first time is kept. Unknown id: KeyError; a channel without
        acknowledgement: ValueError."""
        self.record_ack(alert_id, channel, 0, "", when)

    def record_sent(self, alert_id: str, channel: str, when: float | None = None) -> Sends:
        """Record one more send of the alert on ``channel`` (e.g. a STATUSTEXT, which has no
        acknowledgement) at ``when`` (default now); returns the channel's sends so far.
        Unknown id: KeyError."""
        t = time.time() if when is None else when
        with self._transaction() as conn:
            self._require(conn, alert_id)
            conn.execute(
                "INSERT INTO sends (alert_id, channel, count, first, last) "
                "VALUES (?, ?, 1, ?, ?) ON CONFLICT (alert_id, channel) DO UPDATE SET "
                "count = count + 1, last = max(last, excluded.last)",
                (alert_id, channel, t, t),
            )
            count, first, last = conn.execute(
                "SELECT count, first, last FROM sends WHERE alert_id = ? AND channel = ?",
                (alert_id, channel),
            ).fetchone()
            self._log(conn, "sent", alert_id)
        self._notify()
        return Sends(count, first, last)

    def attach_position(self, alert_id: str, position: tuple[float, float],
                        error_m: float | None, note: str) -> bool:
        """Give an alert stored without a position its ``(lat, lon)``, error and note, durably.

        For a target first alerted while it could not be geolocated and located later. Only the
        first position is attached: True when it was attached now, False when the alert already
        had one. Unknown id: KeyError; a position not finite or out of range: ValueError."""
        lat, lon = check_position(position)
        with self._transaction() as conn:
            self._require(conn, alert_id)
            cur = conn.execute(
                "UPDATE alerts SET lat = ?, lon = ?, error_m = ?, position_note = ? "
                "WHERE alert_id = ? AND lat IS NULL",
                (lat, lon, error_m, note, alert_id),
            )
            if cur.rowcount:
                self._log(conn, "position", alert_id)
        if cur.rowcount:
            self._notify()
        return bool(cur.rowcount)

    @staticmethod
    def _require(conn: sqlite3.Connection, alert_id: str) -> None:
        if conn.execute("SELECT 1 FROM alerts WHERE alert_id = ?", (alert_id,)).fetchone() is None:
            raise KeyError(alert_id)

    @staticmethod
    def _log(conn: sqlite3.Connection, kind: EventKind, alert_id: str) -> None:
        conn.execute(
            "INSERT INTO events (kind, alert_id, time) VALUES (?, ?, ?)",
            (kind, alert_id, time.time()),
        )

    # ------------------------------------------------------------------ reading

    def get(self, alert_id: str) -> Alert | None:
        """The alert with this id, or None."""
        rows = self._query(_SELECT + "WHERE a.alert_id = ?", (alert_id,))
        return rows[0] if rows else None

    def list(self, since: float | None = None) -> list[Alert]:
        """All alerts in the order they were added; with ``since``, only those whose
        ``lock_time`` is at or after it (POSIX seconds)."""
        if since is None:
            return self._query(_SELECT + "ORDER BY a.seq", ())
        return self._query(_SELECT + "WHERE a.lock_time >= ? ORDER BY a.seq", (since,))

    def count(self) -> int:
        """Number of stored alerts."""
        with self._lock:
            return self._conn.execute("SELECT count(*) FROM alerts").fetchone()[0]

    def undelivered(self, channel: str, repeats: int = 1) -> list[Alert]:
        """Alerts still to go out on ``channel``, oldest first (to resend after a link loss or a
        restart): on a channel without acknowledgement (STATUSTEXT) those sent fewer than
        ``repeats`` times; on any other, those the autopilot has not answered (a refusal is an
        answer, and is not sent again)."""
        if channel in UNACKNOWLEDGED_CHANNELS:
            return self._query(
                _SELECT + "WHERE coalesce((SELECT s.count FROM sends s WHERE s.alert_id = "
                "a.alert_id AND s.channel = ?), 0) < ? ORDER BY a.seq",
                (channel, int(repeats)),
            )
        return self._query(
            _SELECT + "WHERE NOT EXISTS (SELECT 1 FROM acks k "
            "WHERE k.alert_id = a.alert_id AND k.channel = ?) ORDER BY a.seq",
            (channel,),
        )

    def known_targets(self, mission_id: str) -> dict[int, tuple[float, float] | None]:
        """Targets already alerted in this mission: target id -> latest known ``(lat, lon)``
        (None if none of its alerts had a position). A restarted controller seeds its target
        registry from this so it does not announce the same person twice."""
        with self._lock:
            rows = self._conn.execute(
                "SELECT target_id, lat, lon FROM alerts WHERE mission_id = ? ORDER BY seq",
                (mission_id,),
            ).fetchall()
        known: dict[int, tuple[float, float] | None] = {}
        for target_id, lat, lon in rows:
            if lat is not None and lon is not None:
                known[target_id] = (lat, lon)
            else:
                known.setdefault(target_id, None)
        return known

    def known_fixes(self, mission_id: str
                    ) -> dict[int, tuple[float, float, float | None] | None]:
        """Like :meth:`known_targets`, with the 1-sigma error of each latest position:
        target id -> ``(lat, lon, error_m)`` (error None when unknown), or None without a
        position. The restarted registry matches new fixes against each by its own error."""
        with self._lock:
            rows = self._conn.execute(
                "SELECT target_id, lat, lon, error_m FROM alerts WHERE mission_id = ? "
                "ORDER BY seq", (mission_id,),
            ).fetchall()
        known: dict[int, tuple[float, float, float | None] | None] = {}
        for target_id, lat, lon, error_m in rows:
            if lat is not None and lon is not None:
                known[target_id] = (lat, lon, error_m)
            else:
                known.setdefault(target_id, None)
        return known

    def events(self, after: int = 0) -> list[AlertEvent]:
        """Events with ``seq > after``, oldest first."""
        with self._lock:
            rows = self._conn.execute(
                "SELECT seq, kind, alert_id FROM events WHERE seq > ? ORDER BY seq", (after,)
            ).fetchall()
            alerts = {a.alert_id: a for a in self._alerts_by_id({r[2] for r in rows})}
        return [AlertEvent(seq, kind, alerts[alert_id]) for seq, kind, alert_id in rows]

    def last_event_seq(self) -> int:
        """The newest event's ``seq`` (0 when there is none)."""
        with self._lock:
            return self._conn.execute("SELECT coalesce(max(seq), 0) FROM events").fetchone()[0]

    def _alerts_by_id(self, ids: set[str]) -> list[Alert]:
        if not ids:
            return []
        marks = ",".join("?" * len(ids))
        return self._query(_SELECT + f"WHERE a.alert_id IN ({marks})", tuple(ids))

    def _query(self, sql: str, params: tuple) -> list[Alert]:
        with self._lock:
            rows = self._conn.execute(sql, params).fetchall()
            ids = [r[0] for r in rows]
            acks: dict[str, list[tuple]] = {}
            sends: dict[str, list[tuple]] = {}
            for i in range(0, len(ids), _ID_BATCH):
                batch = ids[i : i + _ID_BATCH]
                marks = ",".join("?" * len(batch))
                for row in self._conn.execute(
                    "SELECT alert_id, channel, time, result, reason FROM acks "
                    f"WHERE alert_id IN ({marks})", batch,
                ):
                    acks.setdefault(row[0], []).append(row[1:])
                for row in self._conn.execute(
                    "SELECT alert_id, channel, count, first, last FROM sends "
                    f"WHERE alert_id IN ({marks})", batch,
                ):
                    sends.setdefault(row[0], []).append(row[1:])
        return [_row_to_alert(r, acks.get(r[0], []), sends.get(r[0], [])) for r in rows]

    # ------------------------------------------------------------------ following

    def subscribe(self, after: int | None = None) -> Subscription:
        """Follow the event log from ``after`` (default: from now on). See :class:`Subscription`."""
        return Subscription(self, self.last_event_seq() if after is None else after)

    def _current_generation(self) -> int:
        """Counter bumped by each change made through this object."""
        with self._changed:
            return self._generation

    def _wait_for_change(self, generation: int, timeout: float) -> None:
        """Block until the generation moves past ``generation``, the store is closed, or
        ``timeout`` seconds pass."""
        with self._changed:
            if self._generation == generation and not self._closed:
                self._changed.wait(timeout)

    @property
    def closed(self) -> bool:
        """True after :meth:`close`."""
        return self._closed

    def close(self) -> None:
        """Close the database and wake every subscriber."""
        with self._lock:
            if not self._closed:
                self._closed = True
                self._conn.close()
        self._notify()

    def __enter__(self) -> AlertStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Subscription:
    """A cursor on a store's event log. :meth:`get` blocks until there are events after the
    cursor (or the timeout passes), returns them and moves the cursor past them."""

    def __init__(self, store: AlertStore, after: int) -> None:
        self._store = store
        self.cursor = after
        self._closed = False

    def get(self, timeout: float | None = None) -> list[AlertEvent]:
        """New events, oldest first; ``[]`` after ``timeout`` seconds (None: wait for ever) or
        once the subscription or the store is closed."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while not (self._closed or self._store.closed):
            generation = self._store._current_generation()
            events = self._store.events(self.cursor)
            if events:
                self.cursor = events[-1].seq
                return events
            wait = self._store.poll_interval_s
            if deadline is not None:
                wait = min(wait, deadline - time.monotonic())
                if wait <= 0:
                    break
            self._store._wait_for_change(generation, wait)
        return []

    def close(self) -> None:
        """Stop following; a blocked :meth:`get` returns within one poll interval."""
        self._closed = True

    def __iter__(self) -> Iterator[AlertEvent]:
        """Events as they come, until the subscription or the store is closed."""
        while not (self._closed or self._store.closed):
            yield from self.get(timeout=self._store.poll_interval_s)

    def __enter__(self) -> Subscription:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _row_to_alert(row: tuple, acks: list[tuple], sends: list[tuple]) -> Alert:
    (alert_id, mission_id, target_id, class_name, score, lock_time, frame_index, lat, lon,
     position_note, error_m, target_hae_m, d_lat, d_lon, d_alt, track, pixel_track, thumbnail,
     ack_time, ack_by) = row  # fmt: skip
    return Alert(
        alert_id=alert_id,
        mission_id=mission_id,
        target_id=target_id,
        class_name=class_name,
        score=score,
        lock_time=lock_time,
        frame_index=frame_index,
        position=None if lat is None else (lat, lon),
        position_note=position_note,
        error_m=error_m,
        target_hae_m=target_hae_m,
        drone_position=None if d_lat is None else (d_lat, d_lon, d_alt),
        track=[tuple(p) for p in json.loads(track)],
        pixel_track=[(int(p[0]), p[1], p[2]) for p in json.loads(pixel_track)],
        thumbnail=thumbnail,
        ack_time=ack_time,
        ack_by=ack_by,
        delivered={ch: t for ch, t, result, _ in acks if result == 0},
        refused={ch: Refusal(t, result, reason) for ch, t, result, reason in acks if result != 0},
        sent={ch: Sends(count, first, last) for ch, count, first, last in sends},
    )
