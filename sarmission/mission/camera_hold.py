"""Where the camera looks after an ROI, and whether the search is paused meanwhile.

An ROI delivered to the autopilot points the camera at a target; after ``hold_s`` the policy
sends the camera back to the survey view (DO_SET_ROI_NONE). With a gimbal reporting its
attitude the frames show the target, not the survey strip, so the search pauses from the
ROI's delivery until ``settle_s`` after the release (the gimbal slews back). Without a gimbal
the ROI only turns the vehicle and the search goes on. The answers arrive on the outbox's
thread and the frames on the controller's, so every change goes through one lock and the
transition table :data:`TRANSITIONS`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from enum import Enum

log = logging.getLogger(__name__)

#: Seconds after the release is delivered until the camera is back on the survey view (the
#: gimbal slews for about a second).
ROI_SETTLE_S = 2.0


class View(Enum):
    """Where the camera looks; ``paused`` says whether its frames are left unsearched."""

    SURVEY = ("survey", False)
    ON_TARGET = ("on target, gimbal held on it", True)
    VEHICLE_TURNED = ("vehicle turned to the target, fixed camera", False)
    RELEASING_GIMBAL = ("release sent, gimbal still on the target", True)
    RELEASING_VEHICLE = ("release sent, fixed camera", False)
    SETTLING = ("released, gimbal slewing back", True)

    def __init__(self, label: str, paused: bool) -> None:
        self.label = label
        self.paused = paused


class Event(Enum):
    """What moves the camera: the outbox's answers and the passing of the hold / settle time."""

    ROI_DELIVERED = "ROI delivered, gimbal reporting"
    ROI_DELIVERED_NO_GIMBAL = "ROI delivered, no gimbal"
    HOLD_OVER = "hold time over, release queued"
    RELEASE_DELIVERED = "release delivered"
    RELEASE_REFUSED = "release refused"
    SETTLED = "settle time over"


_HOLDS = (View.ON_TARGET, View.VEHICLE_TURNED)
_RELEASES = (View.RELEASING_GIMBAL, View.RELEASING_VEHICLE)

#: ``(view, event) -> next view``. A delivered ROI re-points the camera from any view and
#: restarts the hold. A pair not listed leaves the view as it is: a release answered after a
#: newer ROI was delivered is stale. A refused release ends the pause (where the camera looks
#: is then unknown).
TRANSITIONS: dict[tuple[View, Event], View] = {
    **{(v, Event.ROI_DELIVERED): View.ON_TARGET for v in View},
    **{(v, Event.ROI_DELIVERED_NO_GIMBAL): View.VEHICLE_TURNED for v in View},
    (View.ON_TARGET, Event.HOLD_OVER): View.RELEASING_GIMBAL,
    (View.VEHICLE_TURNED, Event.HOLD_OVER): View.RELEASING_VEHICLE,
    **{(v, Event.RELEASE_DELIVERED): View.SETTLING for v in _RELEASES},
    **{(v, Event.RELEASE_REFUSED): View.SURVEY for v in _RELEASES},
    (View.SETTLING, Event.SETTLED): View.SURVEY,
}


class CameraHold:
    """The camera's :class:`View` after ROIs, driven by :data:`TRANSITIONS`; thread-safe.

    ``hold_s``: seconds an ROI is held before the release is due; ``settle_s``: seconds the
    search stays paused after the release is delivered; ``clock`` gives the seconds both are
    counted in.
    """

    def __init__(
        self,
        hold_s: float,
        settle_s: float = ROI_SETTLE_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.hold_s = hold_s
        self.settle_s = settle_s
        self.clock = clock
        self._lock = threading.Lock()
        self._view = View.SURVEY
        self._deadline = 0.0  # end of the hold or of the settling, in the view that has one

    @property
    def view(self) -> View:
        """The current view (after any settle time that has run out)."""
        with self._lock:
            self._settle_if_due()
            return self._view

    def roi_delivered(self, gimbal: bool) -> None:
        """The autopilot accepted an ROI; ``gimbal``: a gimbal reports its attitude."""
        self.handle(Event.ROI_DELIVERED if gimbal else Event.ROI_DELIVERED_NO_GIMBAL)

    def release_delivered(self) -> None:
        """The autopilot accepted the release (DO_SET_ROI_NONE)."""
        self.handle(Event.RELEASE_DELIVERED)

    def release_refused(self) -> None:
        """The autopilot refused the release."""
        self.handle(Event.RELEASE_REFUSED)

    def release_due(self, roi_on_its_way: Callable[[], bool]) -> bool:
        """Whether the caller must send the release now: the hold is over and no other ROI is
        on its way (``roi_on_its_way()``, asked only then: its delivery would restart the
        hold). Moves to the releasing view."""
        with self._lock:
            if self._view not in _HOLDS or self.clock() < self._deadline or roi_on_its_way():
                return False
            self._apply(Event.HOLD_OVER)
            return True

    def search_paused(self) -> bool:
        """Whether the camera's frames should be left unsearched."""
        return self.view.paused

    def handle(self, event: Event) -> View:
        """Apply ``event``; returns the view after it."""
        with self._lock:
            self._settle_if_due()
            self._apply(event)
            return self._view

    def _settle_if_due(self) -> None:
        if self._view is View.SETTLING and self.clock() >= self._deadline:
            self._apply(Event.SETTLED)

    def _apply(self, event: Event) -> None:
        """One transition (the lock held)."""
        after = TRANSITIONS.get((self._view, event))
        if after is None:
            log.debug("camera %s: %s ignored", self._view.label, event.value)
            return
        if after in _HOLDS:
            self._deadline = self.clock() + self.hold_s
        elif after is View.SETTLING:
            self._deadline = self.clock() + self.settle_s
        self._view = after
