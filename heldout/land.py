"""Ground seen from above: meadow, forest canopy and a dirt road, as reflectance per world point.

All layers are functions of world position (hashed value noise, :mod:`heldout.noise`), so the
ground stays put under a moving camera. Tree crowns are lit on the sun's side: the crown
texture minus itself shifted towards the sun.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from heldout.noise import fractal_noise, value_noise


@dataclass(frozen=True)
class LandLook:
    """One landscape: how much forest, where the road runs, the grass colours."""

    seed: int
    forest_share: float
    road_heading_deg: float
    road_offset_m: float
    road_width_m: float
    lush_bgr: tuple[float, float, float]
    dry_bgr: tuple[float, float, float]


def _smoothstep(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    s = np.clip((x - lo) / (hi - lo), 0, 1)
    return s * s * (3 - 2 * s)


def land_reflectance(
    east: np.ndarray, north: np.ndarray, look: LandLook, sun_azimuth_deg: float
) -> tuple[np.ndarray, np.ndarray]:
    """BGR reflectance ``[..., 3]`` of the ground and how lit it is (0..1, shade of crowns)."""
    seed = look.seed
    field = fractal_noise(east, north, 14.0, seed, octaves=3)
    grass = value_noise(east, north, 0.18, seed + 11)
    lush, dry = np.array(look.lush_bgr, np.float32), np.array(look.dry_bgr, np.float32)
    colour = lush + (dry - lush) * _smoothstep(field, 0.35, 0.75)[..., None]
    colour = colour * (0.8 + 0.4 * grass)[..., None]

    edge = 0.5 + 0.3 * (0.5 - look.forest_share)  # the noise sits around 0.5 +- 0.15
    forest = _smoothstep(
        fractal_noise(east, north, 45.0, seed + 23, octaves=2), edge - 0.03, edge + 0.03
    )
    az = math.radians(sun_azimuth_deg)
    crowns = value_noise(east, north, 2.2, seed + 31)
    towards_sun = value_noise(east - 0.7 * math.sin(az), north - 0.7 * math.cos(az), 2.2, seed + 31)
    lit_crown = np.clip(0.55 + 2.0 * (crowns - towards_sun), 0.1, 1.0) * _smoothstep(
        crowns, 0.2, 0.4
    )
    canopy = np.array((0.025, 0.075, 0.035), np.float32) * (0.7 + 0.6 * crowns)[..., None]
    colour = colour * (1 - forest[..., None]) + canopy * forest[..., None]
    light = 1.0 - forest * (1.0 - lit_crown)

    h = math.radians(look.road_heading_deg)
    along = east * math.sin(h) + north * math.cos(h)
    across = (
        east * math.cos(h) - north * math.sin(h) - look.road_offset_m - 6.0 * np.sin(along / 40.0)
    )
    road = _smoothstep(look.road_width_m / 2 - np.abs(across), -0.2, 0.3)
    ruts = 1.0 - 0.25 * _smoothstep(0.3 - np.abs(np.abs(across) - 0.8), 0.0, 0.2)
    gravel = value_noise(east, north, 0.08, seed + 41)
    dirt = np.array((0.10, 0.16, 0.21), np.float32) * ((0.85 + 0.3 * gravel) * ruts)[..., None]
    colour = colour * (1 - road[..., None]) + dirt * road[..., None]
    light = light * (1 - road) + road
    return colour, light
