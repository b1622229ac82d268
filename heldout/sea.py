"""Colour of the sea per pixel: Fresnel mix of sky and water body, sun glint, whitecaps, haze.

Inputs are the surface height and slopes looked up per pixel (:mod:`heldout.waves`) and the view
rays of the camera. Output is linear radiance in BGR (float32, about 0..1 for a mid-grey sky);
:mod:`heldout.optics` turns it into pixel values.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from heldout.noise import value_noise

WATER_INDEX = 1.34

#: Water body colours (linear BGR): deep ocean, coastal green, turbid brown.
WATER_BODIES: dict[str, tuple[float, float, float]] = {
    "ocean": (0.075, 0.035, 0.010),
    "coastal": (0.055, 0.060, 0.020),
    "turbid": (0.040, 0.060, 0.060),
}


@dataclass(frozen=True)
class Light:
    """Sun direction, sky gradient, haze: the light of one world."""

    sun_azimuth_deg: float
    sun_elevation_deg: float
    sun_radiance: float
    zenith_bgr: tuple[float, float, float]
    horizon_bgr: tuple[float, float, float]
    haze_bgr: tuple[float, float, float]
    visibility_m: float

    def sun_vector(self) -> np.ndarray:
        az, el = math.radians(self.sun_azimuth_deg), math.radians(self.sun_elevation_deg)
        return np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)])


@dataclass(frozen=True)
class SeaLook:
    """What distinguishes one sea from another besides its waves."""

    water_bgr: tuple[float, float, float]
    facet_variance: float
    whitecap_height_m: float
    foam_cover: float
    wind_to_deg: float
    seed: int


def fresnel(cos_i: np.ndarray) -> np.ndarray:
    """Unpolarised reflectance of air-to-water at incidence cosine ``cos_i``."""
    cos_i = np.clip(cos_i, 1e-3, 1.0)
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_i * cos_i)) / WATER_INDEX
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin_t * sin_t))
    rs = (cos_i - WATER_INDEX * cos_t) / (cos_i + WATER_INDEX * cos_t)
    rp = (cos_t - WATER_INDEX * cos_i) / (cos_t + WATER_INDEX * cos_i)
    return 0.5 * (rs * rs + rp * rp)


_FRESNEL_STEPS = 2048
_FRESNEL_TABLE = fresnel(np.linspace(0.0, 1.0, _FRESNEL_STEPS + 1)).astype(np.float32)


def fresnel_lookup(cos_i: np.ndarray) -> np.ndarray:
    """:func:`fresnel` from a table (``cos_i`` in [0, 1]): the per-pixel form."""
    index = (np.minimum(np.maximum(cos_i, 0.0), 1.0) * _FRESNEL_STEPS + 0.5).astype(np.int32)
    return _FRESNEL_TABLE[index]


def foam_pattern(east: np.ndarray, north: np.ndarray, look: SeaLook, t: float) -> np.ndarray:
    """Where foam may lie (0..1): patches across the wind, streaks along it, drifting."""
    w = math.radians(look.wind_to_deg)
    drift = 0.6 * t
    along = east * math.sin(w) + north * math.cos(w) - drift
    across = east * math.cos(w) - north * math.sin(w)
    patches = value_noise(east - drift * math.sin(w), north - drift * math.cos(w), 6.0, look.seed)
    streaks = value_noise(along / 8.0, across, 0.35, look.seed + 1)
    return np.clip(patches * 1.6 - 0.55, 0, 1) * (0.45 + 0.55 * streaks)


def shade_sea(
    height: np.ndarray,
    slope_e: np.ndarray,
    slope_n: np.ndarray,
    foam: np.ndarray,
    view_dirs: np.ndarray,
    ranges: np.ndarray,
    light: Light,
    look: SeaLook,
) -> np.ndarray:
    """Linear BGR radiance ``[H, W, 3]`` of the sea; ``view_dirs`` are the camera's rays
    (pointing down to the surface), ``ranges`` their lengths in metres."""
    norm = 1.0 / np.sqrt(1.0 + slope_e * slope_e + slope_n * slope_n)
    nx, ny, nz = -slope_e * norm, -slope_n * norm, norm
    vx, vy, vz = (-view_dirs[..., i].astype(np.float32) for i in range(3))
    cos_v = np.maximum(nx * vx + ny * vy + nz * vz, 1e-3)
    reflectance = fresnel_lookup(cos_v)
    sky_mix = np.sqrt(np.minimum(np.maximum(2 * cos_v * nz - vz, 0.0), 1.0))

    sun = light.sun_vector().astype(np.float32)
    hx, hy, hz = vx + sun[0], vy + sun[1], vz + sun[2]
    h_len2 = hx * hx + hy * hy + hz * hz
    cos_d = np.maximum((nx * hx + ny * hy + nz * hz) / np.sqrt(h_len2), 1e-3)
    cos_d2 = cos_d * cos_d
    m2 = look.facet_variance
    facets = np.exp((cos_d2 - 1.0) / (cos_d2 * m2)) / (math.pi * m2 * cos_d2 * cos_d2)
    half_cos = np.sqrt(h_len2) * 0.5  # cosine of the angle between the view and the half vector
    glint = np.minimum(
        light.sun_radiance * fresnel_lookup(half_cos) * facets / (4 * cos_v * sun[2]), 40.0
    )

    crest = np.minimum(
        np.maximum((height - look.whitecap_height_m) / max(look.whitecap_height_m, 0.05), 0.0), 1.0
    )
    patchy = np.maximum(foam, 0.0)
    streaks = look.foam_cover * np.maximum(foam - 0.6, 0.0) * 2.5
    cover = np.minimum(crest * 1.5 * patchy + streaks, 1.0)
    veil = 1.0 - np.exp(-ranges / light.visibility_m).astype(np.float32)
    # light scattered up through the facets that face the sun, and through thin crests
    facing = (nx * sun[0] + ny * sun[1]) * (4.0 / max(math.hypot(sun[0], sun[1]), 0.2))
    swell = (1.0 + 0.8 * np.minimum(np.maximum(height, -0.5), 1.0)) * np.maximum(1.0 + facing, 0.3)
    channels = []
    for c, glint_tint, foam_tint in zip(
        range(3), (0.92, 0.98, 1.0), (0.95, 0.97, 1.0), strict=True
    ):
        sky = light.horizon_bgr[c] + (light.zenith_bgr[c] - light.horizon_bgr[c]) * sky_mix
        water = look.water_bgr[c] * swell
        value = water + reflectance * (sky - water) + glint_tint * glint
        value += cover * (0.75 * foam_tint - value)
        value += veil * (light.haze_bgr[c] - value)
        channels.append(value)
    return np.dstack(channels)


def upsample(coarse: np.ndarray, width: int, height: int) -> np.ndarray:
    """Bilinear resize of a smooth per-pixel quantity computed on a coarse grid."""
    return cv2.resize(coarse.astype(np.float32), (width, height), interpolation=cv2.INTER_LINEAR)
