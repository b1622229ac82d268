"""How large a box is on the ground: its pixel extent projected through the camera model.

A person is about 0.2-2 m across from above whatever the altitude, zoom or view angle; a box's
size in pixels means nothing without the ground sampling distance. The box's edge midpoints are
geolocated on the same ground plane as its centre, and the larger of the two ground distances
(left-right, top-bottom) is its extent: at nadir that is pixels x GSD, obliquely the along-ray
side grows as it should.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from sarmission.geo.camera import CameraIntrinsics
from sarmission.geo.geolocate import GeoFix, PlatformPose, geolocate
from sarmission.geo.wgs84 import geodetic_to_ned


def _distance_m(a: GeoFix, b: GeoFix) -> float:
    assert a.lat is not None and a.lon is not None and b.lat is not None and b.lon is not None
    n, e, _ = geodetic_to_ned(b.lat, b.lon, 0.0, a.lat, a.lon, 0.0)
    return math.hypot(float(n), float(e))


def ground_extent_m(
    box_xyxy: Sequence[float],
    intrinsics: CameraIntrinsics,
    pose: PlatformPose,
    ground_below_home_m: float = 0.0,
) -> float | None:
    """The larger ground extent (metres) of box ``[x1, y1, x2, y2]`` seen from ``pose``, or
    None when an edge has no ground fix (above the horizon, drone too low)."""
    x0, y0, x1, y1 = (float(v) for v in box_xyxy)
    cx, cy = (x0 + x1) / 2.0, (y0 + y1) / 2.0
    fixes = [
        geolocate(p, intrinsics, pose, ground_below_home_m)
        for p in ((x0, cy), (x1, cy), (cx, y0), (cx, y1))
    ]
    if not all(f.ok for f in fixes):
        return None
    return max(_distance_m(fixes[0], fixes[1]), _distance_m(fixes[2], fixes[3]))
