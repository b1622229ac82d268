"""Durable alert store on SQLite.

An alert must survive a crash: the database runs in WAL mode with ``synchronous=FULL``,
so :meth:`AlertStore.add` returns only once the alert is on disk. Every change (new alert,
operator acknowledgement, a command accepted or refused by the autopilot, an alert sent on a
channel without acknowledgement, a position found after the alert, a candidate confirmed or
discarded by the system, an operator's decision) also appends a row to an ``events`` log;
:meth:`AlertStore.subscribe` follows that log, which is how the operator feed learns of changes,
including ones written by another process on the same file.

Tiers and decisions (see :mod:`sarmission.alerts.model`): the controller stores a *candidate*,
then :meth:`~AlertStore.promote` s or :meth:`~AlertStore.discard` s it; an operator
:meth:`~AlertStore.decide` s to confirm or dismiss any alert. Each is one transaction, so of
two racing changes the one committed first is applied first and both are in the log; which
decision is newer is their order in the log, never a comparison of clocks (the feed, the
controller and the operator's device may disagree on the time). An operator's dismissal is never
undone by the system: :meth:`~AlertStore.promote` after it changes nothing. Only confirmed alerts
not dismissed are still to go to the autopilot (:meth:`~AlertStore.undelivered`).
:meth:`~AlertStore.dismissed_zones` gives the places dismissed alerts suppress.

For the operator's map the store also keeps the drone's track (the newest
:data:`DRONE_POINTS_KEPT` points per mission, about 5.5 hours at 1 Hz) and each mission's area.

What the store says of the autopilot is what is known, per alert and channel: a command's answer
(``acks``: time, MAV_RESULT and reason; result 0 is acceptance, i.e. delivered) or, for a
STATUSTEXT, which MAVLink never acknowledges, how often it was sent (``sends``: count, first and
last time). It never calls a STATUSTEXT delivered.

The file is marked with an SQLite ``application_id`` and a schema version (``user_version``).
A file that is not an SQLite database, belongs to another application, or is damaged raises
:class:`~sarmission.errors.SarmissionError` and is left untouched. A store of an older schema is
upgraded in place when opened (schema 2 added the ``position`` event; schema 3 replaced
``deliveries`` by ``acks`` and ``sends``: an old "delivered" STATUSTEXT became "sent 1 time",
since that was all that was known; schema 4 added tiers, operator decisions, the ``confirmed``,
``discarded`` and ``decided`` events with who and why, the drone's track and mission areas: an
older alert is a confirmed one without a decision, as it was; schema 5 added the time of the
latest fix a position rests on, unknown for older alerts; schema 6 the target's drift, likewise;
schema 7 the calibrated confidence of a confirmation, unknown for older alerts; schema 8
its range and the evidence's log-odds, with the ``rated`` event, unknown for older alerts).
"""

from __future__ import annotations

import json
import math
import sqlite3
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, NamedTuple

from sarmission.alerts.model import (
    DECISIONS,
    UNACKNOWLEDGED_CHANNELS,
    Alert,
    Decision,
    Refusal,
    Sends,
    check_drift,
    check_position,
    dismiss_radius_m,
    format_confidence,
)
from sarmission.alerts.operator_calibration import OffsetBelief, Rating, check_logit
from sarmission.errors import SarmissionError

#: "SARA" in ASCII, stored in the database header to recognise our files.
APPLICATION_ID = 0x53415241
SCHEMA_VERSION = 8

#: Seconds a change waits for another connection's write lock before giving up.
BUSY_TIMEOUT_S = 10.0

#: Drone track points kept per mission (older ones are dropped): 5.5 hours at 1 Hz.
DRONE_POINTS_KEPT = 20_000
#: The track is trimmed every this many points, so it holds at most KEPT + this many.
_TRIM_EVERY = 100
#: Most vertices a mission area may have.
MAX_AREA_VERTICES = 10_000

#: ``ack``: an operator acknowledged the alert; ``delivered`` / ``refused``: the autopilot
#: accepted / refused a command for it; ``sent``: it went out once more on a channel without
#: acknowledgement; ``confirmed``: a candidate became confirmed (by the system, or by the
#: operator named in ``by``); ``discarded``: the system gave up on a candidate; ``decided``: an
#: operator confirmed or dismissed it (``detail``); ``rated``: its confidence was rated again
#: after an operator's decision on another alert of its mission (``detail``: the new rating).
EventKind = Literal[
    "new",
    "ack",
    "delivered",
    "refused",
    "sent",
    "position",
    "confirmed",
    "discarded",
    "decided",
    "rated",
]
_EVENT_KINDS = {
    2: ("new", "ack", "delivered", "position"),
    3: ("new", "ack", "delivered", "refused", "sent", "position"),
    4: (
        "new",
        "ack",
        "delivered",
        "refused",
        "sent",
        "position",
        "confirmed",
        "discarded",
        "decided",
    ),
}
_EVENT_KINDS[5] = _EVENT_KINDS[6] = _EVENT_KINDS[7] = _EVENT_KINDS[4]
_EVENT_KINDS[8] = (*_EVENT_KINDS[7], "rated")


def _events_table(name: str, schema: int = SCHEMA_VERSION) -> str:
    """The event log's table definition (of ``schema``), under ``name``. From schema 4 an event
    says who made it (``by``: an operator's name, NULL for the system) and why (``detail``)."""
    kinds = ", ".join(f"'{k}'" for k in _EVENT_KINDS[schema])
    extra = ",\n    by       TEXT,\n    detail   TEXT NOT NULL DEFAULT ''" if schema >= 4 else ""
    return f"""
CREATE TABLE {name} (
    seq      INTEGER PRIMARY KEY AUTOINCREMENT,
    kind     TEXT NOT NULL CHECK (kind IN ({kinds})),
    alert_id TEXT NOT NULL REFERENCES alerts (alert_id),
    time     REAL NOT NULL{extra}
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

#: The drone's track (``t``: the controller's time; ``recorded``: the store's) and mission areas
#: (``polygon``: JSON ``[[lat, lon], ...]``), for the operator's map.
_MAP_TABLES = """
CREATE TABLE drone (
    seq        INTEGER PRIMARY KEY AUTOINCREMENT,
    mission_id TEXT NOT NULL,
    t          REAL NOT NULL,
    lat        REAL NOT NULL,
    lon        REAL NOT NULL,
    alt_m      REAL,
    recorded   REAL NOT NULL
);
CREATE INDEX drone_by_mission ON drone (mission_id, seq);
CREATE TABLE areas (
    mission_id TEXT PRIMARY KEY,
    polygon    TEXT NOT NULL,
    set_time   REAL NOT NULL
) WITHOUT ROWID
"""

_SCHEMA = (
    """
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
    added_time    REAL NOT NULL,
    tier          TEXT NOT NULL DEFAULT 'confirmed' CHECK (tier IN ('candidate', 'confirmed')),
    evidence      TEXT NOT NULL DEFAULT '',
    confirmed_at  REAL,
    discarded     TEXT,
    discarded_at  REAL,
    decision      TEXT CHECK (decision IN ('confirmed', 'dismissed')),
    decided_by    TEXT,
    decided_at    REAL,
    position_time REAL,
    drift_north   REAL,
    drift_east    REAL,
    confidence    REAL CHECK (confidence BETWEEN 0 AND 1),
    confidence_low  REAL CHECK (confidence_low BETWEEN 0 AND 1),
    confidence_high REAL CHECK (confidence_high BETWEEN 0 AND 1),
    evidence_logit  REAL
);
CREATE INDEX alerts_by_target ON alerts (mission_id, target_id);
"""
    + _ACKS_AND_SENDS
    + ";"
    + _events_table("events")
    + ";"
    + _MAP_TABLES
)

#: The channels without acknowledgement when schema 3 came (the upgrade moves their rows).
_UNACKED_SQL = "'mavlink'"

#: Statements taking a store from schema ``n`` to ``n + 1``.
_UPGRADES: dict[int, str] = {
    1: _events_table("events_2", 2)
    + """;
INSERT INTO events_2 (seq, kind, alert_id, time) SELECT seq, kind, alert_id, time FROM events;
DROP TABLE events;
ALTER TABLE events_2 RENAME TO events
""",
    # Schema 2 recorded a STATUSTEXT as "delivered" once sent: all that was known is one send.
    2: _ACKS_AND_SENDS
    + f""";
INSERT INTO acks (alert_id, channel, time, result)
    SELECT alert_id, channel, time, 0 FROM deliveries WHERE channel NOT IN ({_UNACKED_SQL});
INSERT INTO sends (alert_id, channel, count, first, last)
    SELECT alert_id, channel, 1, time, time FROM deliveries WHERE channel IN ({_UNACKED_SQL});
DROP TABLE deliveries;
"""
    + _events_table("events_3", 3)
    + """;
INSERT INTO events_3 (seq, kind, alert_id, time) SELECT seq, kind, alert_id, time FROM events;
DROP TABLE events;
ALTER TABLE events_3 RENAME TO events
""",
    # Schema 3 knew only confirmed alerts and no operator decisions: that is what they stay.
    3: """
ALTER TABLE alerts ADD COLUMN tier TEXT NOT NULL DEFAULT 'confirmed'
    CHECK (tier IN ('candidate', 'confirmed'));
ALTER TABLE alerts ADD COLUMN evidence TEXT NOT NULL DEFAULT '';
ALTER TABLE alerts ADD COLUMN confirmed_at REAL;
ALTER TABLE alerts ADD COLUMN discarded TEXT;
ALTER TABLE alerts ADD COLUMN discarded_at REAL;
ALTER TABLE alerts ADD COLUMN decision TEXT CHECK (decision IN ('confirmed', 'dismissed'));
ALTER TABLE alerts ADD COLUMN decided_by TEXT;
ALTER TABLE alerts ADD COLUMN decided_at REAL;
"""
    + _events_table("events_4", 4)
    + """;
INSERT INTO events_4 (seq, kind, alert_id, time) SELECT seq, kind, alert_id, time FROM events;
DROP TABLE events;
ALTER TABLE events_4 RENAME TO events;
"""
    + _MAP_TABLES,
    # Schema 4 kept no time for a position: the lock's it stays.
    4: "ALTER TABLE alerts ADD COLUMN position_time REAL",
    # Schema 5 kept no drift: unknown it stays.
    5: """
ALTER TABLE alerts ADD COLUMN drift_north REAL;
ALTER TABLE alerts ADD COLUMN drift_east REAL
""",
    # Schema 6 kept no confidence: unknown it stays.
    6: "ALTER TABLE alerts ADD COLUMN confidence REAL CHECK (confidence BETWEEN 0 AND 1)",
    # Schema 7 kept no range nor log-odds: unknown they stay; the log learns ``rated``.
    7: """
ALTER TABLE alerts ADD COLUMN confidence_low REAL CHECK (confidence_low BETWEEN 0 AND 1);
ALTER TABLE alerts ADD COLUMN confidence_high REAL CHECK (confidence_high BETWEEN 0 AND 1);
ALTER TABLE alerts ADD COLUMN evidence_logit REAL;
"""
    + _events_table("events_8", 8)
    + """;
INSERT INTO events_8 (seq, kind, alert_id, time, by, detail)
    SELECT seq, kind, alert_id, time, by, detail FROM events;
DROP TABLE events;
ALTER TABLE events_8 RENAME TO events
""",
}


def is_busy(exc: sqlite3.Error) -> bool:
    """Whether ``exc`` is SQLite giving up waiting for a lock another connection holds (e.g.
    another process in the middle of a write, or holding the file exclusively)."""
    code = getattr(exc, "sqlite_errorcode", None)
    if code is None:
        return "locked" in str(exc) or "busy" in str(exc)
    return code & 0xFF in (sqlite3.SQLITE_BUSY, sqlite3.SQLITE_LOCKED)


def is_read_only(exc: sqlite3.Error) -> bool:
    """Whether ``exc`` is SQLite refusing to write the file (permissions, an immutable file,
    a read-only mount)."""
    code = getattr(exc, "sqlite_errorcode", None)
    if code is None:
        return "readonly" in str(exc)
    return code & 0xFF == sqlite3.SQLITE_READONLY


def describe_failure(exc: sqlite3.Error) -> str:
    """What went wrong with the store, in words for an operator or a log line."""
    if is_busy(exc):
        return "is busy: another process holds a lock on it"
    if is_read_only(exc):
        return f"cannot be written ({exc})"
    return f"failed ({exc})"


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
       a.ack_time, a.ack_by, a.tier, a.evidence, a.confirmed_at, a.discarded, a.discarded_at,
       a.decision, a.decided_by, a.decided_at, a.position_time, a.drift_north, a.drift_east,
       a.confidence, a.confidence_low, a.confidence_high, a.evidence_logit
FROM alerts a
"""
#: Alerts still to go to the autopilot: confirmed and not dismissed by an operator.
_FOR_AUTOPILOT = "a.tier = 'confirmed' AND a.decision IS NOT 'dismissed'"
#: Alert ids per query of acks and sends (below SQLite's limit on bound parameters).
_ID_BATCH = 500


@dataclass(frozen=True)
class AlertEvent:
    """One change in the store: ``kind`` is ``"new"``, ``"ack"`` (operator), ``"delivered"`` /
    ``"refused"`` (a command accepted / refused by the autopilot), ``"sent"`` (sent once more on
    a channel without acknowledgement), ``"position"`` (a position attached to an alert that
    had none, or a placed alert's position refined), ``"confirmed"`` / ``"discarded"`` (a
    candidate's tier settled), ``"decided"`` (an operator's decision) or ``"rated"`` (its
    confidence rated again after an operator's decision on another alert); ``seq`` is its position
    in the store's event log; ``alert`` is the alert as it is now; ``by`` the operator who made
    the change (None: the system or unknown); ``detail`` the evidence, reason or decision of
    that change."""

    seq: int
    kind: EventKind
    alert: Alert
    by: str | None = None
    detail: str = ""


class OperatorDecision(NamedTuple):
    """One decision from an alert's history: ``time`` (the store's clock), ``decision``, ``by``."""

    time: float
    decision: Decision
    by: str


class Decided(NamedTuple):
    """What :meth:`AlertStore.record_decision` did: the alert as this decision left it (read
    in its own transaction, so a racing decision committed after it does not show), and
    whether the decision changed anything (False: the alert already had this decision)."""

    alert: Alert
    changed: bool


class DronePoint(NamedTuple):
    """One point of the drone's track: the controller's time ``t`` (POSIX s), WGS84 degrees and
    altitude above home (None when unknown)."""

    t: float
    lat: float
    lon: float
    alt_m: float | None


class AlertStore:
    """Alerts in an SQLite file at ``path`` (created if missing). Thread-safe: one connection
    for changes and one for reads, each serialised by its own lock, so that a change waiting
    for another process's write lock (up to :data:`BUSY_TIMEOUT_S`) does not hold up readers
    (WAL lets them read what is committed meanwhile). ``poll_interval_s`` bounds how late
    subscribers see changes written by another process (changes made through this object wake
    them at once)."""

    def __init__(self, path: str | Path, poll_interval_s: float = 0.25) -> None:
        self.path = Path(path)
        self.poll_interval_s = poll_interval_s
        if self.path.is_dir():
            raise SarmissionError(f"alert store {self.path} is a directory, not a database file")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.RLock()  # the writing connection, ``_conn``
        self._read_lock = threading.RLock()  # the reading connection, ``_reader``
        self._writer: int | None = None  # the thread in a write transaction, if any
        self._changed = threading.Condition()
        self._generation = 0
        self._closed = False
        try:
            self._conn = sqlite3.connect(
                self.path, check_same_thread=False, isolation_level=None, timeout=BUSY_TIMEOUT_S
            )
        except sqlite3.Error as exc:
            raise SarmissionError(f"cannot open alert store {self.path}: {exc}") from exc
        try:
            self._open_schema()
        except sqlite3.DatabaseError as exc:
            self._conn.close()
            if is_busy(exc):
                raise SarmissionError(
                    f"alert store {self.path} is busy: another process holds a lock on it "
                    f"({exc}); try again once that process is done or has released it"
                ) from exc
            if is_read_only(exc):
                raise SarmissionError(
                    f"alert store {self.path} cannot be written ({exc}); check the permissions "
                    "and attributes of the file and its folder, and that the disk is writable"
                ) from exc
            raise SarmissionError(
                f"{self.path} is not a usable sarmission alert store ({exc}); "
                "it was left untouched - move it away or choose another path"
            ) from exc
        except SarmissionError:
            self._conn.close()
            raise
        try:
            self._reader = sqlite3.connect(
                self.path, check_same_thread=False, isolation_level=None, timeout=BUSY_TIMEOUT_S
            )
            self._reader.execute("PRAGMA query_only=ON")
        except sqlite3.Error as exc:
            self._conn.close()
            raise SarmissionError(f"cannot open alert store {self.path}: {exc}") from exc

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
        self._check_writable(version)
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

    def _check_writable(self, version: int) -> None:
        """Refuse a file SQLite can open but not write (read-only permissions, an immutable
        file, a read-only mount), which would otherwise fail at the first alert: rewrite its
        ``user_version`` unchanged and roll back, so nothing is modified. A file another
        process is writing right now is writable; its lock is not waited for."""
        conn = self._conn
        conn.execute("PRAGMA busy_timeout=0")
        try:
            conn.execute("BEGIN IMMEDIATE")
            try:
                conn.execute(f"PRAGMA user_version={int(version)}")
            finally:
                conn.execute("ROLLBACK")
        except sqlite3.OperationalError as exc:
            if not is_busy(exc):
                raise
        finally:
            conn.execute(f"PRAGMA busy_timeout={int(BUSY_TIMEOUT_S * 1000)}")

    @contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        """A write transaction (``BEGIN IMMEDIATE``); committed, hence durable, on exit. If
        the commit fails, the transaction is rolled back (nothing of it is recorded) and the
        error raised, so the connection is left ready for the next one."""
        with self._lock:
            self._conn.execute("BEGIN IMMEDIATE")
            self._writer = threading.get_ident()
            try:
                yield self._conn
                self._conn.execute("COMMIT")
            except BaseException:
                if self._conn.in_transaction:
                    self._conn.execute("ROLLBACK")
                raise
            finally:
                self._writer = None

    @contextmanager
    def _reading(self) -> Iterator[sqlite3.Connection]:
        """The connection to read with: inside this thread's write transaction its own (which
        sees what the transaction wrote), else the reading one, which never waits for the
        writing one's lock."""
        if self._writer == threading.get_ident():
            yield self._conn
            return
        with self._read_lock:
            yield self._reader

    def _notify(self) -> None:
        with self._changed:
            self._generation += 1
            self._changed.notify_all()

    # ------------------------------------------------------------------ writing

    def add(self, alert: Alert) -> bool:
        """Store ``alert`` (a candidate or a confirmed alert, by its ``tier``); durable on disk
        when this returns. Idempotent on ``alert_id``: adding an id already stored changes
        nothing and returns False (True when stored now)."""
        with self._transaction() as conn:
            cur = conn.execute(
                "INSERT OR IGNORE INTO alerts (alert_id, mission_id, target_id, class_name, "
                "score, lock_time, frame_index, lat, lon, position_note, error_m, target_hae_m, "
                "drone_lat, drone_lon, drone_alt_m, track, pixel_track, thumbnail, ack_time, "
                "ack_by, added_time, tier, evidence, confirmed_at, discarded, discarded_at, "
                "decision, decided_by, decided_at, position_time, drift_north, drift_east, "
                "confidence, confidence_low, confidence_high, evidence_logit) VALUES (?, ?, ?, ?, "
                "?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, "
                "?, ?, ?, ?, ?)",
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
                    alert.tier,
                    alert.evidence,
                    alert.confirmed_at,
                    alert.discarded,
                    alert.discarded_at,
                    alert.decision,
                    alert.decided_by,
                    alert.decided_at,
                    alert.position_time,
                    *(alert.drift_ne if alert.drift_ne is not None else (None, None)),
                    alert.confidence,
                    *(alert.confidence_range or (None, None)),
                    alert.evidence_logit,
                ),
            )
            if cur.rowcount == 0:
                return False
            conn.executemany(
                "INSERT INTO acks (alert_id, channel, time, result, reason) VALUES (?, ?, ?, ?, ?)",
                [(alert.alert_id, ch, t, 0, "") for ch, t in alert.delivered.items()]
                + [
                    (alert.alert_id, ch, r.time, r.result, r.reason)
                    for ch, r in alert.refused.items()
                    if ch not in alert.delivered
                ],
            )
            conn.executemany(
                "INSERT INTO sends (alert_id, channel, count, first, last) VALUES (?, ?, ?, ?, ?)",
                [
                    (alert.alert_id, ch, n.count, n.first, n.last)
                    for ch, n in alert.sent.items()
                    if n.count > 0
                ],
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
            alert = self._committed(alert_id)
        if cur.rowcount:
            self._notify()
        return alert

    def record_ack(
        self, alert_id: str, channel: str, result: int, reason: str = "", when: float | None = None
    ) -> bool:
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
                (
                    alert_id,
                    channel,
                    time.time() if when is None else when,
                    result,
                    "" if result == 0 else reason,
                ),
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

    def attach_position(
        self,
        alert_id: str,
        position: tuple[float, float],
        error_m: float | None,
        note: str,
        position_time: float | None = None,
        drift_ne: tuple[float, float] | None = None,
    ) -> bool:
        """Give an alert stored without a position its ``(lat, lon)``, error and note, durably.

        For a target first alerted while it could not be geolocated and located later. Only the
        first position is attached: True when it was attached now, False when the alert already
        had one. Unknown id: KeyError; a position not finite or out of range: ValueError."""
        return self._set_position(
            alert_id, position, error_m, note, position_time, drift_ne, "lat IS NULL", ""
        )

    def refine_position(
        self,
        alert_id: str,
        position: tuple[float, float],
        error_m: float | None,
        note: str,
        detail: str = "",
        position_time: float | None = None,
        drift_ne: tuple[float, float] | None = None,
    ) -> bool:
        """Move a placed alert to a better ``(lat, lon)`` with its error, note and drift (m/s north,
        east; None: unknown), durably: the target's position once more fixes came in. Logged as a
        ``position`` event with ``detail`` (e.g. how far it moved). An alert without a position (see
        :meth:`attach_position`), one an operator dismissed (its dismissed zone stays where the
        operator saw it) or one the system discarded is left as it is: returns False. Unknown id:
        KeyError; a position not finite or out of range: ValueError."""
        return self._set_position(
            alert_id,
            position,
            error_m,
            note,
            position_time,
            drift_ne,
            "lat IS NOT NULL AND discarded IS NULL AND decision IS NOT 'dismissed'",
            detail,
        )

    def _set_position(
        self,
        alert_id: str,
        position: tuple[float, float],
        error_m: float | None,
        note: str,
        position_time: float | None,
        drift_ne: tuple[float, float] | None,
        condition: str,
        detail: str,
    ) -> bool:
        """The position update of :meth:`attach_position` and :meth:`refine_position`, made
        only where the alert meets ``condition`` (SQL); logged as a ``position`` event."""
        lat, lon = check_position(position)
        drift = (None, None) if drift_ne is None else check_drift(drift_ne)
        with self._transaction() as conn:
            self._require(conn, alert_id)
            cur = conn.execute(
                "UPDATE alerts SET lat = ?, lon = ?, error_m = ?, position_note = ?, "
                "position_time = ?, drift_north = ?, drift_east = ? "
                f"WHERE alert_id = ? AND {condition}",
                (lat, lon, error_m, note, position_time, *drift, alert_id),
            )
            if cur.rowcount:
                self._log(conn, "position", alert_id, detail=detail)
        if cur.rowcount:
            self._notify()
        return bool(cur.rowcount)

    # ------------------------------------------------------------------ tiers and decisions

    def promote(
        self,
        alert_id: str,
        evidence: str,
        when: float | None = None,
        evidence_logit: float | None = None,
    ) -> Alert | None:
        """The system confirms a candidate: tier ``confirmed``, ``evidence`` (why), confirmed at
        ``when`` (the controller's time, default now); event ``confirmed``. ``evidence_logit``:
        the log-odds of a person a confidence model read from its evidence (None: no model);
        the alert's confidence is then rated by what the mission's operator decisions have
        taught (:meth:`rating`). Returns the alert,
        or None, changing nothing, when an operator has dismissed it: a dismissal always wins
        over a later promotion. Already confirmed (by the system or an operator): returns it
        unchanged. A candidate the system had discarded is confirmed (its discard reason stays
        in the log). Unknown id: KeyError."""
        t = _finite_time(when)
        z = None if evidence_logit is None else check_logit(evidence_logit)
        with self._transaction() as conn:
            state = self._state(conn, alert_id)
            if state.decision == "dismissed":
                return None
            changed = state.tier != "confirmed"
            if changed:
                rated = (
                    (None,) * 3
                    if z is None
                    else self._mission_belief(conn, state.mission_id).rate(z)
                )
                conn.execute(
                    "UPDATE alerts SET tier = 'confirmed', evidence = ?, confirmed_at = ?, "
                    "confidence = ?, confidence_low = ?, confidence_high = ?, "
                    "evidence_logit = ?, discarded = NULL, discarded_at = NULL "
                    "WHERE alert_id = ?",
                    (evidence, t, *rated, z, alert_id),
                )
                self._log(conn, "confirmed", alert_id, detail=evidence)
            alert = self._committed(alert_id)
        if changed:
            self._notify()
        return alert

    def discard(self, alert_id: str, reason: str, when: float | None = None) -> Alert | None:
        """The system gives up on a candidate: ``discarded`` = ``reason`` (also its
        ``evidence``), at ``when`` (the controller's time, default now); event ``discarded``.
        Returns the alert; None, changing nothing, for a confirmed alert or one an operator
        decided on (the operator's word stands). Already discarded: returns it unchanged.
        Unknown id: KeyError."""
        t = _finite_time(when)
        if not reason.strip():
            raise ValueError("discard needs a reason")
        with self._transaction() as conn:
            state = self._state(conn, alert_id)
            if state.tier == "confirmed" or state.decision is not None:
                return None
            changed = state.discarded is None
            if changed:
                conn.execute(
                    "UPDATE alerts SET discarded = ?, discarded_at = ?, evidence = ? "
                    "WHERE alert_id = ?",
                    (reason, t, reason, alert_id),
                )
                self._log(conn, "discarded", alert_id, detail=reason)
            alert = self._committed(alert_id)
        if changed:
            self._notify()
        return alert

    def decide(
        self, alert_id: str, decision: Decision, by: str, when: float | None = None
    ) -> Alert:
        """An operator's decision on an alert; returns it. See :meth:`record_decision`."""
        return self.record_decision(alert_id, decision, by, when).alert

    def record_decision(
        self, alert_id: str, decision: Decision, by: str, when: float | None = None
    ) -> Decided:
        """Record an operator's ``decision`` (``"confirmed"`` or ``"dismissed"``) by ``by``,
        durably; event ``decided`` (``detail``: the decision). Confirming a candidate also
        confirms it (event ``confirmed`` with ``by``), dismissing one suppresses its place
        (:meth:`dismissed_zones`) and keeps the system from promoting it later. A decision on
        an alert a confidence model rated teaches the mission's calibration: its alerts still
        undecided are rated again (event ``rated`` for each whose confidence changed).

        The alert's current decision repeated changes nothing (``changed`` False, no event).
        A contradicting one (dismiss after confirm, or back) replaces it: operators change their
        minds, and both stay in the log (:meth:`decisions`). Of two racing decisions the one
        committed last is the state; the log has both, in commit order; each caller gets the
        alert as its own decision left it.

        ``decided_at`` is the store's clock: ``when`` is for in-process callers only (tools,
        tests) and must be finite; the feed never passes a client's time. No ordering ever
        compares times, so clock skew between feed, controller and clients changes nothing.
        Unknown id: KeyError; an unknown decision, an empty name or a bad ``when``: ValueError."""
        if decision not in DECISIONS:
            raise ValueError(f"decision must be one of {DECISIONS}, got {decision!r}")
        name = by.strip()
        if not name:
            raise ValueError("a decision needs the name of who made it")
        t = _finite_time(when)
        with self._transaction() as conn:
            state = self._state(conn, alert_id)
            changed = state.decision != decision
            if changed:
                conn.execute(
                    "UPDATE alerts SET decision = ?, decided_by = ?, decided_at = ? "
                    "WHERE alert_id = ?",
                    (decision, name, t, alert_id),
                )
                self._log(conn, "decided", alert_id, by=name, detail=decision)
                if decision == "confirmed" and state.tier != "confirmed":
                    conn.execute(
                        "UPDATE alerts SET tier = 'confirmed', confirmed_at = ?, "
                        "evidence = ?, discarded = NULL, discarded_at = NULL WHERE alert_id = ?",
                        (t, f"confirmed by operator {name}", alert_id),
                    )
                    self._log(
                        conn, "confirmed", alert_id, by=name, detail=f"confirmed by operator {name}"
                    )
                if state.evidence_logit is not None:
                    self._rerate(conn, state.mission_id)
            alert = self._committed(alert_id)
        if changed:
            self._notify()
        return Decided(alert, changed)

    # ------------------------------------------------------------------ calibration

    def rating(self, mission_id: str, evidence_logit: float) -> Rating:
        """The confidence the mission's operator decisions so far give an alert whose evidence
        says log-odds ``evidence_logit`` (:mod:`sarmission.alerts.operator_calibration`)."""
        with self._reading() as conn:
            return self._mission_belief(conn, mission_id).rate(evidence_logit)

    @staticmethod
    def _mission_belief(conn: sqlite3.Connection, mission_id: str) -> OffsetBelief:
        rows = conn.execute(
            "SELECT evidence_logit, decision FROM alerts WHERE mission_id = ? AND "
            "evidence_logit IS NOT NULL AND decision IS NOT NULL ORDER BY seq",
            (mission_id,),
        ).fetchall()
        return OffsetBelief((z, decision == "confirmed") for z, decision in rows)

    def _rerate(self, conn: sqlite3.Connection, mission_id: str) -> None:
        """Rate again the undecided rated alerts of ``mission_id``."""
        belief = self._mission_belief(conn, mission_id)
        rows = conn.execute(
            "SELECT alert_id, evidence_logit, confidence FROM alerts WHERE mission_id = ? "
            "AND evidence_logit IS NOT NULL AND decision IS NULL ORDER BY seq",
            (mission_id,),
        ).fetchall()
        for other, z, before in rows:
            rated = belief.rate(z)
            if before is not None and abs(rated.confidence - before) < 5e-4:
                continue
            conn.execute(
                "UPDATE alerts SET confidence = ?, confidence_low = ?, confidence_high = ? "
                "WHERE alert_id = ?",
                (*rated, other),
            )
            self._log(
                conn,
                "rated",
                other,
                detail=f"{format_confidence(rated.confidence, (rated.low, rated.high))} "
                f"after {belief.decisions} operator decision"
                + ("" if belief.decisions == 1 else "s"),
            )

    # ------------------------------------------------------------------ drone and area

    def record_drone(
        self, mission_id: str, t: float, lat: float, lon: float, alt_m: float | None
    ) -> None:
        """Append a point to the mission's drone track (the controller calls this about once a
        second; nothing is logged as an event, the feed polls :meth:`drone_points_after`). Only
        the newest :data:`DRONE_POINTS_KEPT` points per mission are kept. A time or altitude not
        finite, or a position out of range: ValueError."""
        t = float(t)
        if not math.isfinite(t):
            raise ValueError(f"drone time must be finite, got {t}")
        lat, lon = check_position((lat, lon))
        if alt_m is not None and not math.isfinite(alt_m):
            raise ValueError(f"drone altitude must be finite or None, got {alt_m}")
        with self._transaction() as conn:
            seq = conn.execute(
                "INSERT INTO drone (mission_id, t, lat, lon, alt_m, recorded) "
                "VALUES (?, ?, ?, ?, ?, ?)",
                (mission_id, t, lat, lon, None if alt_m is None else float(alt_m), time.time()),
            ).lastrowid
            if seq is not None and seq % _TRIM_EVERY == 0:
                conn.execute(
                    "DELETE FROM drone WHERE mission_id = ? AND seq <= (SELECT seq FROM drone "
                    "WHERE mission_id = ? ORDER BY seq DESC LIMIT 1 OFFSET ?)",
                    (mission_id, mission_id, DRONE_POINTS_KEPT),
                )

    def drone_track(self, mission_id: str, since: float | None = None) -> list[DronePoint]:
        """The mission's drone track in the order recorded; with ``since``, only points whose
        time ``t`` is at or after it."""
        sql = "SELECT t, lat, lon, alt_m FROM drone WHERE mission_id = ?"
        params: tuple = (mission_id,)
        if since is not None:
            sql, params = sql + " AND t >= ?", (mission_id, since)
        with self._reading() as conn:
            rows = conn.execute(sql + " ORDER BY seq", params).fetchall()
        return [DronePoint(*r) for r in rows]

    def drone_points_after(self, mission_id: str, after: int = 0) -> tuple[int, list[DronePoint]]:
        """For a follower of the track: the newest track ``seq`` of the mission and its points
        recorded after ``after`` (a ``seq`` this returned before; 0: all of them)."""
        with self._reading() as conn:
            rows = conn.execute(
                "SELECT seq, t, lat, lon, alt_m FROM drone WHERE mission_id = ? AND seq > ? "
                "ORDER BY seq",
                (mission_id, after),
            ).fetchall()
        return (rows[-1][0] if rows else after), [DronePoint(*r[1:]) for r in rows]

    def set_mission_area(self, mission_id: str, polygon_latlon: list[tuple[float, float]]) -> None:
        """Store the mission's area: a polygon of ``(lat, lon)`` vertices (at least 3, at most
        :data:`MAX_AREA_VERTICES`, each in range), replacing an earlier one. ValueError
        otherwise."""
        vertices = [check_position(tuple(v)) for v in polygon_latlon]  # type: ignore[arg-type]
        if not 3 <= len(vertices) <= MAX_AREA_VERTICES:
            raise ValueError(
                f"a mission area needs 3 to {MAX_AREA_VERTICES} vertices, got {len(vertices)}"
            )
        with self._transaction() as conn:
            conn.execute(
                "INSERT INTO areas (mission_id, polygon, set_time) VALUES (?, ?, ?) "
                "ON CONFLICT (mission_id) DO UPDATE SET polygon = excluded.polygon, "
                "set_time = excluded.set_time",
                (mission_id, json.dumps([list(v) for v in vertices]), time.time()),
            )

    def mission_area(self, mission_id: str) -> list[tuple[float, float]] | None:
        """The mission's area as ``(lat, lon)`` vertices, or None when none was set."""
        with self._reading() as conn:
            row = conn.execute(
                "SELECT polygon FROM areas WHERE mission_id = ?", (mission_id,)
            ).fetchone()
        return None if row is None else [(v[0], v[1]) for v in json.loads(row[0])]

    # ------------------------------------------------------------------ helpers

    def _state(self, conn: sqlite3.Connection, alert_id: str) -> _TierState:
        """The alert's tier, discard reason, decision, evidence log-odds and mission, read inside
        a write transaction. Unknown id: KeyError."""
        row = conn.execute(
            "SELECT tier, discarded, decision, evidence_logit, mission_id FROM alerts "
            "WHERE alert_id = ?",
            (alert_id,),
        ).fetchone()
        if row is None:
            raise KeyError(alert_id)
        return _TierState(*row)

    def _committed(self, alert_id: str) -> Alert:
        """The alert as the open write transaction leaves it: what a change returns must be
        what it committed, not what another connection committed right after."""
        alert = self.get(alert_id)
        assert alert is not None, alert_id
        return alert

    @staticmethod
    def _require(conn: sqlite3.Connection, alert_id: str) -> None:
        if conn.execute("SELECT 1 FROM alerts WHERE alert_id = ?", (alert_id,)).fetchone() is None:
            raise KeyError(alert_id)

    @staticmethod
    def _log(
        conn: sqlite3.Connection,
        kind: EventKind,
        alert_id: str,
        by: str | None = None,
        detail: str = "",
    ) -> None:
        conn.execute(
            "INSERT INTO events (kind, alert_id, time, by, detail) VALUES (?, ?, ?, ?, ?)",
            (kind, alert_id, time.time(), by, detail),
        )

    # ------------------------------------------------------------------ reading

    def get(self, alert_id: str) -> Alert | None:
        """The alert with this id, or None."""
        rows = self._query(_SELECT + "WHERE a.alert_id = ?", (alert_id,))
        return rows[0] if rows else None

    def list(self, since: float | None = None, mission_id: str | None = None) -> list[Alert]:
        """All alerts in the order they were added; with ``since``, only those whose
        ``lock_time`` is at or after it (POSIX seconds); with ``mission_id``, only that
        mission's."""
        where, params = ["1"], []
        if since is not None:
            where.append("a.lock_time >= ?")
            params.append(since)
        if mission_id is not None:
            where.append("a.mission_id = ?")
            params.append(mission_id)
        return self._query(_SELECT + f"WHERE {' AND '.join(where)} ORDER BY a.seq", tuple(params))

    def pending_candidates(self, mission_id: str) -> list[Alert]:
        """The mission's candidates still open: neither confirmed, nor discarded, nor decided
        on by an operator, oldest first (a restarted controller resumes judging them)."""
        return self._query(
            _SELECT + "WHERE a.mission_id = ? AND a.tier = 'candidate' AND a.discarded IS NULL "
            "AND a.decision IS NULL ORDER BY a.seq",
            (mission_id,),
        )

    def followed_alerts(self, mission_id: str) -> list[Alert]:
        """The mission's placed alerts a position refinement may still move: neither
        discarded nor dismissed by an operator, oldest first (a restarted controller goes on
        following their targets)."""
        return self._query(
            _SELECT + "WHERE a.mission_id = ? AND a.lat IS NOT NULL AND a.discarded IS NULL "
            "AND a.decision IS NOT 'dismissed' ORDER BY a.seq",
            (mission_id,),
        )

    def dismissed_zones(self, mission_id: str) -> list[tuple[float, float, float]]:
        """``(lat, lon, radius_m)`` of every alert of the mission an operator dismissed (and
        has not confirmed since) that has a position, oldest first. The radius is twice the
        alert's error radius, at least 10 m, and 25 m when its error is unknown
        (:func:`~sarmission.alerts.model.dismiss_radius_m`). New alerts within one are
        suppressed for the rest of the mission; it is a query, so it survives restarts."""
        with self._reading() as conn:
            rows = conn.execute(
                "SELECT lat, lon, error_m FROM alerts WHERE mission_id = ? AND "
                "decision = 'dismissed' AND lat IS NOT NULL AND lon IS NOT NULL ORDER BY seq",
                (mission_id,),
            ).fetchall()
        return [(lat, lon, dismiss_radius_m(error_m)) for lat, lon, error_m in rows]

    def decisions(self, alert_id: str) -> list[OperatorDecision]:
        """Every operator decision on the alert, oldest first (the last one is its state)."""
        with self._reading() as conn:
            rows = conn.execute(
                "SELECT time, detail, by FROM events WHERE alert_id = ? AND kind = 'decided' "
                "ORDER BY seq",
                (alert_id,),
            ).fetchall()
        return [OperatorDecision(*r) for r in rows]

    def current_mission(self) -> str | None:
        """The mission the store heard of last (newest alert, drone point or area, by the
        store's clock), None when it holds nothing: the one an operator's map shows."""
        with self._reading() as conn:
            rows = [
                conn.execute(sql).fetchone()
                for sql in (
                    "SELECT added_time, mission_id FROM alerts ORDER BY seq DESC LIMIT 1",
                    "SELECT recorded, mission_id FROM drone ORDER BY seq DESC LIMIT 1",
                    "SELECT set_time, mission_id FROM areas ORDER BY set_time DESC LIMIT 1",
                )
            ]
        known = [r for r in rows if r is not None]
        return max(known)[1] if known else None

    def count(self) -> int:
        """Number of stored alerts."""
        with self._reading() as conn:
            return conn.execute("SELECT count(*) FROM alerts").fetchone()[0]

    def undelivered(self, channel: str, repeats: int = 1) -> list[Alert]:
        """Confirmed alerts not dismissed by an operator still to go out on ``channel``, oldest
        first (to resend after a link loss or a restart): on a channel without acknowledgement
        (STATUSTEXT) those sent fewer than ``repeats`` times; on any other, those the autopilot
        has not answered (a refusal is an answer, and is not sent again). Candidates never go
        to the autopilot."""
        if channel in UNACKNOWLEDGED_CHANNELS:
            return self._query(
                _SELECT + f"WHERE {_FOR_AUTOPILOT} AND coalesce((SELECT s.count FROM sends s "
                "WHERE s.alert_id = a.alert_id AND s.channel = ?), 0) < ? ORDER BY a.seq",
                (channel, int(repeats)),
            )
        return self._query(
            _SELECT + f"WHERE {_FOR_AUTOPILOT} AND NOT EXISTS (SELECT 1 FROM acks k "
            "WHERE k.alert_id = a.alert_id AND k.channel = ?) ORDER BY a.seq",
            (channel,),
        )

    def known_targets(self, mission_id: str) -> dict[int, tuple[float, float] | None]:
        """Targets already alerted in this mission: target id -> latest known ``(lat, lon)``
        (None if none of its alerts had a position). A restarted controller seeds its target
        registry from this so it does not announce the same person twice."""
        with self._reading() as conn:
            rows = conn.execute(
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

    def known_fixes(self, mission_id: str) -> dict[int, tuple[float, float, float | None] | None]:
        """Like :meth:`known_targets`, with the 1-sigma error of each latest position:
        target id -> ``(lat, lon, error_m)`` (error None when unknown), or None without a
        position. The restarted registry matches new fixes against each by its own error."""
        with self._reading() as conn:
            rows = conn.execute(
                "SELECT target_id, lat, lon, error_m FROM alerts WHERE mission_id = ? ORDER BY seq",
                (mission_id,),
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
        with self._reading() as conn:
            rows = conn.execute(
                "SELECT seq, kind, alert_id, by, detail FROM events WHERE seq > ? ORDER BY seq",
                (after,),
            ).fetchall()
            alerts = {a.alert_id: a for a in self._alerts_by_id({r[2] for r in rows})}
        return [
            AlertEvent(seq, kind, alerts[alert_id], by, detail)
            for seq, kind, alert_id, by, detail in rows
        ]

    def last_event_seq(self) -> int:
        """The newest event's ``seq`` (0 when there is none)."""
        with self._reading() as conn:
            return conn.execute("SELECT coalesce(max(seq), 0) FROM events").fetchone()[0]

    def _alerts_by_id(self, ids: set[str]) -> list[Alert]:
        if not ids:
            return []
        marks = ",".join("?" * len(ids))
        return self._query(_SELECT + f"WHERE a.alert_id IN ({marks})", tuple(ids))

    def _query(self, sql: str, params: tuple) -> list[Alert]:
        with self._reading() as conn:
            rows = conn.execute(sql, params).fetchall()
            ids = [r[0] for r in rows]
            acks: dict[str, list[tuple]] = {}
            sends: dict[str, list[tuple]] = {}
            for i in range(0, len(ids), _ID_BATCH):
                batch = ids[i : i + _ID_BATCH]
                marks = ",".join("?" * len(batch))
                for row in conn.execute(
                    "SELECT alert_id, channel, time, result, reason FROM acks "
                    f"WHERE alert_id IN ({marks})",
                    batch,
                ):
                    acks.setdefault(row[0], []).append(row[1:])
                for row in conn.execute(
                    "SELECT alert_id, channel, count, first, last FROM sends "
                    f"WHERE alert_id IN ({marks})",
                    batch,
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
        with self._lock, self._read_lock:
            if not self._closed:
                self._closed = True
                self._conn.close()
                self._reader.close()
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


class _TierState(NamedTuple):
    tier: str
    discarded: str | None
    decision: str | None
    evidence_logit: float | None
    mission_id: str


def _finite_time(when: float | None) -> float:
    """``when`` as a float (default: the store's clock now); ValueError unless finite."""
    t = time.time() if when is None else float(when)
    if not math.isfinite(t):
        raise ValueError(f"time must be finite POSIX seconds, got {when}")
    return t


def _row_to_alert(row: tuple, acks: list[tuple], sends: list[tuple]) -> Alert:
    (alert_id, mission_id, target_id, class_name, score, lock_time, frame_index, lat, lon,
     position_note, error_m, target_hae_m, d_lat, d_lon, d_alt, track, pixel_track, thumbnail,
     ack_time, ack_by, tier, evidence, confirmed_at, discarded, discarded_at, decision,
     decided_by, decided_at, position_time, drift_n, drift_e, confidence, confidence_low,
     confidence_high, evidence_logit) = row  # fmt: skip
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
        tier=tier,
        evidence=evidence,
        confirmed_at=confirmed_at,
        discarded=discarded,
        discarded_at=discarded_at,
        decision=decision,
        decided_by=decided_by,
        decided_at=decided_at,
        position_time=position_time,
        drift_ne=None if drift_n is None else (drift_n, drift_e),
        confidence=confidence,
        confidence_range=None if confidence_low is None else (confidence_low, confidence_high),
        evidence_logit=evidence_logit,
    )
