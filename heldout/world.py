"""What a held-out world holds: its kind, light, sea or land, and the objects in it with their
motion. Everything is drawn from one seed (:func:`populate`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from heldout.bodies import Look, draw_look

#: Categories written to the annotation file, by id; the first two are the maritime detector's
#: classes, ``person`` the land target, the rest distractors.
CATEGORIES: dict[str, int] = {
    "swimmer": 1,
    "swimmer_with_life_jacket": 2,
    "person": 3,
    "boat": 4,
    "buoy": 5,
    "debris": 6,
    "bird": 7,
    "rock": 8,
    "log": 9,
    "animal": 10,
}
TARGETS: frozenset[str] = frozenset({"swimmer", "swimmer_with_life_jacket", "person"})


@dataclass(frozen=True)
class Thing:
    """One object: its look, where it is at t = 0 (east, north, height above the surface), its
    velocity (m/s east, north), heading (degrees clockwise from north) and turn rate."""

    track_id: int
    look: Look
    start: tuple[float, float, float]
    velocity: tuple[float, float]
    heading_deg: float
    turn_deg_s: float

    @property
    def category(self) -> str:
        return self.look.kind

    def place(self, t: float) -> tuple[tuple[float, float, float], float]:
        """Position (east, north, height) and heading at ``t``."""
        e, n, z = self.start
        return (
            (e + self.velocity[0] * t, n + self.velocity[1] * t, z),
            (self.heading_deg + self.turn_deg_s * t) % 360.0,
        )


@dataclass(frozen=True)
class Population:
    """How many of each kind, on average, in one camera footprint."""

    per_frame: dict[str, float]


def _motion(
    rng: np.random.Generator, kind: str, posture: str, current: tuple[float, float]
) -> tuple[tuple[float, float], float, float, float]:
    """Velocity, heading, turn rate and height above the surface for one object."""
    heading = float(rng.uniform(0, 360))
    if kind in ("swimmer", "swimmer_with_life_jacket"):
        own = float(rng.uniform(0.0, 0.6 if posture == "crawl" else 0.2))
        speed, turn, height = own, float(rng.normal(0, 4)), 0.0
        vel = (
            current[0] + speed * math.sin(math.radians(heading)),
            current[1] + speed * math.cos(math.radians(heading)),
        )
        return vel, heading, turn, height
    if kind in ("buoy", "debris"):
        return current, heading, float(rng.normal(0, 3)), 0.0
    if kind == "bird":
        if posture == "sitting":
            return current, heading, 0.0, 0.0
        speed = float(rng.uniform(6, 13))
        return (
            (speed * math.sin(math.radians(heading)), speed * math.cos(math.radians(heading))),
            heading,
            float(rng.normal(0, 8)),
            float(rng.uniform(4, 30)),
        )
    if kind == "boat":
        speed = float(rng.uniform(0, 6))
        return (
            (speed * math.sin(math.radians(heading)), speed * math.cos(math.radians(heading))),
            heading,
            0.0,
            0.0,
        )
    if kind == "person" and posture == "walking":
        speed = float(rng.uniform(0.6, 1.5))
        return (
            (speed * math.sin(math.radians(heading)), speed * math.cos(math.radians(heading))),
            heading,
            float(rng.normal(0, 3)),
            0.0,
        )
    return (0.0, 0.0), heading, 0.0, 0.0


def populate(
    rng: np.random.Generator,
    population: Population,
    area: tuple[float, float, float, float],
    footprint_m2: float,
    water: tuple[float, float, float],
    current: tuple[float, float] = (0.0, 0.0),
) -> list[Thing]:
    """Objects scattered uniformly over ``area`` (east0, north0, east1, north1), as many as
    ``population`` asks for per ``footprint_m2`` of it."""
    e0, n0, e1, n1 = area
    footprints = (e1 - e0) * (n1 - n0) / footprint_m2
    things: list[Thing] = []
    for kind, per_frame in population.per_frame.items():
        for _ in range(int(rng.poisson(per_frame * footprints))):
            look = draw_look(rng, kind, water)
            velocity, heading, turn, height = _motion(rng, kind, look.posture, current)
            start = (float(rng.uniform(e0, e1)), float(rng.uniform(n0, n1)), height)
            things.append(Thing(len(things) + 1, look, start, velocity, heading, turn))
    return things
