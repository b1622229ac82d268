"""Action policy: what the autopilot is told about a confirmed target, and its delivery record.

The mission file's ``[actions] policy`` lists, in order, what to do for each new alert:

- ``alert``: STATUSTEXT with severity ALERT (``Alert.statustext()`` in ASCII, at most 50 bytes);
- ``loiter``: MAV_CMD_DO_REPOSITION as COMMAND_INT to the target at the loiter altitude
  (``loiter_altitude_m``, else the survey altitude), switching to guided; one visit at a time
  from the visit plan (:class:`~sarmission.mission.visits.VisitPlanner`: at most one every
  ``visit_interval_s``, nearest first, close neighbours covered), not one per alert;
- ``roi``: MAV_CMD_DO_SET_ROI_LOCATION as COMMAND_INT at the target (camera points at it), and
  ``roi_hold_s`` after the newest ROI was delivered, MAV_CMD_DO_SET_ROI_NONE (:meth:`ActionPolicy.
  tick`): the camera goes back to the survey view. A new target's ROI re-points the camera and
  restarts the hold. With a gimbal reporting its attitude, while the camera is on a target and
  for :data:`ROI_SETTLE_S` after the release, the search pauses (:meth:`ActionPolicy.
  search_paused`): the camera does not look at the survey strip, and off nadir the motion
  front-end sees the waves move. Without a gimbal the ROI only turns the vehicle (the fixed
  camera keeps its view), so the search goes on. Without the pause every false alert
  re-pointed the camera; with it a dense scene costs coverage (docs/experiments.md);
- ``mission``: the pilot's mission is kept: downloaded, the visit plan's targets inserted as
  NAV_LOITER_TIME items (``visit_loiter_s``) before the item the vehicle flies to, uploaded
  whole, and the first visit made current; after the visits the survey resumes where it was.
  At most one insertion every ``visit_interval_s``.

Positional actions are skipped for an alert without a position (there is nowhere to go); when its
position is found later, the alert is announced again with it. When a confirmed alert's position is
refined (:mod:`~sarmission.mission.refinement`), a visit still queued for it goes to the new
position (:meth:`ActionPolicy.refine`); nothing already sent is sent again. Positional actions are
withheld, with the reason on the console, for a position whose error exceeds ``max_error_m`` or
that lies more than ``area_margin_m`` outside the mission area
(:class:`~sarmission.mission.visits.MoveGate`), and while the vehicle may not be taken over
(``takeover``, from the autopilot's HEARTBEAT: disarmed, landing, returning home (RTL,
SMART_RTL, LAND), braking, flown by hand, or its mode unknown or stale;
:mod:`~sarmission.mavlink.flight_mode`): a loiter or visit would cancel the pilot's or a
failsafe's landing. That is checked when the action is queued, when a visit is due (the
queued visits are withdrawn), and by the outbox right before a command goes out (one queued
while the link was down). The STATUSTEXT and the feed carry the alert regardless. In AUTO,
``loiter`` does switch the vehicle to GUIDED (the survey stops at the target; the pilot
resumes it); ``mission`` keeps the survey. A queued visit is withdrawn when, by the time
it is due, the operator has dismissed its alert or the gate refuses it as the store now has it
(its confidence rated down by the operator's decisions); a visit withheld only because its
target was too unlikely a person is queued once the operator's decisions on other alerts rate
it up to ``min_confidence`` (checked every :data:`RATED_UP_CHECK_S`), unless it was dismissed.
Everything goes through the
:class:`~sarmission.mavlink.commands.Outbox`, which waits for each COMMAND_ACK with retries and
keeps actions queued while the link is down. The store records what is known on each action's own
channel (:data:`CHANNELS`): a command's answer (accepted, i.e. delivered, or refused with the
autopilot's reason), and for the STATUSTEXT, which MAVLink never acknowledges, each of its
``statustext_repeats`` sends (it is never called delivered). A restarted controller re-submits what
never got through (:meth:`ActionPolicy.resume`): commands nobody answered, and the sends a
STATUSTEXT still lacks. Of the positional actions only the newest unanswered one per channel is
re-submitted: flying to an older target first would only delay the newest order.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

from sarmission.alerts.model import CHANNEL_MAVLINK, Alert
from sarmission.alerts.store import AlertStore
from sarmission.mavlink.commands import Action, CommandResult, Outbox
from sarmission.mavlink.connection import M
from sarmission.mavlink.mission_transfer import loiter_item
from sarmission.mavlink.outbox_commands import (
    ClearRoi,
    InsertVisits,
    OutboxCommand,
    Reposition,
    SetRoi,
    StatusText,
)
from sarmission.mission.camera_hold import ROI_SETTLE_S, CameraHold
from sarmission.mission.config import ActionsConfig
from sarmission.mission.visits import MoveGate, VisitPlanner

log = logging.getLogger(__name__)

#: Alert store channel of each policy entry.
CHANNELS: dict[str, str] = {
    "alert": CHANNEL_MAVLINK,
    "loiter": "mavlink_loiter",
    "roi": "mavlink_roi",
    "mission": "mavlink_mission",
}
_POSITIONAL = ("loiter", "roi", "mission")
_VISITS = ("loiter", "mission")
#: Commands that send the vehicle somewhere or turn it: withheld while it may not be taken over.
_TAKEOVER_COMMANDS = (Reposition, SetRoi, InsertVisits)
#: How often (seconds) visits withheld for their confidence are checked against the store.
RATED_UP_CHECK_S = 1.0
#: Outbox key channel of the camera release (not an alert delivery: nothing is stored).
ROI_RELEASE = "roi_release"
__all__ = ["CHANNELS", "ROI_RELEASE", "ROI_SETTLE_S", "ActionPolicy", "ascii_statustext"]


@dataclass(frozen=True)
class _Key:
    """An outbox action's key: the alert and store channel it is for (the camera release has
    neither), the target and the alert's short id for the console."""

    alert_id: str
    channel: str
    target_id: int
    short_id: str = ""
    covered: tuple[str, ...] = ()  # a visit's other alerts (same answer recorded for them)


class ActionPolicy:
    """Turns alerts into outbox actions per ``config.policy`` and records what became of them.

    ``survey_altitude_m`` is the loiter altitude when the mission gives none;
    ``target_altitude_m`` is the target's height above home (ROI altitude). ``move_gate``
    decides where the aircraft may be sent (None: nowhere: positional actions are withheld);
    ``aircraft_position`` gives its latest ``(lat, lon)`` (nearest visit first);
    ``gimbal_present`` says whether a gimbal reports its attitude (the ROI pause needs one).
    ``takeover`` says why the vehicle may not be taken over now ("" when it may; None: its
    flight mode is not tracked, so positional actions are withheld).
    ``console`` receives one line per command answered and per STATUSTEXT sent all its
    repeats; ``clock`` gives the seconds that ``roi_hold_s`` is counted in. Counters:
    ``acknowledged`` (commands accepted), ``refused``, ``sent`` (STATUSTEXT alerts sent all
    their repeats; nothing acknowledges them).
    """

    def __init__(
        self,
        config: ActionsConfig,
        outbox: Outbox,
        store: AlertStore,
        survey_altitude_m: float,
        target_altitude_m: float = 0.0,
        console: Callable[[str], None] = print,
        clock: Callable[[], float] = time.monotonic,
        *,
        move_gate: MoveGate | None = None,
        aircraft_position: Callable[[], tuple[float, float] | None] = lambda: None,
        gimbal_present: Callable[[], bool] = lambda: False,
        takeover: Callable[[], str] | None = None,
    ) -> None:
        if "loiter" in config.policy and "mission" in config.policy:
            raise ValueError("policy can hold loiter or mission, not both (one visit plan)")
        self.policy = list(config.policy)
        self.outbox = outbox
        self.store = store
        self.loiter_altitude_m = (
            config.loiter_altitude_m if config.loiter_altitude_m is not None else survey_altitude_m
        )
        self.target_altitude_m = target_altitude_m
        self.console = console
        self.roi_hold_s = config.roi_hold_s
        self.repeats = config.statustext_repeats
        self.repeat_interval_s = config.statustext_repeat_interval_s
        self.clock = clock
        self.move_gate = move_gate
        self.aircraft_position = aircraft_position
        self.gimbal_present = gimbal_present
        self.takeover = takeover
        self.planner = VisitPlanner(
            config.visit_interval_s, config.visit_group_radius_m, clock=clock
        )
        self.visit_loiter_s = config.visit_loiter_s
        self._visit_alerts: dict[int, Alert] = {}  # target id -> its newest placed alert
        self._too_unlikely: dict[int, Alert] = {}  # target id -> visit withheld for confidence
        self._rated_up_checked = -math.inf
        self.withheld = 0
        self.withdrawn = 0  # queued visits the store overruled since (see _withdraw_overruled)
        self.acknowledged = 0
        self.refused = 0
        self.sent = 0
        self.camera = CameraHold(config.roi_hold_s, ROI_SETTLE_S, clock)
        outbox.set_callbacks(
            on_delivered=self._on_delivered, on_refused=self._on_refused, on_sent=self._on_sent
        )
        outbox.set_gate(self._outbox_gate)

    @property
    def delivered(self) -> int:
        """Commands the autopilot accepted (a STATUSTEXT is never counted: nothing
        acknowledges it; see :attr:`sent`)."""
        return self.acknowledged

    def summary(self) -> str:
        """One line on what the autopilot was told, for the run's summary."""
        return (
            f"autopilot commands acknowledged: {self.acknowledged}, refused: {self.refused}"
            + (
                f", withheld (no bounded position in the area, or the vehicle not to be "
                f"taken over): {self.withheld}"
                if self.withheld
                else ""
            )
            + (
                f", visits withdrawn (dismissed or rated down since): {self.withdrawn}"
                if self.withdrawn
                else ""
            )
            + (
                f", targets waiting for a visit: {len(self.planner.pending)}"
                if self.planner.pending
                else ""
            )
            + f"; STATUSTEXT alerts sent {self.repeats}x (no acknowledgement exists for "
            f"STATUSTEXT): {self.sent}; pending: {self.pending()}"
        )

    def announce(self, alert: Alert) -> int:
        """Queue every action of the policy for a new alert, or again for an alert whose position
        was found after it was announced (the STATUSTEXT then carries the position, and the
        positional actions skipped the first time go out); returns how many were queued."""
        return sum(self._submit(entry, alert) for entry in self.policy)

    def refine(self, alert: Alert) -> bool:
        """A confirmed alert's position was refined: a visit still queued for its target goes
        to the new position, or is withdrawn if the new position fails the move gate. What
        went out already (STATUSTEXT, ROI, a visit flown) is not sent again: the feed and the
        store carry the refined position. Returns whether a queued visit changed."""
        target_id = alert.target_id
        if target_id not in self.planner.pending or alert.position is None:
            return False
        refusal = self._move_refusal(alert)
        if refusal:
            self._withdraw_visit(target_id, alert.short_id, refusal)
            self.withheld += 1
            return True
        self.planner.add(target_id, alert.position)
        self._visit_alerts[target_id] = alert
        return True

    def resume(self) -> int:
        """Re-queue what earlier runs stored but never got through (commands not answered,
        STATUSTEXTs sent fewer than ``statustext_repeats`` times: the sends they lack);
        returns the count queued."""
        queued = 0
        for entry in self.policy:
            channel = CHANNELS[entry]
            pending = self.store.undelivered(channel, self.repeats)
            if entry == "roi":  # pointing the camera at an older target would only delay
                pending = [a for a in pending if a.position is not None][-1:]
            for alert in pending:
                sends = alert.sent.get(channel)
                left = self.repeats - (sends.count if sends is not None else 0)
                queued += self._submit(entry, alert, repeats=max(1, left))
        return queued

    def pending(self) -> int:
        """Actions still waiting for the autopilot."""
        return len(self.outbox.pending())

    def search_paused(self) -> bool:
        """Whether the camera is pointed at a target (from the delivery of an ROI until
        :data:`ROI_SETTLE_S` after its release), so that its frames should not be searched. A
        release waiting for a lost link keeps the pause (the autopilot still points the camera
        at the target); a refused release ends it (where the camera looks is then unknown)."""
        return self.camera.search_paused()

    def tick(self) -> bool:
        """Call once per frame: sends the next visit when the plan allows one, and releases
        the camera (DO_SET_ROI_NONE) once the newest delivered ROI has been held ``roi_hold_s``,
        unless another ROI is still on its way (its delivery restarts the hold). Returns
        whether a release was queued."""
        self._dispatch_visits()
        if not self.camera.release_due(self._roi_on_its_way):
            return False
        self.outbox.submit(ClearRoi(), key=_Key("", ROI_RELEASE, 0))
        return True

    def _withdraw_overruled(self) -> None:
        """Withdraw the queued visits whose alert the store now says not to fly to: dismissed
        by the operator, or refused by the move gate as it stands (its confidence rated down
        by the operator's decisions on other alerts) since it was queued."""
        for target_id, queued in list(self._visit_alerts.items()):
            current = self.store.get(queued.alert_id)
            if current is None or target_id not in self.planner.pending:
                continue
            reason = (
                f"dismissed by {current.decided_by}"
                if current.dismissed
                else self._move_refusal(current)
            )
            if reason:
                self._withdraw_visit(target_id, queued.short_id, reason)
                self.withdrawn += 1

    def _withdraw_visit(self, target_id: int, short_id: str, reason: str) -> None:
        """Take ``target_id``'s queued visit out of the plan, saying why on the console."""
        del self.planner.pending[target_id]
        self._visit_alerts.pop(target_id, None)
        self.console(f"  -> target {target_id} ({short_id}): visit withdrawn: {reason}")

    def _move_refusal(self, alert: Alert) -> str:
        """Why the vehicle may not be sent to ``alert``'s position ("" when it may)."""
        if self.move_gate is None:
            return "no mission area to check it against"
        return self.move_gate.refusal(alert.position, alert.error_m, alert.confidence)

    def _takeover_refusal(self) -> str:
        """Why the vehicle may not be taken over now ("" when it may)."""
        if self.takeover is None:
            return "the vehicle's flight mode is not tracked"
        return self.takeover()

    def _outbox_gate(self, command: OutboxCommand) -> str:
        """The outbox's last check before a command goes out: positional ones only while the
        vehicle may be taken over."""
        return self._takeover_refusal() if isinstance(command, _TAKEOVER_COMMANDS) else ""

    def _roi_on_its_way(self) -> bool:
        return any(isinstance(a.command, SetRoi) for a in self.outbox.pending())

    def _submit(self, entry: str, alert: Alert, repeats: int | None = None) -> bool:
        key = _Key(alert.alert_id, CHANNELS[entry], alert.target_id, alert.short_id)
        if entry == "alert":
            self.outbox.submit(
                StatusText(ascii_statustext(alert), M.MAV_SEVERITY_ALERT),
                key=key,
                repeats=self.repeats if repeats is None else repeats,
                interval_s=self.repeat_interval_s,
            )
            return True
        if alert.position is None:
            log.info("target %d has no position: %s skipped", alert.target_id, entry)
            return False
        refusal = self._move_refusal(alert)
        if refusal:
            self.withheld += 1
            self.console(
                f"  -> target {alert.target_id} ({alert.short_id}): {entry} withheld: {refusal}"
            )
            if entry in _VISITS and self._too_unlikely_alone(alert):
                self._too_unlikely[alert.target_id] = alert
            return False
        takeover = self._takeover_refusal()
        if takeover:
            self.withheld += 1
            self.console(
                f"  -> target {alert.target_id} ({alert.short_id}): {entry} withheld: "
                f"{takeover}{self._alert_goes_out()}"
            )
            return False
        if entry == "roi":
            lat, lon = alert.position
            self.outbox.submit(SetRoi(lat, lon, self.target_altitude_m), key=key)
            return True
        return self._queue_visit(alert)

    def _alert_goes_out(self) -> str:
        """What still tells the pilot of the alert, for a withheld action's console line."""
        return "; the alert goes out as STATUSTEXT" if "alert" in self.policy else ""

    def _queue_visit(self, alert: Alert) -> bool:
        """Put ``alert``'s target (placed, past the move gate) in the visit plan; False when
        it was visited already."""
        self._too_unlikely.pop(alert.target_id, None)
        if not self.planner.add(alert.target_id, alert.position):
            return False
        self._visit_alerts[alert.target_id] = alert
        return True

    def _too_unlikely_alone(self, alert: Alert) -> bool:
        """Whether the move gate refuses ``alert`` for its confidence alone (its position
        would do)."""
        return self.move_gate is not None and not self.move_gate.refusal(
            alert.position, alert.error_m
        )

    def _queue_rated_up(self) -> None:
        """Queue the visits withheld for their target's confidence that the store now rates
        likely enough (the operator's decisions on other alerts); forget the dismissed ones."""
        now = self.clock()
        if not self._too_unlikely or now - self._rated_up_checked < RATED_UP_CHECK_S:
            return
        self._rated_up_checked = now
        for target_id, withheld in list(self._too_unlikely.items()):
            current = self.store.get(withheld.alert_id)
            if current is None or current.dismissed or current.position is None:
                del self._too_unlikely[target_id]
            elif not self._move_refusal(current):
                if self._queue_visit(current):
                    self.console(
                        f"  -> target {target_id} ({current.short_id}): visit queued: "
                        f"rated up to {current.format_confidence()}"
                    )

    def _dispatch_visits(self) -> None:
        """The next visit (``loiter``) or the whole pending plan (``mission``), when due."""
        entry = next((e for e in self.policy if e in _VISITS), None)
        if entry is None:
            return
        self._queue_rated_up()
        if not self.planner.pending or self.planner.seconds_to_next() > 0:
            return
        self._withdraw_overruled()
        takeover = self._takeover_refusal()
        if takeover:
            for target_id in list(self.planner.pending):
                alert = self._visit_alerts.get(target_id)
                self._withdraw_visit(target_id, alert.short_id if alert else "", takeover)
                self.withheld += 1
        if not self.planner.pending:
            return
        here = self.aircraft_position()
        visits = (
            [v for v in [self.planner.next_visit(here)] if v is not None]
            if entry == "loiter"
            else self.planner.tour(here)
        )
        if not visits:
            return
        alerts = [
            self._visit_alerts.pop(t) for v in visits for t in v.covered if t in self._visit_alerts
        ]
        if not alerts:
            return
        first = next((a for a in alerts if a.target_id == visits[0].target_id), alerts[0])
        key = _Key(
            first.alert_id,
            CHANNELS[entry],
            first.target_id,
            first.short_id,
            tuple(a.alert_id for a in alerts if a is not first),
        )
        if entry == "loiter":
            lat, lon = visits[0].position
            self.outbox.submit(Reposition(lat, lon, self.loiter_altitude_m), key=key)
        else:
            items = [
                loiter_item(*v.position, self.loiter_altitude_m, self.visit_loiter_s)
                for v in visits
            ]
            self.outbox.submit(InsertVisits(tuple(items)), key=key)
        covered = ", ".join(str(t) for v in visits for t in v.covered)
        self.console(
            f"  -> visit plan: {entry} to target{'s' if len(alerts) > 1 else ''} {covered}"
        )

    def _on_sent(self, action: Action, result: CommandResult) -> None:
        key = _key(action)
        if key is None:
            return
        sends = self.store.record_sent(key.alert_id, key.channel)
        if action.done:
            self.sent += 1
            self.console(
                f"  -> target {key.target_id} ({key.short_id}): STATUSTEXT sent "
                f"{sends.count}x (no acknowledgement exists for STATUSTEXT)"
            )

    def _on_delivered(self, action: Action, result: CommandResult) -> None:
        key = _key(action)
        if key is None:
            return
        if key.channel == ROI_RELEASE:
            self.camera.release_delivered()
            self.console("  -> camera back to the survey view (DO_SET_ROI_NONE)")
            return
        if key.channel == CHANNELS["roi"]:
            gimbal = self.gimbal_present()
            self.camera.roi_delivered(gimbal)
            if not gimbal:
                log.info(
                    "ROI without a gimbal reporting: it turns the vehicle, the fixed "
                    "camera keeps its view, the search goes on"
                )
        for alert_id in (key.alert_id, *key.covered):
            self.store.record_ack(alert_id, key.channel, result.result or 0)
        self.acknowledged += 1
        self.console(
            f"  -> target {key.target_id}: {result.name} acknowledged "
            f"({action.attempts} attempt{'s' if action.attempts != 1 else ''})"
        )

    def _on_refused(self, action: Action, result: CommandResult) -> None:
        key = _key(action)
        if key is None:
            return
        if result.withheld:
            self.withheld += 1
            entry = next((e for e, c in CHANNELS.items() if c == key.channel), key.channel)
            self.console(
                f"  -> target {key.target_id} ({key.short_id}): {entry} {result.error}"
                f"{self._alert_goes_out()}"
            )
            return
        self.refused += 1
        if key.channel == ROI_RELEASE:  # where the camera looks is unknown: search on regardless
            self.camera.release_refused()
            self.console(f"  -> camera release: {result.error}")
            return
        if result.result is not None:
            for alert_id in (key.alert_id, *key.covered):
                self.store.record_ack(alert_id, key.channel, result.result, result.error)
        self.console(f"  -> target {key.target_id}: {result.error}")


def ascii_statustext(alert: Alert) -> str:
    """The alert's STATUSTEXT in ASCII: the autopilot's text field is ASCII, so "±" (two bytes in
    UTF-8) becomes "+-" (two bytes), keeping the 50-byte limit."""
    return alert.statustext().replace("±", "+-")


def _key(action: Action) -> _Key | None:
    """The policy's key of ``action``; None for an action that someone else queued."""
    return action.key if isinstance(action.key, _Key) else None
