"""A pinhole camera over the plane z = 0: one homography from ground metres to image pixels.

Ground coordinates are east-north metres. The camera looks along ``heading_deg`` (clockwise from
north) tilted ``tilt_deg`` from nadir towards it; ``roll_deg`` turns the image about the optical
axis. Image x runs right, y down; the window is the central ``width`` x ``height`` of a sensor
``sensor_width`` pixels across.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class View:
    """One frame's camera: position (metres), attitude (degrees) and optics."""

    east: float
    north: float
    height: float
    heading_deg: float
    tilt_deg: float
    roll_deg: float
    hfov_deg: float
    width: int = 1920
    height_px: int = 1080
    sensor_width: int = 3840

    @property
    def focal(self) -> float:
        return (self.sensor_width / 2.0) / math.tan(math.radians(self.hfov_deg) / 2.0)

    def axes(self) -> np.ndarray:
        """Rows: the image's right, down and optical-axis directions in ground coordinates."""
        psi, theta = math.radians(self.heading_deg), math.radians(self.tilt_deg)
        forward = np.array([math.sin(psi), math.cos(psi), 0.0])
        right = np.array([math.cos(psi), -math.sin(psi), 0.0])
        up = np.array([0.0, 0.0, 1.0])
        axis = math.cos(theta) * -up + math.sin(theta) * forward
        down = -(math.cos(theta) * forward + math.sin(theta) * up)
        roll = math.radians(self.roll_deg)
        x = math.cos(roll) * right + math.sin(roll) * down
        y = -math.sin(roll) * right + math.cos(roll) * down
        return np.stack([x, y, axis])

    def homography(self) -> np.ndarray:
        """3x3 matrix taking ground ``(east, north, 1)`` to homogeneous image pixels."""
        k = np.array(
            [
                [self.focal, 0.0, self.width / 2.0],
                [0.0, self.focal, self.height_px / 2.0],
                [0, 0, 1],
            ]
        )
        shift = np.array(
            [[1.0, 0.0, -self.east], [0.0, 1.0, -self.north], [0.0, 0.0, -self.height]]
        )
        return k @ self.axes() @ shift

    def ground_of_pixels(self) -> tuple[np.ndarray, np.ndarray]:
        """East and north (float32, ``height_px`` x ``width``) of each pixel centre's ground."""
        inverse = np.linalg.inv(self.homography())
        u = np.arange(self.width, dtype=np.float64) + 0.5
        v = np.arange(self.height_px, dtype=np.float64) + 0.5
        uu, vv = np.meshgrid(u, v)
        w = inverse[2, 0] * uu + inverse[2, 1] * vv + inverse[2, 2]
        east = (inverse[0, 0] * uu + inverse[0, 1] * vv + inverse[0, 2]) / w
        north = (inverse[1, 0] * uu + inverse[1, 1] * vv + inverse[1, 2]) / w
        return east.astype(np.float32), north.astype(np.float32)


def project(h: np.ndarray, east: float, north: float) -> tuple[float, float]:
    """Image pixel of one ground point under homography ``h``."""
    p = h @ np.array([east, north, 1.0])
    return float(p[0] / p[2]), float(p[1] / p[2])


def local_affine(h: np.ndarray, east: float, north: float) -> np.ndarray:
    """2x2 Jacobian of the ground-to-image map at a ground point: pixels per metre east, north."""
    p = h @ np.array([east, north, 1.0])
    w = p[2]
    u, v = p[0] / w, p[1] / w
    return np.array(
        [
            [(h[0, 0] - u * h[2, 0]) / w, (h[0, 1] - u * h[2, 1]) / w],
            [(h[1, 0] - v * h[2, 0]) / w, (h[1, 1] - v * h[2, 1]) / w],
        ]
    )


def off_nadir_deg(view: View, east: float, north: float) -> float:
    """Angle between straight down and the ray from the camera to a ground point."""
    d = np.array([east - view.east, north - view.north, -view.height])
    return math.degrees(math.acos(view.height / float(np.linalg.norm(d))))
