"""Where the aircraft may be sent, and when: the gate for moving commands and the visit plan.

Commands that move the aircraft (``loiter``: DO_REPOSITION, ``mission``: loiter items in the
pilot's mission) are a pilot's decision taken by software, so they need more than an alert:

- :class:`MoveGate`: a target is a destination only when its position has a bounded error
  (``max_error_m``) and lies inside the mission area, or within ``margin_m`` of it. A fix far
  outside the area is more likely wrong than a person there, and an unbounded error means the
  aircraft could be sent anywhere.
- :class:`VisitPlanner`: one plan for many targets instead of a reposition per alert. Targets
  wait in a queue; a visit leaves at most every ``min_interval_s`` (the aircraft gets there and
  the camera has time to look); the next destination is the pending target nearest to the
  aircraft (the oldest when its position is unknown), and the pending targets within
  ``group_radius_m`` of it are covered by the same visit.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from sarmission.alerts.model import format_confidence
from sarmission.geo.wgs84 import geodetic_to_ned
from sarmission.mission.config import MissionConfig


def _distance_m(a: tuple[float, float], b: tuple[float, float]) -> float:
    n, e, _ = geodetic_to_ned(b[0], b[1], 0.0, a[0], a[1], 0.0)
    return math.hypot(float(n), float(e))


class MoveGate:
    """Whether a target may be flown to: bounded error, inside the area plus a margin, and at
    least ``min_confidence`` likely to be a person when its likelihood is known.

    ``area_ne``: the mission area as (north, east) metres around ``area_origin`` (lat, lon).
    """

    def __init__(
        self,
        area_ne: Sequence[tuple[float, float]],
        area_origin: tuple[float, float],
        max_error_m: float,
        margin_m: float,
        min_confidence: float = 0.0,
    ) -> None:
        if len(area_ne) < 3:
            raise ValueError("the mission area needs at least 3 corners")
        self.contour = np.asarray(area_ne, dtype=np.float32).reshape(-1, 1, 2)
        self.origin = area_origin
        self.max_error_m = max_error_m
        self.margin_m = margin_m
        self.min_confidence = min_confidence

    @classmethod
    def from_mission(cls, mission: MissionConfig) -> MoveGate:
        """The gate of a mission: its area (around the mission's planned home, where the area
        is defined) and its ``[actions] max_error_m`` / ``area_margin_m`` / ``min_confidence``."""
        return cls(
            mission.area.polygon_ne(),
            mission.area.home[:2],
            mission.actions.max_error_m,
            mission.actions.area_margin_m,
            mission.actions.min_confidence,
        )

    def refusal(
        self,
        position: tuple[float, float] | None,
        error_m: float | None,
        confidence: float | None = None,
    ) -> str:
        """ "" when ``position`` (with 1-sigma ``error_m``; a person there with probability
        ``confidence``, None: unknown) may be flown to, else why not."""
        if confidence is not None and confidence < self.min_confidence:
            return (
                f"{format_confidence(confidence)}, below the {100 * self.min_confidence:g} % "
                "that moves the aircraft"
            )
        if position is None:
            return "no position"
        if error_m is None or not math.isfinite(error_m):
            return "position error unknown"
        if error_m > self.max_error_m:
            return f"position error {error_m:.0f} m exceeds {self.max_error_m:g} m"
        n, e, _ = geodetic_to_ned(position[0], position[1], 0.0, *self.origin, 0.0)
        if not (math.isfinite(float(n)) and math.isfinite(float(e))):
            return "position not finite"
        inside = cv2.pointPolygonTest(self.contour, (float(n), float(e)), True)
        if inside < -self.margin_m:
            return f"{-inside:.0f} m outside the mission area (allowed: {self.margin_m:g} m)"
        return ""


@dataclass
class PendingTarget:
    """A target waiting for a visit (``added``: when it joined the queue, planner clock)."""

    target_id: int
    position: tuple[float, float]
    added: float


@dataclass(frozen=True)
class Visit:
    """One move: fly to ``position`` (the target ``target_id``); ``covered`` lists every target
    the visit takes care of (that one and its close neighbours)."""

    target_id: int
    position: tuple[float, float]
    covered: tuple[int, ...]


@dataclass
class VisitPlanner:
    """Queue of targets to visit; :meth:`next_visit` hands out at most one visit per
    ``min_interval_s`` (see the module docstring). Not thread-safe: one owner calls it."""

    min_interval_s: float = 60.0
    group_radius_m: float = 30.0
    clock: Callable[[], float] = time.monotonic
    pending: dict[int, PendingTarget] = field(default_factory=dict)
    visited: set[int] = field(default_factory=set)
    _last_visit: float = -math.inf

    def add(self, target_id: int, position: tuple[float, float]) -> bool:
        """Queue a target (a newer position replaces the queued one); False if it was already
        visited or covered by a visit."""
        if target_id in self.visited:
            return False
        entry = self.pending.get(target_id)
        if entry is None:
            self.pending[target_id] = PendingTarget(target_id, position, self.clock())
        else:
            entry.position = position
        return True

    def seconds_to_next(self) -> float:
        """Seconds until a visit may leave (0 when one may leave now)."""
        return max(0.0, self._last_visit + self.min_interval_s - self.clock())

    def next_visit(self, aircraft: tuple[float, float] | None = None) -> Visit | None:
        """The visit to fly now, or None (nothing pending, or too soon after the last one)."""
        if not self.pending or self.seconds_to_next() > 0:
            return None
        if aircraft is None:
            first = min(self.pending.values(), key=lambda p: (p.added, p.target_id))
        else:
            first = min(
                self.pending.values(),
                key=lambda p: (_distance_m(aircraft, p.position), p.target_id),
            )
        covered = sorted(
            p.target_id
            for p in self.pending.values()
            if _distance_m(first.position, p.position) <= self.group_radius_m
        )
        for target_id in covered:
            del self.pending[target_id]
            self.visited.add(target_id)
        self._last_visit = self.clock()
        return Visit(first.target_id, first.position, tuple(covered))

    def tour(self, aircraft: tuple[float, float] | None = None) -> list[Visit]:
        """Every pending target as one ordered plan (nearest neighbour from the aircraft),
        grouped as :meth:`next_visit` does; respects ``min_interval_s`` like it (one plan per
        interval) and empties the queue."""
        if not self.pending or self.seconds_to_next() > 0:
            return []
        plan: list[Visit] = []
        here = aircraft
        while self.pending:
            self._last_visit = -math.inf
            visit = self.next_visit(here)
            assert visit is not None
            plan.append(visit)
            here = visit.position
        self._last_visit = self.clock()
        return plan
