"""Two store connections (two processes' worth: the controller and the operator feed) writing
the same database at once: every write lands, none fails with "database is locked".

Each write reads before it writes (the alert must exist). With a deferred ``BEGIN`` the reader
holds a snapshot; once the other connection commits, upgrading to a write fails at once with
SQLITE_BUSY (SQLite cannot wait there). ``BEGIN IMMEDIATE`` takes the write lock first, so the
other writer waits its turn.
"""

import threading

from alert_samples import make_alert

from sarmission.alerts.store import AlertStore

WRITES = 150


def test_two_connections_writing_at_once_lose_nothing(tmp_path):
    path = tmp_path / "alerts.db"
    with AlertStore(path) as setup:
        alerts = [make_alert(i) for i in (1, 2)]
        for alert in alerts:
            setup.add(alert)
    stores = [AlertStore(path), AlertStore(path)]
    start = threading.Barrier(2)
    errors: list[BaseException] = []

    def write(store: AlertStore, alert_id: str) -> None:
        try:
            start.wait(10.0)
            for _ in range(WRITES):
                store.record_sent(alert_id, "mavlink")
                store.get(alert_id)  # a read between writes, as the feed does
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    threads = [
        threading.Thread(target=write, args=(s, a.alert_id))
        for s, a in zip(stores, alerts, strict=True)
    ]
    try:
        for t in threads:
            t.start()
        for t in threads:
            t.join(120.0)
        assert not any(t.is_alive() for t in threads)
        assert errors == []
        with AlertStore(path) as check:
            for alert in alerts:
                assert check.get(alert.alert_id).sent["mavlink"].count == WRITES
            sent_events = [e for e in check.events() if e.kind == "sent"]
            assert len(sent_events) == 2 * WRITES
    finally:
        for s in stores:
            s.close()
