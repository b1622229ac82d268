"""Land: one ground raster per clip, warped through each frame's homography.

Two or three materials of a biome blended by large-scale noise, fine grain per material, a
winding track, and static clutter with shadows cast along the sun: tree crowns, bushes, rocks,
logs, stumps and hay bales. The clutter is background (never boxed); much of it is person-sized.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from altworld.camera import View
from altworld.noise import fractal_tile

#: biome -> (materials BGR, grain amplitude, track colour, clutter per 100 m^2:
#: trees, bushes, rocks, logs, stumps, bales)
BIOMES: dict[str, tuple] = {
    "meadow": (
        ((60, 140, 90), (70, 150, 140), (60, 90, 110)),
        18,
        (110, 150, 170),
        (0.05, 0.6, 0.1, 0.05, 0.05, 0.08),
    ),
    "forest": (
        ((40, 80, 60), (40, 70, 90), (30, 60, 40)),
        22,
        (70, 100, 120),
        (1.2, 0.8, 0.1, 0.3, 0.2, 0.0),
    ),
    "rocky": (
        ((120, 125, 130), (95, 100, 105), (80, 120, 110)),
        26,
        (150, 160, 165),
        (0.02, 0.2, 1.5, 0.02, 0.0, 0.0),
    ),
    "snow": (
        ((240, 235, 230), (225, 215, 205), (200, 195, 190)),
        8,
        (210, 200, 195),
        (0.15, 0.1, 0.3, 0.03, 0.0, 0.0),
    ),
    "sand": (
        ((140, 185, 210), (120, 165, 195), (100, 140, 160)),
        12,
        (150, 195, 220),
        (0.01, 0.3, 0.05, 0.05, 0.0, 0.0),
    ),
    "stubble": (
        ((90, 170, 200), (70, 140, 170), (60, 110, 120)),
        20,
        (80, 120, 140),
        (0.0, 0.05, 0.02, 0.0, 0.0, 0.4),
    ),
}


@dataclass
class Land:
    """One clip's ground raster and the transform from its pixels to ground metres."""

    raster: np.ndarray  # uint8 BGR
    origin: tuple[float, float]  # east, north of pixel (0, 0)'s corner
    resolution: float  # metres per raster pixel
    biome: str
    base: tuple[float, float, float]

    def render(self, view: View) -> np.ndarray:
        """The ground as float32 BGR (0-255) seen through ``view``."""
        r, (east0, north0) = self.resolution, self.origin
        to_ground = np.array([[r, 0.0, east0], [0.0, -r, north0], [0.0, 0.0, 1.0]])
        matrix = view.homography() @ to_ground
        image = cv2.warpPerspective(
            self.raster,
            matrix,
            (view.width, view.height_px),
            flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REFLECT,
        )
        return image.astype(np.float32)


def draw_land(
    rng: np.random.Generator,
    bounds: tuple[float, float, float, float],
    resolution: float,
    sun_deg: float,
) -> Land:
    """A ground raster covering ``bounds`` (east min, north min, east max, north max) at
    ``resolution`` m per pixel, with shadows cast towards azimuth ``sun_deg`` + 180."""
    biome = str(rng.choice(list(BIOMES)))
    materials, grain, track, density = BIOMES[biome]
    e0, n0, e1, n1 = bounds
    width, height = int((e1 - e0) / resolution) + 1, int((n1 - n0) / resolution) + 1
    blend = cv2.resize(fractal_tile(rng, 128, 3.0), (width, height), interpolation=cv2.INTER_CUBIC)
    blend2 = cv2.resize(fractal_tile(rng, 128, 2.5), (width, height), interpolation=cv2.INTER_CUBIC)
    cols = [np.clip(np.asarray(m, np.float32) + rng.normal(0, 10, 3), 0, 255) for m in materials]
    w1 = np.clip(0.5 + 0.6 * blend, 0, 1)[..., None]
    w2 = np.clip(blend2 - 0.6, 0, 1)[..., None]
    ground = cols[0] * (1 - w1) + cols[1] * w1
    ground = ground * (1 - w2) + cols[2] * w2
    fine = fractal_tile(rng, 256, 1.2)
    reps = (height // 256 + 1, width // 256 + 1)
    grain_scale = max(0.02, 0.05 / resolution)
    fine = cv2.resize(np.tile(fine, reps), None, fx=grain_scale, fy=grain_scale)
    fine = np.tile(fine, (height // fine.shape[0] + 1, width // fine.shape[1] + 1))[:height, :width]
    ground = ground + (grain * fine)[..., None]
    raster = np.clip(ground, 0, 255).astype(np.uint8)
    px = 1.0 / resolution
    _track(rng, raster, track, px)
    area = (e1 - e0) * (n1 - n0) / 100.0
    sun = math.radians(sun_deg + 180.0)
    shadow_dir = (math.sin(sun), -math.cos(sun))  # raster x east, y south
    kinds = ("tree", "bush", "rock", "log", "stump", "bale")
    for kind, per in zip(kinds, density, strict=True):
        for _ in range(int(rng.poisson(per * area))):
            _clutter(
                rng, raster, kind, (rng.uniform(0, width), rng.uniform(0, height)), px, shadow_dir
            )
    return Land(raster, (e0, n1), resolution, biome, tuple(float(x) for x in cols[0]))


def _track(rng: np.random.Generator, raster: np.ndarray, colour, px: float) -> None:
    height, width = raster.shape[:2]
    if rng.random() < 0.3:
        return
    x, y = rng.uniform(0, width), 0.0
    heading = rng.uniform(-0.5, 0.5)
    points = []
    while 0 <= y <= height and -width <= x <= 2 * width:
        points.append((x, y))
        heading += rng.normal(0, 0.15)
        x += math.sin(heading) * 2 * px
        y += math.cos(heading) * 2 * px
    if len(points) > 1:
        col = tuple(float(c) for c in np.clip(np.asarray(colour) + rng.normal(0, 12, 3), 0, 255))
        cv2.polylines(
            raster,
            [np.array(points, np.int32)],
            False,
            col,
            max(1, int(rng.uniform(1.0, 3.0) * px)),
            cv2.LINE_AA,
        )


def _clutter(
    rng: np.random.Generator, raster: np.ndarray, kind: str, at, px: float, shadow_dir
) -> None:
    x, y = at
    dark = (0.55, 0.55, 0.55)

    def shade(radius: float, length: float) -> None:
        cx, cy = int(x + shadow_dir[0] * length * px), int(y + shadow_dir[1] * length * px)
        r = max(1, int(radius * px))
        roi = raster[max(cy - r, 0) : cy + r, max(cx - r, 0) : cx + r]
        if roi.size:
            mask = np.zeros(roi.shape[:2], np.uint8)
            cv2.circle(mask, (cx - max(cx - r, 0), cy - max(cy - r, 0)), r, 1, -1)
            roi[mask > 0] = (roi[mask > 0] * np.asarray(dark)).astype(np.uint8)

    def jitter(base) -> tuple[float, float, float]:
        return tuple(
            float(c) for c in np.clip(np.asarray(base, np.float64) + rng.normal(0, 12, 3), 0, 255)
        )

    if kind == "tree":
        radius = rng.uniform(1.2, 4.5)
        shade(radius, radius * 1.2)
        green = jitter((35, 85, 45))
        cv2.circle(raster, (int(x), int(y)), int(radius * px), green, -1, cv2.LINE_AA)
        for _ in range(12):
            a, r = rng.uniform(0, 2 * math.pi), radius * math.sqrt(rng.random()) * 0.8
            c = (int(x + r * math.cos(a) * px), int(y + r * math.sin(a) * px))
            cv2.circle(
                raster, c, max(1, int(radius * 0.3 * px)), jitter((50, 115, 70)), -1, cv2.LINE_AA
            )
    elif kind == "bush":
        radius = rng.uniform(0.25, 0.8)
        shade(radius, radius * 0.8)
        cv2.circle(
            raster,
            (int(x), int(y)),
            max(1, int(radius * px)),
            jitter((40, 95, 55)),
            -1,
            cv2.LINE_AA,
        )
    elif kind == "rock":
        radius = rng.uniform(0.15, 1.2)
        shade(radius, radius * 0.6)
        angles = np.sort(rng.uniform(0, 2 * math.pi, 7))
        pts = [
            (
                x + radius * px * rng.uniform(0.6, 1.1) * math.cos(a),
                y + radius * px * rng.uniform(0.6, 1.1) * math.sin(a),
            )
            for a in angles
        ]
        cv2.fillPoly(raster, [np.array(pts, np.int32)], jitter((130, 135, 140)), cv2.LINE_AA)
    elif kind == "log":
        length, a = rng.uniform(1.5, 5.0), rng.uniform(0, math.pi)
        dx, dy = math.cos(a) * length * px / 2, math.sin(a) * length * px / 2
        cv2.line(
            raster,
            (int(x - dx), int(y - dy)),
            (int(x + dx), int(y + dy)),
            jitter((50, 80, 110)),
            max(1, int(rng.uniform(0.15, 0.4) * px)),
            cv2.LINE_AA,
        )
    elif kind == "stump":
        radius = rng.uniform(0.15, 0.35)
        shade(radius, radius * 1.5)
        cv2.circle(
            raster,
            (int(x), int(y)),
            max(1, int(radius * px)),
            jitter((80, 120, 150)),
            -1,
            cv2.LINE_AA,
        )
    elif kind == "bale":
        radius = rng.uniform(0.5, 0.8)
        shade(radius, radius)
        cv2.circle(
            raster,
            (int(x), int(y)),
            max(1, int(radius * px)),
            jitter((100, 190, 215)),
            -1,
            cv2.LINE_AA,
        )
