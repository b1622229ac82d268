"""Drawing flat objects (:class:`sim.scene.Part` lists) into an image through a plane homography.

``h`` maps object-local metres ``(x, y, 1)`` to pixels ``(u, v, w)`` with pixel centres at
integer ``(u, v)``. Only a small patch around the object is touched: its pixels are mapped back to
local metres, each part's signed distance (metres) is divided by the local pixel footprint to give
an anti-aliased coverage ``clip(0.5 - d / m, 0, 1)`` (scaled down for parts thinner than a pixel),
parts are blended in order, and the change is softened by a Gaussian of ``blur_px`` (optics).

Extents: :func:`outline_points` samples each part's outline (exact ellipses and rounded boxes), so
the projected tight box of an object is the min/max of those points in the image.
"""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np

from sim.kernels import rasterize_parts
from sim.scene import Part

_MIN_OPACITY = 0.05
_PHI = np.linspace(0.0, 2 * math.pi, 32, endpoint=False)
_CIRCLE = np.stack([np.cos(_PHI), np.sin(_PHI)], axis=1)
_QUARTER = np.linspace(0.0, math.pi / 2, 5)
# Rounded-box outline: per corner (sign x, sign y) and the arc's unit offsets.
_CORNER_SIGNS = np.repeat(np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]], float), 5, axis=0)
_CORNER_ARCS = np.concatenate(
    [
        np.stack([np.cos(_QUARTER + k * math.pi / 2), np.sin(_QUARTER + k * math.pi / 2)], axis=1)
        for k in range(4)
    ]
)


def corner_radius(part: Part) -> float:
    """Rounding radius of a box part (30 % of its smaller half-size)."""
    return 0.3 * min(part.a, part.b)


@functools.lru_cache(maxsize=8192)
def outline_points(part: Part) -> np.ndarray:
    """Points [K, 2] on the part's outline in object-local metres (cached: do not modify)."""
    if part.shape == "ellipse":
        local = _CIRCLE * np.array([part.a, part.b])
    else:
        r = corner_radius(part)
        local = _CORNER_SIGNS * np.array([part.a - r, part.b - r]) + r * _CORNER_ARCS
    c, s = math.cos(part.angle), math.sin(part.angle)
    return local @ np.array([[c, s], [-s, c]]) + np.array([part.x, part.y])


def project_local(h: np.ndarray, points: np.ndarray) -> np.ndarray | None:
    """Pixels [K, 2] of local points through ``h``; None if any point is behind the camera."""
    hom = np.concatenate([points, np.ones((len(points), 1))], axis=1) @ h.T
    if np.any(hom[:, 2] <= 1e-9):
        return None
    return hom[:, :2] / hom[:, 2:3]


def visible_parts(parts: list[Part], visibility: float = 1.0) -> list[Part]:
    """Parts that show at all (opacity times ``visibility`` above a small threshold)."""
    return [p for p in parts if p.opacity * visibility > _MIN_OPACITY]


def tight_extent(
    h: np.ndarray, parts: list[Part], visibility: float = 1.0, min_opacity: float = 0.25
) -> np.ndarray | None:
    """Projected ``[u_min, v_min, u_max, v_max]`` (pixel-centre coordinates, unclipped) of the
    ``in_box`` parts at least ``min_opacity`` opaque; None when none, or behind the camera."""
    chosen = [p for p in parts if p.in_box and p.opacity * visibility >= min_opacity]
    if not chosen:
        chosen = [p for p in parts if p.in_box and p.opacity * visibility > _MIN_OPACITY]
    if not chosen:
        return None
    uv = project_local(h, np.concatenate([outline_points(p) for p in chosen]))
    if uv is None:
        return None
    return np.array([uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])


def draw_parts(
    image: np.ndarray,
    h: np.ndarray,
    parts: list[Part],
    visibility: float = 1.0,
    blur_px: float = 0.5,
) -> bool:
    """Blend ``parts`` into ``image`` (uint8 HxWx3, in place) through ``h``; False if off-image."""
    parts = visible_parts(parts, visibility)
    if not parts:
        return False
    uv = project_local(h, np.concatenate([outline_points(p) for p in parts]))
    if uv is None:
        return False
    height, width = image.shape[:2]
    pad = 2 + int(math.ceil(2 * blur_px))
    u0 = max(0, int(math.floor(uv[:, 0].min())) - pad)
    v0 = max(0, int(math.floor(uv[:, 1].min())) - pad)
    u1 = min(width, int(math.ceil(uv[:, 0].max())) + pad + 1)
    v1 = min(height, int(math.ceil(uv[:, 1].max())) + pad + 1)
    if u0 >= u1 or v0 >= v1:
        return False
    hinv = np.linalg.inv(h)
    # Metres per pixel at the patch centre (square root of the local Jacobian determinant).
    cu, cv = (u0 + u1) / 2.0, (v0 + v1) / 2.0
    probe = np.array([[cu, cv, 1.0], [cu + 1, cv, 1.0], [cu, cv + 1, 1.0]]) @ hinv.T
    probe = probe[:, :2] / probe[:, 2:3]
    jac = np.column_stack([probe[1] - probe[0], probe[2] - probe[0]])
    metres_per_px = math.sqrt(abs(float(np.linalg.det(jac)))) or 1e-6
    table = np.array([_part_row(p, visibility, metres_per_px) for p in parts])
    original = image[v0:v1, u0:u1].astype(np.float32)
    patch = original.copy()
    rasterize_parts(patch, hinv, u0, v0, table, metres_per_px)
    delta = patch - original
    if blur_px > 0:
        delta = cv2.GaussianBlur(delta, (0, 0), blur_px)
    image[v0:v1, u0:u1] = np.clip(original + delta + 0.5, 0, 255).astype(np.uint8)
    return True


def _part_row(part: Part, visibility: float, metres_per_px: float) -> list[float]:
    """One row of the kernel's part table; parts thinner than a pixel get less coverage."""
    thin = min(1.0, 2.0 * min(part.a, part.b) / metres_per_px)
    return [
        1.0 if part.shape == "box" else 0.0,
        part.x,
        part.y,
        part.a,
        part.b,
        math.cos(part.angle),
        math.sin(part.angle),
        *part.bgr,
        part.opacity * visibility * thin,
        part.shade,
        corner_radius(part),
    ]
