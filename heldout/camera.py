"""Pinhole camera over a flat world: east-north-up metres, heading, tilt from nadir, roll.

Image coordinates are continuous with pixel ``i`` covering ``[i, i+1)``; the principal point is
the image centre. The camera frame is x right, y down, z along the optical axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Lens:
    """Image size and focal length in pixels (from the horizontal field of view)."""

    width: int
    height: int
    hfov_deg: float

    @property
    def focal_px(self) -> float:
        return (self.width / 2.0) / math.tan(math.radians(self.hfov_deg) / 2.0)


@dataclass(frozen=True)
class View:
    """Where the camera is and where it looks.

    ``position`` is (east, north, up) in metres; ``heading_deg`` is clockwise from north and is
    the image's "up" direction at nadir; ``tilt_deg`` turns the optical axis from straight down
    towards the heading; ``roll_deg`` turns the image about the optical axis.
    """

    position: tuple[float, float, float]
    heading_deg: float
    tilt_deg: float = 0.0
    roll_deg: float = 0.0

    def rotation(self) -> np.ndarray:
        """3x3 matrix whose columns are the camera's right, down and forward axes in ENU."""
        psi, tau, rho = (math.radians(a) for a in (self.heading_deg, self.tilt_deg, self.roll_deg))
        ahead = np.array([math.sin(psi), math.cos(psi), 0.0])
        right = np.array([math.cos(psi), -math.sin(psi), 0.0])
        up = np.array([0.0, 0.0, 1.0])
        forward = -math.cos(tau) * up + math.sin(tau) * ahead
        down = -math.cos(tau) * ahead - math.sin(tau) * up
        c, s = math.cos(rho), math.sin(rho)
        return np.stack([c * right + s * down, -s * right + c * down, forward], axis=1)


def project(lens: Lens, view: View, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Image coordinates ``[N, 2]`` of ENU points ``[N, 3]`` and their depth ``[N]``."""
    rel = np.asarray(points, dtype=np.float64) - np.asarray(view.position)
    cam = rel @ view.rotation()
    depth = cam[:, 2]
    safe = np.where(depth > 1e-6, depth, np.nan)
    f = lens.focal_px
    uv = np.stack(
        [lens.width / 2 + f * cam[:, 0] / safe, lens.height / 2 + f * cam[:, 1] / safe], axis=1
    )
    return uv, depth


def rays(lens: Lens, view: View, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit ENU ray directions ``[..., 3]`` through image coordinates ``u, v``."""
    f = lens.focal_px
    x = (np.asarray(u, np.float64) - lens.width / 2) / f
    y = (np.asarray(v, np.float64) - lens.height / 2) / f
    cam = np.stack([x, y, np.ones_like(x)], axis=-1)
    world = cam @ view.rotation().T
    return world / np.linalg.norm(world, axis=-1, keepdims=True)


def ground_points(
    lens: Lens, view: View, u: np.ndarray, v: np.ndarray, height: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Where the rays through ``u, v`` meet the plane ``z = height``: (east, north) ``[..., 2]``
    and the ray length in metres; NaN where a ray does not reach the plane."""
    d = rays(lens, view, u, v)
    drop = view.position[2] - height
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(d[..., 2] < -1e-6, drop / -d[..., 2], np.nan)
    east = view.position[0] + t * d[..., 0]
    north = view.position[1] + t * d[..., 1]
    return np.stack([east, north], axis=-1), t


def ground_jacobian(lens: Lens, view: View, point: np.ndarray) -> np.ndarray:
    """2x2 derivative of image (u, v) by ground (east, north) at an ENU point, in pixels/metre:
    how a small flat shape lying at the point's height looks in the image."""
    step = 0.05
    base = np.asarray(point, np.float64)
    pts = np.stack([base, base + [step, 0, 0], base + [0, step, 0]])
    uv, _ = project(lens, view, pts)
    return np.stack([(uv[1] - uv[0]) / step, (uv[2] - uv[0]) / step], axis=1)


def block_centres(lens: Lens, step: int) -> tuple[np.ndarray, np.ndarray]:
    """Centres of the ``step`` x ``step`` pixel blocks (``u, v`` arrays, rows x columns).

    A quantity sampled there and resized to the full image with ``cv2.resize`` (bilinear) lands
    on the right pixels. ``step`` must divide both image sides.
    """
    if lens.width % step or lens.height % step:
        raise ValueError(f"block step {step} does not divide {lens.width}x{lens.height}")
    us = (np.arange(lens.width // step, dtype=np.float64) + 0.5) * step
    vs = (np.arange(lens.height // step, dtype=np.float64) + 0.5) * step
    return np.meshgrid(us, vs)


def block_step(lens: Lens) -> int:
    """The coarsest block step (8, 4, 2 or 1) that divides both image sides."""
    return next(s for s in (8, 4, 2, 1) if lens.width % s == 0 and lens.height % s == 0)
