"""The drone's drift over a clip: position, heading, tilt and roll at any time, and its telemetry.

A base velocity along a course (zero when hovering), slow gusts (a few seeded sinusoids per axis),
a wandering heading, an altitude ramp and a small gimbal jitter. Smooth by construction, so the
velocity in the telemetry is the exact derivative of the position.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from heldout.camera import View
from heldout.geodesy import lat_lon


@dataclass(frozen=True)
class Sway:
    """A sum of sinusoids: ``sum a_i sin(2 pi t / T_i + p_i)``, and its derivative."""

    amplitudes: tuple[float, ...]
    periods: tuple[float, ...]
    phases: tuple[float, ...]

    @classmethod
    def draw(
        cls, rng: np.random.Generator, scale: float, periods: tuple[float, float], terms: int = 3
    ) -> Sway:
        return cls(
            tuple(float(a) for a in rng.uniform(0.3, 1.0, terms) * scale / terms),
            tuple(float(p) for p in rng.uniform(*periods, terms)),
            tuple(float(p) for p in rng.uniform(0, 2 * math.pi, terms)),
        )

    def at(self, t: float) -> float:
        return sum(
            a * math.sin(2 * math.pi * t / p + ph)
            for a, p, ph in zip(self.amplitudes, self.periods, self.phases, strict=True)
        )

    def rate(self, t: float) -> float:
        return sum(
            a * 2 * math.pi / p * math.cos(2 * math.pi * t / p + ph)
            for a, p, ph in zip(self.amplitudes, self.periods, self.phases, strict=True)
        )


@dataclass(frozen=True)
class DronePath:
    """Seeded drift of the drone and its gimbal over a clip (see the module docstring)."""

    start: tuple[float, float]
    altitude_m: float
    course_deg: float
    speed_m_s: float
    climb_m_s: float
    heading_deg: float
    heading_rate_deg_s: float
    tilt_deg: float
    gust_east: Sway = field(default_factory=lambda: Sway((), (), ()))
    gust_north: Sway = field(default_factory=lambda: Sway((), (), ()))
    heading_sway: Sway = field(default_factory=lambda: Sway((), (), ()))
    jitter: Sway = field(default_factory=lambda: Sway((), (), ()))

    def position(self, t: float) -> tuple[float, float, float]:
        c = math.radians(self.course_deg)
        east = self.start[0] + self.speed_m_s * t * math.sin(c) + self.gust_east.at(t)
        north = self.start[1] + self.speed_m_s * t * math.cos(c) + self.gust_north.at(t)
        return east, north, self.altitude_m + self.climb_m_s * t

    def velocity(self, t: float) -> tuple[float, float, float]:
        c = math.radians(self.course_deg)
        return (
            self.speed_m_s * math.sin(c) + self.gust_east.rate(t),
            self.speed_m_s * math.cos(c) + self.gust_north.rate(t),
            self.climb_m_s,
        )

    def view(self, t: float) -> View:
        heading = self.heading_deg + self.heading_rate_deg_s * t + self.heading_sway.at(t)
        return View(
            self.position(t),
            heading % 360.0,
            self.tilt_deg + self.jitter.at(t + 0.37),
            self.jitter.at(t),
        )

    def meta(self, t: float, home: tuple[float, float]) -> dict[str, float]:
        """SeaDronesSee telemetry keys at ``t``: degrees, metres above home, m/s (x north,
        y east, z down), seconds."""
        east, north, up = self.position(t)
        ve, vn, vu = self.velocity(t)
        lat, lon = lat_lon(home[0], home[1], east, north)
        view = self.view(t)
        return {
            "gps_latitude": lat,
            "gps_longitude": lon,
            "altitude": up,
            "gimbal_pitch": -(90.0 - view.tilt_deg),
            "gimbal_roll": view.roll_deg,
            "gimbal_heading": view.heading_deg,
            "compass_heading": view.heading_deg,
            "speed": math.sqrt(ve * ve + vn * vn + vu * vu),
            "xspeed": vn,
            "yspeed": ve,
            "zspeed": -vu,
            "time": t,
        }


def draw_path(
    rng: np.random.Generator,
    altitude: tuple[float, float],
    speed: tuple[float, float],
    tilt: tuple[float, float],
    hover_chance: float = 0.25,
) -> DronePath:
    """A drift for one clip, every number from ``rng`` within the given ranges."""
    hovering = rng.random() < hover_chance
    course = float(rng.uniform(0, 360))
    heading = course + float(rng.choice([0.0, 90.0, 180.0, -90.0])) + float(rng.normal(0, 8))
    return DronePath(
        start=(float(rng.uniform(-50, 50)), float(rng.uniform(-50, 50))),
        altitude_m=float(rng.uniform(*altitude)),
        course_deg=course,
        speed_m_s=0.0 if hovering else float(rng.uniform(*speed)),
        climb_m_s=float(rng.uniform(-1.5, 1.5)),
        heading_deg=heading % 360.0,
        heading_rate_deg_s=float(rng.uniform(-3, 3)),
        tilt_deg=float(rng.uniform(*tilt)),
        gust_east=Sway.draw(rng, 1.5, (5, 30)),
        gust_north=Sway.draw(rng, 1.5, (5, 30)),
        heading_sway=Sway.draw(rng, 2.0, (3, 12)),
        jitter=Sway.draw(rng, 0.06, (0.07, 0.2)),
    )
