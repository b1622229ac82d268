"""The sea: scrolling fractal noise sampled at every pixel's ground position.

Three tileable tiles (:func:`~altworld.noise.fractal_tile`), each at its own ground scale and
scrolling in its own direction, sum to a surface pattern that modulates the clip's water colour;
whitecaps appear where the pattern crosses a threshold that falls with the sea state, sparkles
where a fine fast tile peaks inside the sun's specular zone. Not a wave model, on purpose: it
looks unlike both other renderers' seas.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from altworld.camera import View
from altworld.noise import fractal_tile, smoothstep

#: Water colours (BGR): navy, teal, green-grey, turquoise, silt brown, slate.
WATERS = ((90, 50, 20), (110, 90, 30), (90, 100, 70), (150, 130, 40), (70, 100, 110), (100, 85, 70))


@dataclass
class Sea:
    """One clip's sea; :meth:`render` draws it for a view at time ``t``."""

    colour: np.ndarray
    state: float  # 0 calm .. 1 rough
    tiles: list[np.ndarray]
    scales: np.ndarray  # metres per tile pixel, per tile
    drifts: np.ndarray  # tile pixels per second (x, y), per tile
    tint_tile: np.ndarray
    sun_pixel: tuple[float, float]
    sun_radius: float
    glint: float

    @classmethod
    def draw(cls, rng: np.random.Generator) -> Sea:
        base = np.asarray(WATERS[int(rng.integers(len(WATERS)))], np.float32)
        base = np.clip(base * rng.uniform(0.7, 1.3) + rng.normal(0, 8, 3), 5, 250)
        tiles = [fractal_tile(rng, 256, s) for s in (2.4, 2.8, 1.6)]
        scales = np.array([rng.uniform(0.08, 0.2), rng.uniform(0.25, 0.6), rng.uniform(0.02, 0.05)])
        angles = rng.uniform(0, 2 * math.pi, 3)
        speeds = np.array([rng.uniform(2, 8), rng.uniform(1, 4), rng.uniform(8, 25)])
        drifts = np.stack([speeds * np.cos(angles), speeds * np.sin(angles)], axis=1)
        return cls(
            colour=base.astype(np.float32),
            state=float(rng.uniform(0, 1)),
            tiles=tiles,
            scales=scales,
            drifts=drifts,
            tint_tile=fractal_tile(rng, 128, 3.0),
            sun_pixel=(float(rng.uniform(-400, 2300)), float(rng.uniform(-300, 1400))),
            sun_radius=float(rng.uniform(250, 900)),
            glint=float(rng.uniform(0, 1)),
        )

    def _sample(
        self, tile: np.ndarray, east: np.ndarray, north: np.ndarray, scale: float, shift
    ) -> np.ndarray:
        size = tile.shape[0]
        mx = np.mod(east / scale + shift[0], size).astype(np.float32)
        my = np.mod(-north / scale + shift[1], size).astype(np.float32)
        return cv2.remap(tile, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)

    def render(self, view: View, t: float) -> np.ndarray:
        """The sea as float32 BGR (0-255) for ``view`` at clip time ``t`` seconds, drawn at half
        resolution (the pattern is smooth at the pixel scale) and scaled up."""
        full = (view.width, view.height_px)
        view = dataclasses.replace(
            view,
            width=view.width // 2,
            height_px=view.height_px // 2,
            sensor_width=view.sensor_width // 2,
        )
        east, north = view.ground_of_pixels()
        layers = [
            self._sample(tile, east, north, float(scale), drift * t)
            for tile, scale, drift in zip(self.tiles, self.scales, self.drifts, strict=True)
        ]
        tint = self._sample(self.tint_tile, east, north, 0.6, (0.0, 0.0))
        surface = layers[0] + 0.7 * layers[1]
        amplitude = 0.05 + 0.12 * self.state
        shade = 1.0 + amplitude * surface + 0.08 * tint
        colour = self.colour[None, None, :] * shade[..., None]
        colour += np.array([12.0, 6.0, -6.0], np.float32) * tint[..., None]
        caps = smoothstep(surface + 0.4 * layers[2], 3.3 - 1.4 * self.state, 3.8 - 1.4 * self.state)
        colour += caps[..., None] * (235.0 - colour) * 0.85
        if self.glint > 0.3:
            v, u = _pixel_grid(view.width, view.height_px)
            zone = np.exp(
                -((2 * u - self.sun_pixel[0]) ** 2 + (2 * v - self.sun_pixel[1]) ** 2)
                / (2 * self.sun_radius**2)
            )
            sparkle = smoothstep(layers[2] + 0.5 * layers[0], 2.2, 3.0) * zone * self.glint
            colour += sparkle[..., None] * 255.0
        return cv2.resize(colour.astype(np.float32), full, interpolation=cv2.INTER_LINEAR)


@lru_cache(maxsize=4)
def _pixel_grid(width: int, height: int) -> np.ndarray:
    """Row and column of every pixel (float32), the same for every frame of a clip."""
    return np.mgrid[0:height, 0:width].astype(np.float32)
