"""Flat shapes in an object's own frame (metres; x to its right, y ahead) with colour and opacity.

``solid`` shapes are the object itself (they make its ground-truth box); the others are what it
does to its surroundings (shadow, ring of disturbed water, wake).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BGR = tuple[float, float, float]


@dataclass(frozen=True)
class Ellipse:
    centre: tuple[float, float]
    radii: tuple[float, float]
    colour: BGR
    opacity: float = 1.0
    angle_deg: float = 0.0
    solid: bool = True

    def inside(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        a = np.radians(self.angle_deg)
        dx, dy = x - self.centre[0], y - self.centre[1]
        px = dx * np.cos(a) + dy * np.sin(a)
        py = -dx * np.sin(a) + dy * np.cos(a)
        return (px / self.radii[0]) ** 2 + (py / self.radii[1]) ** 2 <= 1.0

    def reach(self) -> float:
        return float(np.hypot(*self.centre) + max(self.radii))


@dataclass(frozen=True)
class Capsule:
    start: tuple[float, float]
    end: tuple[float, float]
    radius: float
    colour: BGR
    opacity: float = 1.0
    solid: bool = True

    def inside(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        ax, ay = self.start
        bx, by = self.end
        ex, ey = bx - ax, by - ay
        length2 = max(ex * ex + ey * ey, 1e-12)
        s = np.clip(((x - ax) * ex + (y - ay) * ey) / length2, 0.0, 1.0)
        return (x - ax - s * ex) ** 2 + (y - ay - s * ey) ** 2 <= self.radius**2

    def reach(self) -> float:
        return float(max(np.hypot(*self.start), np.hypot(*self.end)) + self.radius)


@dataclass(frozen=True)
class Polygon:
    points: tuple[tuple[float, float], ...]
    colour: BGR
    opacity: float = 1.0
    solid: bool = True

    def inside(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Even-odd rule: a point is inside when a ray to its right crosses an odd count of
        edges."""
        result = np.zeros(np.shape(x), bool)
        pts = self.points
        for (x0, y0), (x1, y1) in zip(pts, pts[1:] + pts[:1], strict=True):
            if y0 == y1:
                continue
            straddles = (y0 > y) != (y1 > y)
            cross_x = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
            result ^= straddles & (x < cross_x)
        return result

    def reach(self) -> float:
        return float(max(np.hypot(px, py) for px, py in self.points))


Shape = Ellipse | Capsule | Polygon


def mix(a: BGR, b: BGR, share_of_b: float) -> BGR:
    """Colour ``a`` veiled by ``b`` (e.g. clothing under a film of water)."""
    return tuple(float(x + (y - x) * share_of_b) for x, y in zip(a, b, strict=True))  # type: ignore[return-value]
