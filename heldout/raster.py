"""Drawing an object's shapes into the frame through the camera's local ground-to-image map.

Each pixel of a small patch is supersampled; the sample points go back to the object's frame
through the inverse of (image Jacobian on the object's plane) x (object rotation), every shape
tests them, and shapes are blended in order. The patch carries the premultiplied colour, the total
opacity and the coverage of the object's solid shapes alone (for its ground-truth box).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from heldout.camera import Lens, View, ground_jacobian, project
from heldout.shapes import Shape


@dataclass
class Patch:
    """A drawn object: rows ``y0..``, columns ``x0..`` of the frame (may reach outside it)."""

    x0: int
    y0: int
    colour: np.ndarray
    alpha: np.ndarray
    solid: np.ndarray


def object_to_image(
    lens: Lens, view: View, anchor: Sequence[float], yaw_deg: float
) -> tuple[np.ndarray, np.ndarray]:
    """Image position of ``anchor`` (ENU) and the 2x2 map of object metres to pixel offsets."""
    uv, depth = project(lens, view, np.asarray([anchor], np.float64))
    jac = ground_jacobian(lens, view, np.asarray(anchor, np.float64))
    psi = math.radians(yaw_deg)
    body_to_enu = np.array([[math.cos(psi), math.sin(psi)], [-math.sin(psi), math.cos(psi)]])
    return uv[0], jac @ body_to_enu


def draw_shapes(
    lens: Lens, view: View, anchor: Sequence[float], yaw_deg: float, shapes: Sequence[Shape]
) -> Patch | None:
    """Rasterise ``shapes`` placed at ``anchor`` facing ``yaw_deg``; ``None`` when off-image.

    Small patches get 4 x 4 samples per pixel, large ones (whole boats) fewer.
    """
    centre, affine = object_to_image(lens, view, anchor, yaw_deg)
    if not np.all(np.isfinite(centre)) or not np.all(np.isfinite(affine)):
        return None
    reach = max(s.reach() for s in shapes)
    half = float(np.abs(affine).sum(axis=1).max()) * reach + 2.0
    x0, y0 = int(math.floor(centre[0] - half)), int(math.floor(centre[1] - half))
    x1, y1 = int(math.ceil(centre[0] + half)), int(math.ceil(centre[1] + half))
    if x1 <= 0 or y1 <= 0 or x0 >= lens.width or y0 >= lens.height or x1 - x0 > 2000:
        return None
    supersample = 4 if x1 - x0 <= 48 else 2 if x1 - x0 <= 160 else 1
    offsets = (np.arange(supersample) + 0.5) / supersample
    us = (np.arange(x0, x1)[:, None] + offsets[None, :]).ravel()
    vs = (np.arange(y0, y1)[:, None] + offsets[None, :]).ravel()
    gu, gv = np.meshgrid(us - centre[0], vs - centre[1])
    inverse = np.linalg.inv(affine)
    bx = inverse[0, 0] * gu + inverse[0, 1] * gv
    by = inverse[1, 0] * gu + inverse[1, 1] * gv
    colour = np.zeros(gu.shape + (3,), np.float32)
    alpha = np.zeros(gu.shape, np.float32)
    solid = np.zeros(gu.shape, np.float32)
    for shape in shapes:
        a = shape.inside(bx, by).astype(np.float32) * shape.opacity
        colour = colour * (1 - a[..., None]) + a[..., None] * np.array(shape.colour, np.float32)
        alpha = alpha + a * (1 - alpha)
        if shape.solid:
            solid = solid + a * (1 - solid)
    h, w = y1 - y0, x1 - x0

    def pool(x: np.ndarray) -> np.ndarray:
        return x.reshape(h, supersample, w, supersample, *x.shape[2:]).mean(axis=(1, 3))

    return Patch(x0, y0, pool(colour), pool(alpha), pool(solid))


def composite(frame: np.ndarray, patch: Patch) -> None:
    """Blend ``patch`` over the linear-radiance ``frame`` in place (clipped to the frame)."""
    h, w = patch.alpha.shape
    fy0, fx0 = max(patch.y0, 0), max(patch.x0, 0)
    fy1, fx1 = min(patch.y0 + h, frame.shape[0]), min(patch.x0 + w, frame.shape[1])
    if fy1 <= fy0 or fx1 <= fx0:
        return
    py, px = slice(fy0 - patch.y0, fy1 - patch.y0), slice(fx0 - patch.x0, fx1 - patch.x0)
    a = patch.alpha[py, px, None]
    frame[fy0:fy1, fx0:fx1] = frame[fy0:fy1, fx0:fx1] * (1 - a) + patch.colour[py, px]


def solid_box(
    patch: Patch, width: int, height: int, threshold: float = 1 / 3
) -> tuple[tuple[float, float, float, float], float] | None:
    """COCO box ``(x, y, w, h)`` of the pixels the object covers by at least ``threshold``,
    clipped to the frame, and the share of its coverage inside the frame; ``None`` if none."""
    total = float(patch.solid.sum())
    if total <= 0:
        return None
    rows, cols = np.nonzero(patch.solid >= threshold)
    xs, ys = cols + patch.x0, rows + patch.y0
    keep = (xs >= 0) & (xs < width) & (ys >= 0) & (ys < height)
    if not keep.any():
        return None
    xs, ys = xs[keep], ys[keep]
    h, w = patch.solid.shape
    inside = patch.solid[
        max(0, -patch.y0) : min(h, height - patch.y0), max(0, -patch.x0) : min(w, width - patch.x0)
    ].sum()
    x0, y0 = float(xs.min()), float(ys.min())
    return (x0, y0, float(xs.max()) + 1 - x0, float(ys.max()) + 1 - y0), float(inside) / total
