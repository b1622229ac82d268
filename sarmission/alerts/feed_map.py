"""The operator map's data: one mission's area, drone track, alerts and dismissed zones.

:func:`map_document` is ``GET /api/map``. :class:`MapFollower` keeps an event stream's map up to
date without flooding it: a ``map`` event (area and track) when the stream starts or the store
turns to another mission, then at most one ``track`` event (the new drone points) and one
``area`` event (a changed area) per ``interval_s``. Alerts reach the page as their own events.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

from sarmission.alerts.store import AlertStore, DronePoint

#: Most track points in a stream's ``map`` event (every k-th point, the newest kept): enough to
#: draw 5 hours of flight on a screen, a small fraction of a full track's bytes.
MAX_STREAM_TRACK = 4000


def track_rows(points: Sequence[DronePoint]) -> list[list[float]]:
    """Track points as ``[t, lat, lon]`` rows."""
    return [[p.t, p.lat, p.lon] for p in points]


def thin(points: Sequence[DronePoint], most: int) -> list[DronePoint]:
    """At most ``most`` of ``points``, evenly spaced, always with the newest one."""
    if len(points) <= most:
        return list(points)
    step = -(-len(points) // most)  # ceiling division
    kept = list(points[::step])
    if kept[-1] is not points[-1]:
        kept[-1] = points[-1]
    return kept


def map_document(
    store: AlertStore, mission_id: str | None = None, since: float | None = None
) -> dict[str, Any]:
    """``{"mission_id", "area", "track", "alerts", "dismissed"}`` of ``mission_id`` (default:
    the store's current mission, :meth:`AlertStore.current_mission`): area ``[[lat, lon], ...]``
    or None, track ``[[t, lat, lon], ...]`` (with ``since``: points at or after that time),
    the mission's alerts as JSON documents, dismissed zones ``[[lat, lon, radius_m], ...]``.
    Empty lists (and a null mission) when the store knows no such mission."""
    mission = mission_id if mission_id is not None else store.current_mission()
    if mission is None:
        return {"mission_id": None, "area": None, "track": [], "alerts": [], "dismissed": []}
    area = store.mission_area(mission)
    return {
        "mission_id": mission,
        "area": None if area is None else [list(v) for v in area],
        "track": track_rows(store.drone_track(mission, since)),
        "alerts": [a.to_json_dict() for a in store.list(mission_id=mission)],
        "dismissed": [list(z) for z in store.dismissed_zones(mission)],
    }


class MapFollower:
    """What an event stream should send about the map, polled once per tick (see module doc)."""

    def __init__(
        self,
        store: AlertStore,
        interval_s: float = 1.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.store = store
        self.interval_s = interval_s
        self.clock = clock
        self.mission: str | None = None
        self._cursor = 0
        self._area: list[tuple[float, float]] | None = None
        self._last = -float("inf")
        self._started = False

    def poll(self) -> list[tuple[str, dict[str, Any]]]:
        """``(event name, data)`` to send now: ``map`` first (and on a change of mission),
        else ``track`` / ``area`` when they changed, at most once per ``interval_s``."""
        now = self.clock()
        if self._started and now - self._last < self.interval_s:
            return []
        self._last = now
        mission = self.store.current_mission()
        if not self._started or mission != self.mission:
            self._started = True
            return [("map", self._snapshot(mission))]
        if mission is None:
            return []
        out: list[tuple[str, dict[str, Any]]] = []
        self._cursor, points = self.store.drone_points_after(mission, self._cursor)
        if points:
            out.append(("track", {"mission_id": mission, "track": track_rows(points)}))
        area = self.store.mission_area(mission)
        if area != self._area:
            self._area = area
            out.append(
                (
                    "area",
                    {
                        "mission_id": mission,
                        "area": None if area is None else [list(v) for v in area],
                    },
                )
            )
        return out

    def _snapshot(self, mission: str | None) -> dict[str, Any]:
        self.mission = mission
        if mission is None:
            self._cursor, self._area = 0, None
            return {"mission_id": None, "area": None, "track": []}
        self._cursor, points = self.store.drone_points_after(mission, 0)
        self._area = self.store.mission_area(mission)
        return {
            "mission_id": mission,
            "area": None if self._area is None else [list(v) for v in self._area],
            "track": track_rows(thin(points, MAX_STREAM_TRACK)),
        }
