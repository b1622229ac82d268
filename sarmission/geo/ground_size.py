"""How large a box's object is: its pixel extent through the camera model, in metres.

A person is about 0.2-2 m across from above whatever the altitude, zoom or view angle; a box's
size in pixels means nothing without the range. :func:`apparent_size_m` is the box's larger
angular side times the slant range to its centre: the object's size across the line of sight.
That is what a camera measures whatever the object's shape: a standing or upright person's
height, a flat one's width (its near-far side shrinks obliquely, its width does not).

:func:`ground_extent_m` projects the box's edges onto the ground plane instead. That is right
for flat things seen from above and wrong for anything with height seen obliquely: the
along-ray side grows as 1 / tan(depression), so at 20 degrees below the horizon a person 1.8 m
tall spans 4.9 m of ground. On the real SeaDronesSee validation file a size gate of 0.15-2.5 m
on the ground extent drops 23 % of the swimmers seen 3-30 degrees below the horizon; across
the line of sight it drops 2 % (docs/size_gate.md).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from sarmission.geo.camera import CameraIntrinsics, pixel_rays
from sarmission.geo.geolocate import GeoFix, PlatformPose, geolocate
from sarmission.geo.wgs84 import geodetic_to_ned


def _distance_m(a: GeoFix, b: GeoFix) -> float:
    assert a.lat is not None and a.lon is not None and b.lat is not None and b.lon is not None
    n, e, _ = geodetic_to_ned(b.lat, b.lon, 0.0, a.lat, a.lon, 0.0)
    return math.hypot(float(n), float(e))


def _edge_midpoints(box_xyxy: Sequence[float]) -> list[tuple[float, float]]:
    """Left, right, top and bottom edge midpoints of ``[x1, y1, x2, y2]``."""
    x0, y0, x1, y1 = (float(v) for v in box_xyxy)
    cx, cy = (x0 + x1) / 2.0, (y0 + y1) / 2.0
    return [(x0, cy), (x1, cy), (cx, y0), (cx, y1)]


def apparent_size_m(
    box_xyxy: Sequence[float],
    intrinsics: CameraIntrinsics,
    pose: PlatformPose,
    ground_below_home_m: float = 0.0,
) -> float | None:
    """The size (metres) across the line of sight of the object in box ``[x1, y1, x2, y2]``:
    ``2 R tan(a / 2)`` with ``a`` the larger angle between opposite edge midpoints' rays and
    ``R`` the slant range to the ground at the box's centre. None when the centre has no ground
    fix (above the horizon, drone too low) or the box is not finite."""
    corners = np.asarray(box_xyxy, dtype=float)
    if corners.shape != (4,) or not np.all(np.isfinite(corners)):
        return None
    x0, y0, x1, y1 = corners
    centre = geolocate(((x0 + x1) / 2.0, (y0 + y1) / 2.0), intrinsics, pose, ground_below_home_m)
    if not centre.ok or centre.range_m is None:
        return None
    camera = pose.camera_pose(pose.rel_alt_m + ground_below_home_m)
    rays = pixel_rays(intrinsics, camera, np.asarray(_edge_midpoints(corners)))
    across = float(np.clip(rays[0] @ rays[1], -1.0, 1.0))
    down = float(np.clip(rays[2] @ rays[3], -1.0, 1.0))
    angle = max(math.acos(across), math.acos(down))
    return 2.0 * centre.range_m * math.tan(angle / 2.0)


def ground_extent_m(
    box_xyxy: Sequence[float],
    intrinsics: CameraIntrinsics,
    pose: PlatformPose,
    ground_below_home_m: float = 0.0,
) -> float | None:
    """The larger ground extent (metres) of box ``[x1, y1, x2, y2]`` seen from ``pose``: the
    distance on the ground plane between opposite edge midpoints. None when an edge has no
    ground fix (above the horizon, drone too low)."""
    fixes = [geolocate(p, intrinsics, pose, ground_below_home_m) for p in _edge_midpoints(box_xyxy)]
    if not all(f.ok for f in fixes):
        return None
    return max(_distance_m(fixes[0], fixes[1]), _distance_m(fixes[2], fixes[3]))
