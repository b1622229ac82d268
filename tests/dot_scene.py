"""A plain scene for live tests: white dots (people) at fixed ground points on a grey sea, with
the simulator's annotation type, so the blob detector of ``scripted_detector`` finds them."""

from __future__ import annotations

import numpy as np

from sarmission.geo.camera import CameraIntrinsics, CameraPose, project_points
from sarmission.geo.wgs84 import ned_to_geodetic
from sim.render import ObjectAnnotation

DOT_RADIUS_PX = 2


class DotRenderer:
    """Renders ``targets_ne`` ((north, east) metres from ``home``) as 5x5 px white squares."""

    def __init__(
        self,
        targets_ne: list[tuple[float, float]],
        intrinsics: CameraIntrinsics,
        home: tuple[float, float, float],
    ) -> None:
        self.points = np.array([[n, e, 0.0] for n, e in targets_ne], dtype=float)
        self.intrinsics = intrinsics
        lat, lon, _ = ned_to_geodetic(self.points[:, 0], self.points[:, 1], 0.0, *home)
        self.latlon = list(
            zip(np.atleast_1d(lat).tolist(), np.atleast_1d(lon).tolist(), strict=True)
        )

    def render(self, t: float, pose: CameraPose) -> tuple[np.ndarray, list[ObjectAnnotation]]:
        w, h = self.intrinsics.width, self.intrinsics.height
        frame = np.full((h, w, 3), 80, np.uint8)
        uv, in_front = project_points(self.intrinsics, pose, self.points)
        annotations = []
        r = DOT_RADIUS_PX
        for i, ((u, v), front) in enumerate(zip(uv, in_front, strict=True)):
            if not front or not (r <= u < w - r and r <= v < h - r):
                continue
            x, y = int(round(u)), int(round(v))
            frame[y - r : y + r + 1, x - r : x + r + 1] = 255
            annotations.append(
                ObjectAnnotation(
                    i + 1,
                    "swimmer",
                    1,
                    True,
                    (x - r, y - r, x + r + 1, y + r + 1),
                    float((2 * r + 1) ** 2),
                    1.0,
                    tuple(self.points[i]),
                    *self.latlon[i],
                )
            )
        return frame, annotations
