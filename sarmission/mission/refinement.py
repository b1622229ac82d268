"""When a placed alert's position is refined: its target has moved, or its error changed.

An alert is stored with the position its target had at the lock: one frame's fix. Later fixes
place it better (:mod:`sarmission.mission.position_estimate`: a fit of the recent fixes, as of
the latest): at an oblique view, where a metre of altitude error is ten metres along the ray,
the first seconds' fixes can all lie short together, and a swimmer drifting with the current is
tens of metres from where they were locked a minute later. The operator, the team and a queued
visit should have the better position, without a stream of updates:

- at the confirmation, the confirmed alert takes its target's estimate (``force``), so what is
  announced rests on the fixes that confirmed it, not on the lock's single fix;
- after that, at most once per ``period_s`` per alert, and only when the estimate moved by at
  least ``max(min_move_m, move_share x the alert's error)``, the error changed by more than
  ``error_share`` of the alert's, or the drift by more than ``drift_tolerance_m_s`` (a team
  intercepting a drifting swimmer steers by it)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from sarmission.alerts.model import Alert
from sarmission.mission.targets import distance_m

#: Seconds between two refinements of one alert.
REFINE_PERIOD_S = 5.0
#: The smallest move (m) worth telling.
REFINE_MIN_MOVE_M = 1.0
#: A move of this share of the alert's error is worth telling.
REFINE_MOVE_SHARE = 0.5
#: An error that changed by more than this share of the alert's is worth telling.
REFINE_ERROR_SHARE = 0.25
#: Seconds between two looks at an alert whose refinement is due but whose estimate had not
#: moved enough (each look fits a window of fixes).
CHECK_PERIOD_S = 1.0
#: At the confirmation (``force``) a move or an error change of more than this (m) is taken.
FORCED_TOLERANCE_M = 0.1
#: A drift that changed by more than this (m/s, as a vector) is worth telling; at the
#: confirmation any change is.
REFINE_DRIFT_TOLERANCE_M_S = 0.1


@dataclass(frozen=True)
class Refinement:
    """A better position for an alert: where, its 1-sigma error, how far it moved, the
    target's drift (m/s north, east; None: not estimated) and how far apart its tracks' fixes
    lay (m; 0: they agree; :mod:`sarmission.mission.continuity`), which the error includes."""

    position: tuple[float, float]
    error_m: float | None
    moved_m: float
    drift_ne: tuple[float, float] | None = None
    apart_m: float = 0.0

    def detail(self) -> str:
        """The event log's line for it."""
        error = "unknown" if self.error_m is None else f"+- {self.error_m:.1f} m"
        apart = f" (sightings {self.apart_m:.1f} m apart)" if self.apart_m > 0 else ""
        return f"refined: moved {self.moved_m:.1f} m, {error}{apart}"


@dataclass
class PositionRefiner:
    """Decides, per alert, when its target's position is worth an update (see the module
    docstring). Not thread-safe: one controller owns it."""

    period_s: float = REFINE_PERIOD_S
    min_move_m: float = REFINE_MIN_MOVE_M
    move_share: float = REFINE_MOVE_SHARE
    error_share: float = REFINE_ERROR_SHARE
    check_period_s: float = CHECK_PERIOD_S
    drift_tolerance_m_s: float = REFINE_DRIFT_TOLERANCE_M_S
    _last: dict[str, float] = field(default_factory=dict)
    _looked: dict[str, float] = field(default_factory=dict)

    def due(
        self,
        alert: Alert,
        position: tuple[float, float] | None,
        error_m: float | None,
        now: float,
        force: bool = False,
        drift_ne: tuple[float, float] | None = None,
        apart_m: float = 0.0,
    ) -> Refinement | None:
        """The refinement ``alert`` should get at time ``now`` from its target's ``position``,
        ``error_m`` (which includes ``apart_m``, how far apart its tracks' fixes lay) and
        ``drift_ne``, or None. ``force``: any change beyond
        :data:`FORCED_TOLERANCE_M`, or of the drift, however soon (the confirmation). An alert
        without a position gets none here: it is placed, not refined."""
        if alert.position is None or position is None:
            return None
        if not force and not self.ready(alert.alert_id, now):
            return None
        moved = distance_m(alert.position, position)
        old = alert.error_m
        if error_m is None or old is None:
            error_changed = error_m != old
        else:
            error_changed = abs(error_m - old) > (
                FORCED_TOLERANCE_M if force else self.error_share * old
            )
        threshold = (
            FORCED_TOLERANCE_M if force else max(self.min_move_m, self.move_share * (old or 0.0))
        )
        if (
            not error_changed
            and moved <= threshold
            and not self._drift_changed(alert.drift_ne, drift_ne, force)
        ):
            return None
        return Refinement(position, error_m, moved, drift_ne, apart_m)

    def _drift_changed(
        self, old: tuple[float, float] | None, new: tuple[float, float] | None, force: bool
    ) -> bool:
        """Whether the drift changed enough to tell: known or unknown now, any change at the
        confirmation, else more than ``drift_tolerance_m_s``."""
        if old is None or new is None:
            return old != new
        change = math.hypot(new[0] - old[0], new[1] - old[1])
        return change > (0.0 if force else self.drift_tolerance_m_s)

    def ready(self, alert_id: str, now: float) -> bool:
        """Whether ``period_s`` has passed since ``alert_id`` was last refined (or placed)."""
        return now - self._last.get(alert_id, -math.inf) >= self.period_s

    def worth_a_look(self, alert_id: str, now: float) -> bool:
        """Whether to fit ``alert_id``'s estimate now: it is :meth:`ready`, and
        ``check_period_s`` has passed since the last look that found no refinement due.
        Counts this call as a look."""
        if not self.ready(alert_id, now):
            return False
        if now - self._looked.get(alert_id, -math.inf) < self.check_period_s:
            return False
        self._looked[alert_id] = now
        return True

    def done(self, alert_id: str, now: float) -> None:
        """``alert_id`` was refined (or placed) at ``now``: the next waits ``period_s``."""
        self._last[alert_id] = now

    def forget(self, alert_id: str) -> None:
        """Nothing more to refine for ``alert_id`` (discarded or dismissed)."""
        self._last.pop(alert_id, None)
        self._looked.pop(alert_id, None)
