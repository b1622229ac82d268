"""Moving sea surface: wave layers warped onto the image, colour, foam, sky reflection, sun glint.

Precomputed once (seeded): two wave layers, each as two periodic tiles of a directional height
field (FFT-filtered noise) with a mip pyramid:

- swell, 256 m period at 1 m per texel, wavelengths 12-80 m;
- wind waves, 25.6 m period at 5 cm per texel, wavelengths 0.4-5 m.

Each tile stores three uint8 channels: the slope of the surface along the sun's azimuth (shading),
the height (crests: foam above a sea-state threshold) and a foam texture. Per frame every tile is
warped onto a quarter-resolution image with ``cv2.warpPerspective`` through the ground-to-image
homography (``BORDER_WRAP``: the tiles are periodic), each tile scrolling at the deep-water phase
speed ``c = sqrt(g lambda / 2 pi)`` of its peak wavelength in its own direction, so the two tiles of
a layer interfere and the pattern changes as it moves instead of sliding rigidly.

Per-pixel view geometry on a coarse grid gives the Fresnel sky reflection (Schlick, R0 = 0.02) and
the sun-glint envelope: the probability that a facet tilts by the half angle between the view's
mirror direction and the sun, ``exp(-tan^2(beta) / sigma^2)`` with the Cox-Munk slope variance
``sigma^2 = 0.003 + 0.00512 U`` for wind speed ``U`` of the sea state. Within the envelope the
full-resolution frame gets per-frame random sparkles (1-3 px specular points).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from sarmission.geo.camera import CameraIntrinsics, CameraPose
from sim.kernels import compose_sea
from sim.scene import Scenario
from sim.truth_camera import rays

GRAVITY = 9.81
#: Wind speed (m/s) at 10 m for each Douglas sea state 0..6.
WIND_FOR_SEA_STATE = (1.0, 3.0, 5.0, 7.5, 10.0, 13.0, 17.0)
WATER_COLOURS: tuple[tuple[float, float, float], ...] = (
    (96.0, 86.0, 44.0),
    (108.0, 74.0, 32.0),
    (78.0, 86.0, 52.0),
    (92.0, 92.0, 60.0),
)
SKY_BGR = np.array([215.0, 200.0, 180.0], dtype=np.float32)
LOW_RES = 4
_GRID = (24, 40)
_VIEW_M = 400.0
_MAX_TEXELS = 2048


def _wave_tile(
    rng: np.random.Generator,
    n: int,
    texel_m: float,
    wavelengths: tuple[float, float],
    direction: float,
    spread: float,
    sun_azimuth: float,
) -> np.ndarray:
    """n x n x 3 uint8 periodic tile: (slope towards the sun, height, foam texture).

    Tile columns run east and rows south (``north = n0 - row * texel``); ``direction`` and
    ``sun_azimuth`` are radians clockwise from north.
    """
    k_col = np.fft.fftfreq(n, d=texel_m)[None, :]  # cycles per metre, east
    k_row = np.fft.fftfreq(n, d=texel_m)[:, None]  # cycles per metre, south
    k = np.hypot(k_col, k_row)
    k_safe = np.where(k > 0, k, 1.0)
    lo, hi = 1.0 / wavelengths[1], 1.0 / wavelengths[0]
    band = np.exp(-0.5 * (np.log(k_safe / math.sqrt(lo * hi)) / (0.35 * math.log(hi / lo))) ** 2)
    band *= k_safe**-1.5
    east, south = math.sin(direction), -math.cos(direction)
    cos_dir = (k_col * east + k_row * south) / k_safe
    spreading = np.maximum(cos_dir, 0.0) ** spread + 0.05
    amp = np.where(k > 0, band * spreading, 0.0)
    spec = amp * (rng.standard_normal((n, n)) + 1j * rng.standard_normal((n, n)))
    height = np.real(np.fft.ifft2(spec))
    se, ss = math.sin(sun_azimuth), -math.cos(sun_azimuth)
    slope = np.real(np.fft.ifft2(spec * 2j * math.pi * (k_col * se + k_row * ss)))
    height /= max(float(height.std()), 1e-9)
    slope /= max(float(slope.std()), 1e-9)
    foam_freq = np.exp(-2 * (np.pi * 1.2 * texel_m) ** 2 * k * k)
    foam = np.real(np.fft.ifft2(np.fft.fft2(rng.standard_normal((n, n))) * foam_freq))
    foam /= max(float(foam.std()), 1e-9)
    chans = [slope, height, foam]
    return np.stack([np.clip(128 + 40 * c, 0, 255) for c in chans], -1).astype(np.uint8)


class _Layer:
    """One periodic tile scrolling at ``velocity_ne`` m/s, with mip levels.

    Each level is stored repeated to about ``_VIEW_M`` metres (at most ``_MAX_TEXELS`` texels) so
    that a view usually falls inside it: ``BORDER_WRAP`` then only handles the rest, and it is
    slow for every pixel it has to wrap.
    """

    def __init__(
        self, tile: np.ndarray, texel_m: float, velocity_ne: tuple[float, float], weight: float
    ) -> None:
        self.texel_m = texel_m
        self.period_m = texel_m * tile.shape[0]
        self.velocity_ne = velocity_ne
        self.weight = weight
        self._tiles = [tile]
        while self._tiles[-1].shape[0] > 16:
            half = self._tiles[-1].shape[0] // 2
            self._tiles.append(
                cv2.resize(self._tiles[-1], (half, half), interpolation=cv2.INTER_AREA)
            )
        self._big: dict[int, np.ndarray] = {}

    def _level(self, level: int) -> np.ndarray:
        if level not in self._big:
            tile = self._tiles[level]
            n = tile.shape[0]
            texel = self.period_m / n
            reps = max(1, min(_MAX_TEXELS // n, math.ceil(_VIEW_M / (texel * n))))
            self._big[level] = np.ascontiguousarray(np.tile(tile, (reps, reps, 1)))
        return self._big[level]

    def warp(
        self,
        h_lo: np.ndarray,
        size: tuple[int, int],
        t: float,
        metres_per_px: float,
        near_ne: np.ndarray,
    ) -> np.ndarray:
        """The tile warped onto the low-resolution image (uint8 x 3), offset for time ``t``."""
        level = int(
            np.clip(
                math.floor(math.log2(max(metres_per_px / self.texel_m, 1.0))),
                0,
                len(self._tiles) - 1,
            )
        )
        big = self._level(level)
        s = self.period_m / self._tiles[level].shape[0]
        span = s * big.shape[0]
        # Put the big tile's texel (0, 0) a whole number of periods from the scrolled origin,
        # half a tile north-west of the view centre, so the view lies inside it.
        shift = np.array(self.velocity_ne) * t
        corner = near_ne + np.array([span / 2, -span / 2])
        n0, e0 = shift + self.period_m * np.round((corner - shift) / self.period_m)
        a = np.array([[0.0, -s, n0], [s, 0.0, e0], [0.0, 0.0, 1.0]])
        return cv2.warpPerspective(
            big, h_lo @ a, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP
        )


class SeaSurface:
    """The sea of one scenario; :meth:`render_lowres` draws it for a camera pose and time."""

    def __init__(self, scenario: Scenario) -> None:
        rng = np.random.default_rng([scenario.seed, 21])
        self.sea_state = scenario.sea_state
        wind = WIND_FOR_SEA_STATE[scenario.sea_state]
        self.slope_var = 0.003 + 0.00512 * wind
        self.sun = scenario.sun_direction_ned
        self.water = np.asarray(
            WATER_COLOURS[int(rng.integers(len(WATER_COLOURS)))], dtype=np.float32
        ) * np.float32(rng.uniform(0.9, 1.1))
        to = math.radians(scenario.wind_from_deg + 180.0)
        sun_az = math.radians(scenario.sun_azimuth_deg)
        self.layers: list[_Layer] = []
        swell_w = 0.35 + 0.12 * scenario.sea_state
        wind_w = 0.25 + 0.18 * scenario.sea_state
        for n, texel, band, peak, weight, spread in (
            (256, 1.0, (12.0, 80.0), 40.0, swell_w, 6.0),
            (512, 0.05, (0.4, 5.0), 2.0, wind_w, 2.0),
        ):
            for dev, speed_scale, share in ((0.15, 1.0, 0.6), (-0.3, 0.8, 0.4)):
                d = to + dev + float(rng.normal(0, 0.1))
                tile = _wave_tile(rng, n, texel, band, d, spread, sun_az)
                c = speed_scale * math.sqrt(GRAVITY * peak / (2 * math.pi))
                self.layers.append(
                    _Layer(tile, texel, (c * math.cos(d), c * math.sin(d)), weight * share)
                )
        self.foam_threshold = 2.9 - 0.28 * scenario.sea_state

    def glint_and_fresnel(
        self, intr: CameraIntrinsics, pose: CameraPose
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(glint envelope, Fresnel reflectance, sea mask) on a coarse grid of float32 maps whose
        samples lie on the image's outer pixel edges."""
        gh, gw = _GRID
        us = np.linspace(-0.5, intr.width - 0.5, gw)
        vs = np.linspace(-0.5, intr.height - 0.5, gh)
        uu, vv = np.meshgrid(us, vs)
        d = rays(intr, pose, np.stack([uu.ravel(), vv.ravel()], axis=1))
        cos_view = np.clip(d[:, 2], 0.0, 1.0)
        mirror = d * np.array([1.0, 1.0, -1.0])
        cos2b = np.clip(mirror @ self.sun, -1.0, 1.0)  # cos of twice the facet tilt
        half = np.arccos(cos2b) / 2
        glint = np.exp(-(np.tan(np.minimum(half, 1.5)) ** 2) / self.slope_var)
        fresnel = 0.02 + 0.98 * (1.0 - cos_view) ** 5
        sea = (d[:, 2] > 0.02).astype(np.float64)
        glint_map, fresnel_map, sea_map = (
            m.reshape(gh, gw).astype(np.float32) for m in (glint * sea, fresnel, sea)
        )
        return glint_map, fresnel_map, sea_map

    def render_lowres(
        self, intr: CameraIntrinsics, pose: CameraPose, h_ground: np.ndarray, t: float, bias: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """The sea at 1/:data:`LOW_RES` resolution as (BGR uint8, coarse glint envelope).

        ``h_ground`` maps ground (north, east) to full-resolution pixels. ``bias`` is subtracted
        from every pixel (the mean of the detail added later at full resolution).
        """
        size = (math.ceil(intr.width / LOW_RES), math.ceil(intr.height / LOW_RES))
        k = 1.0 / LOW_RES
        to_lo = np.array([[k, 0.0, 0.5 * k - 0.5], [0.0, k, 0.5 * k - 0.5], [0.0, 0.0, 1.0]])
        h_lo = to_lo @ h_ground
        centre = np.linalg.solve(h_lo, np.array([size[0] / 2, size[1] / 2, 1.0]))
        near = centre[:2] / centre[2] if centre[2] != 0 else np.zeros(2)
        probe = np.linalg.solve(h_lo, np.array([size[0] / 2 + 1, size[1] / 2, 1.0]))
        metres_per_px = float(np.hypot(*(probe[:2] / probe[2] - near))) if probe[2] else 1.0
        layers = np.stack([layer.warp(h_lo, size, t, metres_per_px, near) for layer in self.layers])
        weights = np.array([layer.weight for layer in self.layers])
        coarse = self.glint_and_fresnel(intr, pose)
        glint, fresnel, sea = (cv2.resize(m, size, interpolation=cv2.INTER_LINEAR) for m in coarse)
        out = np.empty((size[1], size[0], 3), np.uint8)
        compose_sea(
            layers,
            weights,
            glint,
            fresnel,
            sea,
            self.water.astype(np.float64),
            SKY_BGR.astype(np.float64),
            9.0 + 2.5 * self.sea_state,
            self.foam_threshold,
            float(bias),
            out,
        )
        return out, coarse[0]

    def add_sparkles(self, frame: np.ndarray, glint_grid: np.ndarray, t: float, seed: int) -> None:
        """Scatter specular sparkles over ``frame`` with density following the coarse glint
        envelope ``glint_grid`` (from :meth:`glint_and_fresnel`)."""
        flat = glint_grid.ravel().astype(np.float64)
        height, width = frame.shape[:2]
        gh, gw = glint_grid.shape
        cell_px = (width / (gw - 1)) * (height / (gh - 1))
        total = float(flat.sum()) * cell_px
        if total < 1.0:
            return
        density = 0.0002 * (1 + self.sea_state)
        rng = np.random.default_rng([seed, 22, int(round(t * 1e6))])
        count = min(int(rng.poisson(density * total)), 6000)
        if count == 0:
            return
        cdf = np.cumsum(flat)
        idx = np.minimum(np.searchsorted(cdf, rng.random(count) * cdf[-1]), flat.size - 1)
        u = ((idx % gw) + rng.random(count) - 0.5) * (width / (gw - 1))
        v = ((idx // gw) + rng.random(count) - 0.5) * (height / (gh - 1))
        u = np.clip(u.astype(np.int64), 1, width - 2)
        v = np.clip(v.astype(np.int64), 1, height - 2)
        level = (150 + 105 * rng.random(count) * np.sqrt(flat[idx])).astype(np.float32)
        spread = rng.random(count) < 0.5
        for du, dv, f in ((0, 0, 1.0), (1, 0, 0.45), (-1, 0, 0.45), (0, 1, 0.45), (0, -1, 0.45)):
            keep = spread if (du or dv) else np.ones(count, bool)
            vv, uu = v[keep] + dv, u[keep] + du
            cur = frame[vv, uu].astype(np.float32)
            lev = level[keep, None]
            frame[vv, uu] = np.maximum(cur, cur + f * (lev - cur)).astype(np.uint8)
