"""Painted ground: a texture painted once per world, warped per frame; the city painter.

The texture (``texel_m`` metres per texel, north up) covers the scenario area plus a margin:
grass and yards, asphalt roads with dashed centre lines and sidewalks, car parks with stall
lines, flat roofs with parapets and rooftop units, trees, and the shadows of buildings and trees
cast away from the sun (length ``height / tan(sun elevation)``). Parked cars (``static`` objects)
are painted in with :func:`sim.sprites.draw_parts`, so they are annotated like any object but cost
nothing per frame. Per frame the texture (or a coarser mip level) is warped to half resolution
through the ground-to-image homography and upsampled.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from sim.scene import SceneObject, World
from sim.sprites import draw_parts

GRASS = (62.0, 112.0, 84.0)
ASPHALT = (92.0, 94.0, 97.0)
SIDEWALK = (165.0, 168.0, 170.0)
LOT = (104.0, 106.0, 109.0)
TREE = (38.0, 78.0, 46.0)
MARGIN_M = 100.0


class PaintedGround:
    """A ground texture over a world's area plus :data:`MARGIN_M`, painted once by
    :meth:`_paint` (subclasses), its mip levels, and the per-frame warp."""

    def __init__(self, world: World, texel_m: float = 0.1) -> None:
        sc = world.scenario
        self.texel_m = texel_m
        n0, e0, n1, e1 = sc.area_ne
        self.north_top = n1 + MARGIN_M
        self.east_left = e0 - MARGIN_M
        rows = int(math.ceil((n1 - n0 + 2 * MARGIN_M) / texel_m))
        cols = int(math.ceil((e1 - e0 + 2 * MARGIN_M) / texel_m))
        rng = np.random.default_rng([sc.seed, 31])
        self._sun = sc.sun_direction_ned
        self.texture = self._paint(world, rows, cols, rng)
        self._levels = [self.texture]
        while min(self._levels[-1].shape[:2]) > 64:
            self._levels.append(cv2.pyrDown(self._levels[-1]))

    # -- painting ------------------------------------------------------------------------
    def texel(self, north: float, east: float) -> tuple[float, float]:
        """(col, row) of a ground point."""
        return (east - self.east_left) / self.texel_m, (self.north_top - north) / self.texel_m

    def texel_from_ground(self) -> np.ndarray:
        """3x3 matrix taking homogeneous ground ``(north, east, 1)`` to texel ``(col, row, 1)``."""
        s = self.texel_m
        return np.array(
            [[0.0, 1 / s, -self.east_left / s], [-1 / s, 0.0, self.north_top / s], [0.0, 0.0, 1.0]]
        )

    def _rect(
        self, img: np.ndarray, rect: tuple[float, float, float, float], bgr: tuple[float, ...]
    ) -> None:
        n0, e0, n1, e1 = rect
        c0, r0 = self.texel(n1, e0)
        c1, r1 = self.texel(n0, e1)
        cv2.rectangle(img, (int(c0), int(r0)), (int(c1), int(r1)), bgr, -1)

    def _poly(self, img: np.ndarray, pts_ne: np.ndarray, bgr: tuple[float, ...]) -> None:
        pts = np.array([self.texel(n, e) for n, e in pts_ne], dtype=np.int32)
        cv2.fillConvexPoly(img, pts, bgr, lineType=cv2.LINE_AA)

    def _paint(self, world: World, rows: int, cols: int, rng: np.random.Generator) -> np.ndarray:
        raise NotImplementedError

    def _paint_object(self, img: np.ndarray, obj: SceneObject) -> None:
        state = obj.state_at(0.0)
        draw_parts(
            img,
            self.texel_from_ground() @ state.local_to_ne(),
            state.parts,
            state.visibility,
            blur_px=0.0,
        )

    def _paint_static(self, img: np.ndarray, world: World) -> None:
        """Static objects (parked cars, resting animals) painted in: annotated like any object,
        free per frame."""
        for obj in world.objects:
            if obj.static:
                self._paint_object(img, obj)

    # -- per frame -----------------------------------------------------------------------
    def render(self, h_ground: np.ndarray, width: int, height: int) -> np.ndarray:
        """The ground seen through ``h_ground`` (ground north/east -> full-resolution pixels)."""
        half_w, half_h = math.ceil(width / 2), math.ceil(height / 2)
        to_half = np.array([[0.5, 0.0, -0.25], [0.0, 0.5, -0.25], [0.0, 0.0, 1.0]])
        h = to_half @ h_ground @ np.linalg.inv(self.texel_from_ground())
        # Texels per half-resolution pixel at the image centre picks the mip level.
        c = np.linalg.solve(h, np.array([half_w / 2, half_h / 2, 1.0]))
        d = np.linalg.solve(h, np.array([half_w / 2 + 1, half_h / 2, 1.0]))
        step = float(np.hypot(*(d[:2] / d[2] - c[:2] / c[2]))) if c[2] and d[2] else 1.0
        level = int(np.clip(math.floor(math.log2(max(step, 1.0))), 0, len(self._levels) - 1))
        scale = np.diag([2.0**-level, 2.0**-level, 1.0])
        scale[:2, 2] = 0.5 * 2.0**-level - 0.5
        m = h @ np.linalg.inv(scale)
        half_img = cv2.warpPerspective(
            self._levels[level],
            m,
            (half_w, half_h),
            flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REFLECT,
        )
        return cv2.resize(half_img, (width, height), interpolation=cv2.INTER_LINEAR)


class UrbanGround(PaintedGround):
    """The painted city of one urban :class:`World`."""

    def __init__(self, world: World, texel_m: float = 0.1) -> None:
        if world.layout is None:
            raise ValueError("UrbanGround needs an urban world (with a street layout)")
        super().__init__(world, texel_m)

    def _paint(self, world: World, rows: int, cols: int, rng: np.random.Generator) -> np.ndarray:
        layout = world.layout
        assert layout is not None
        img = np.empty((rows, cols, 3), np.uint8)
        img[:] = GRASS
        n_lo, e_lo = self.north_top - rows * self.texel_m, self.east_left
        n_hi, e_hi = self.north_top, self.east_left + cols * self.texel_m
        north_roads, east_roads = layout.road_lines((n_lo, e_lo, n_hi, e_hi))
        half, walk = layout.road_m / 2, layout.road_m / 2 + 2.5
        for rn in north_roads:
            self._rect(img, (rn - walk, e_lo, rn + walk, e_hi), SIDEWALK)
        for re_ in east_roads:
            self._rect(img, (n_lo, re_ - walk, n_hi, re_ + walk), SIDEWALK)
        for rn in north_roads:
            self._rect(img, (rn - half, e_lo, rn + half, e_hi), ASPHALT)
        for re_ in east_roads:
            self._rect(img, (n_lo, re_ - half, n_hi, re_ + half), ASPHALT)
        for rn in north_roads:
            for e in np.arange(e_lo, e_hi, 6.0):
                self._rect(img, (rn - 0.07, e, rn + 0.07, e + 3.0), (220, 222, 225))
        for re_ in east_roads:
            for n in np.arange(n_lo, n_hi, 6.0):
                self._rect(img, (n, re_ - 0.07, n + 3.0, re_ + 0.07), (220, 222, 225))
        for lot in layout.lots:
            self._rect(img, lot, LOT)
            ln0, le0, ln1, le1 = lot
            for e in np.arange(le0 + 1.0, le1 - 1.0, 2.5):
                for n in np.arange(ln0 + 0.5, ln1 - 5.0, 6.0):
                    self._rect(img, (n, e, n + 4.8, e + 0.1), (200, 200, 200))
        # Shadows first (they fall on the ground), then roofs and trees on top.
        sun = self._sun
        away = -sun[:2] / max(float(np.hypot(*sun[:2])), 1e-9)
        per_m = 1.0 / max(math.tan(math.asin(min(1.0, -sun[2]))), 0.05)
        shadow = np.zeros((rows, cols), np.uint8)
        for b in layout.buildings:
            n0, e0, n1, e1 = b.rect
            off = away * b.height_m * per_m
            corners = np.array([(n0, e0), (n0, e1), (n1, e1), (n1, e0)])
            pts = np.concatenate([corners, corners + off])
            hull = cv2.convexHull(np.array([self.texel(n, e) for n, e in pts], np.float32))
            cv2.fillConvexPoly(shadow, hull.astype(np.int32), 255)
        for tn, te, tr in layout.trees:
            c, r = self.texel(tn + away[0] * 4 * per_m, te + away[1] * 4 * per_m)
            cv2.circle(shadow, (int(c), int(r)), int(tr / self.texel_m), 255, -1)
        shadow = cv2.GaussianBlur(shadow, (0, 0), 0.3 / self.texel_m)
        img = img.astype(np.float32) * (1.0 - 0.5 * shadow[..., None] / 255.0)
        img = img.astype(np.uint8)
        for b in layout.buildings:
            n0, e0, n1, e1 = b.rect
            edge = tuple(0.75 * c for c in b.roof_bgr)
            self._rect(img, b.rect, edge)
            self._rect(img, (n0 + 0.4, e0 + 0.4, n1 - 0.4, e1 - 0.4), b.roof_bgr)
            for _ in range(int(rng.integers(0, 4))):
                un, ue = (
                    rng.uniform(n0 + 1, max(n0 + 1.1, n1 - 3)),
                    rng.uniform(e0 + 1, max(e0 + 1.1, e1 - 3)),
                )
                self._rect(
                    img,
                    (un, ue, un + rng.uniform(1, 2.5), ue + rng.uniform(1, 2.5)),
                    (150, 152, 155),
                )
        for tn, te, tr in layout.trees:
            c, r = self.texel(tn, te)
            rad = int(tr / self.texel_m)
            cv2.circle(img, (int(c), int(r)), rad, TREE, -1, cv2.LINE_AA)
            cv2.circle(
                img,
                (int(c - 0.25 * rad), int(r - 0.25 * rad)),
                int(0.55 * rad),
                (48, 98, 60),
                -1,
                cv2.LINE_AA,
            )
        grain = rng.standard_normal((rows // 4 + 1, cols // 4 + 1)).astype(np.float32)
        grain = cv2.resize(grain, (cols, rows), interpolation=cv2.INTER_LINEAR)
        img = np.clip(img.astype(np.float32) * (1.0 + 0.06 * grain[..., None]), 0, 255)
        img = img.astype(np.uint8)
        self._paint_static(img, world)
        return img
