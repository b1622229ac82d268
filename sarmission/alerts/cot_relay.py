"""Confirmed alerts to the rescue team's TAK: one Cursor-on-Target marker per target, kept current.

:class:`CotRelay` follows the alert store's event log on its own thread, as the feed does, and
sends every alert the team should see (confirmed, placed, not dismissed by an operator) to each
destination (:class:`~sarmission.alerts.cot.CotSender`: UDP, e.g. the SA multicast group, or a
TAK Server's TCP input):

- when it is confirmed (by the evidence or an operator), placed after its alert, refined, or
  rated again (the operator's decisions on other alerts changed how likely it is a person, which
  its remarks say): the event's uid is per target
  (:attr:`~sarmission.alerts.model.Alert.cot_uid`), so the marker moves rather than multiplies;
- every ``refresh_s`` again, as the store holds it then, so that a TAK client that joins late
  sees it and its stale time (``stale_after_s``) is renewed;
- once an operator dismisses it: a delete event (:func:`~sarmission.alerts.cot.cot_delete`)
  takes the marker off the team's maps.

At start, what the mission's alerts in the store already hold is sent (a restarted run keeps
the team's markers), and the marker of each dismissed alert sent before is deleted (the
dismissal may have come while no relay ran). Each successful send is recorded on the alert's
``cot`` channel (count, first, last), which the feed shows. CoT has no acknowledgement: "sent"
is all that is known. A send that fails everywhere (a TAK Server down), marker or delete, is
tried again at the next change or refresh; its failures are warned about at most every few
seconds and never stop the mission.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence

from sarmission.alerts.cot import CotSender, alert_to_cot, cot_delete
from sarmission.alerts.model import CHANNEL_COT, Alert
from sarmission.alerts.store import AlertStore, Subscription
from sarmission.ratelimit import RateLimitedLog

log = logging.getLogger(__name__)

#: Seconds between two sends of every live marker.
REFRESH_S = 60.0
#: A marker not refreshed for this long goes stale on the team's maps (an hour: a casualty
#: marker must outlive a lost link to the aircraft).
STALE_AFTER_S = 3600.0
#: Store events after which an alert is sent again (or deleted).
_RESEND = frozenset(("new", "confirmed", "position", "decided", "rated"))


def for_the_team(alert: Alert) -> bool:
    """Whether the team's maps show ``alert``: confirmed, placed and not dismissed."""
    return alert.tier == "confirmed" and alert.position is not None and not alert.dismissed


class CotRelay:
    """Sends the store's confirmed alerts of ``mission_id`` as CoT (see the module docstring).

    Args:
        store: the alert store (shared with the controller and the feed; thread-safe).
        senders: one per destination.
        mission_id: whose alerts go out.
        refresh_s: seconds between two sends of every live marker.
        stale_after_s: each event's stale time after its send.
        clock: POSIX time for the events (tests).
    """

    def __init__(
        self,
        store: AlertStore,
        senders: Sequence[CotSender],
        mission_id: str,
        refresh_s: float = REFRESH_S,
        stale_after_s: float = STALE_AFTER_S,
        clock: Callable[[], float] = time.time,
    ) -> None:
        if not refresh_s > 0 or not stale_after_s > 0:
            raise ValueError("refresh_s and stale_after_s must be > 0")
        self.store = store
        self.senders = list(senders)
        self.mission_id = mission_id
        self.refresh_s = refresh_s
        self.stale_after_s = stale_after_s
        self.clock = clock
        self.sent = 0
        self.deleted = 0
        self.failures = RateLimitedLog(log)
        self._live: set[str] = set()  # ids of the alerts the team should see
        self._shown: set[str] = set()  # ids whose marker went out and was not deleted since
        self._state_lock = threading.Lock()  # publish runs on the relay's and callers' threads
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # -- lifecycle ---------------------------------------------------------------------------
    def start(self) -> CotRelay:
        """Send what the store holds for the mission, then follow it on a thread. A marker the
        store says went out before (its ``cot`` sends) counts as shown: if its alert was
        dismissed meanwhile (no relay running), its delete goes out now."""
        subscription = self.store.subscribe()
        alerts = self.store.list(mission_id=self.mission_id)
        with self._state_lock:
            self._shown.update(a.alert_id for a in alerts if CHANNEL_COT in a.sent)
        self.publish(alerts)
        self._thread = threading.Thread(
            target=self._follow, args=(subscription,), name="cot-relay", daemon=True
        )
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop following, once what changed until now has gone out, and close the sockets.
        Calling it again does nothing more."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(10.0)
        for sender in self.senders:
            sender.close()

    def summary(self) -> str:
        """One line for the run's summary."""
        failed = self.failures.total
        return (
            f"TAK (CoT) to {', '.join(s.url for s in self.senders)}: {self.sent} events sent, "
            f"{self.deleted} markers deleted, {len(self._live & self._shown)} live"
            + (f", {failed} sends failed" if failed else "")
        )

    # -- work --------------------------------------------------------------------------------
    def _follow(self, subscription: Subscription) -> None:
        next_refresh = time.monotonic() + self.refresh_s
        with subscription:
            while True:
                stopping = self._stop.is_set() or self.store.closed
                wait = 0.0 if stopping else max(0.0, min(0.5, next_refresh - time.monotonic()))
                events = subscription.get(timeout=wait)  # stopping: what is left, at once
                # each event carries its alert as it is now: one per alert is enough
                changed = {e.alert.alert_id: e.alert for e in events if e.kind in _RESEND}
                self.publish(list(changed.values()))
                if stopping:
                    return
                if time.monotonic() >= next_refresh:
                    self.refresh()
                    next_refresh = time.monotonic() + self.refresh_s

    def publish(self, alerts: Sequence[Alert]) -> None:
        """Send each of ``alerts`` the team should see; delete the marker of each one sent
        before that the team should no longer see (dismissed). A marker counts as shown until
        its delete goes out: a delete that failed is tried again at the next refresh."""
        with self._state_lock:
            for alert in alerts:
                if alert.mission_id != self.mission_id:
                    continue
                if for_the_team(alert):
                    self._live.add(alert.alert_id)
                    if self._send(alert, alert_to_cot(alert, self.clock(), self.stale_after_s)):
                        self._shown.add(alert.alert_id)
                    continue
                self._live.discard(alert.alert_id)
                if alert.alert_id in self._shown and alert.dismissed:
                    if self._send(alert, cot_delete(alert.cot_uid, self.clock())):
                        self._shown.discard(alert.alert_id)
                        self.deleted += 1

    def refresh(self) -> None:
        """Send every marker the team should see again, as the store holds it now (renewing
        its stale time; a change whose send failed goes out now), and retry the deletes that
        failed."""
        with self._state_lock:
            ids = sorted(self._live | self._shown)
        current = [self.store.get(alert_id) for alert_id in ids]
        self.publish([alert for alert in current if alert is not None])

    def _send(self, alert: Alert, event: bytes) -> bool:
        """``event`` to every destination; recorded once if any took it."""
        went = False
        for sender in self.senders:
            try:
                sender.send(event)
                went = True
            except OSError as exc:
                self.failures.event(sender.url, "CoT to %s failed: %s", sender.url, exc)
        if not went:
            return False
        self.sent += 1
        try:
            self.store.record_sent(alert.alert_id, CHANNEL_COT)
        except KeyError:  # not in this store (cannot happen for alerts read from it)
            pass
        return True
