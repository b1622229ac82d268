"""How many pixels a person spans at each point of the image, from the camera and its pose.

The head classifies a crop of the proposal's box, S pixels whatever the range. At the survey's
ranges a swimmer (head and shoulders, about 0.45 m across the line of sight) fits in it; flown
lower, or seen nearer in an oblique view, the same person spans several S and the box holds
part of one, which the head misses (docs/lower_look.md). :func:`person_pixels` says how large
the person would be at each proposal so that the detector can cut a crop that holds them.
"""

from __future__ import annotations

import numpy as np

from sarmission.geo.camera import CameraIntrinsics, intersect_ground, pixel_rays
from sarmission.geo.geolocate import PlatformPose


def person_pixels(
    centres_uv: np.ndarray,
    intrinsics: CameraIntrinsics,
    pose: PlatformPose,
    person_m: float,
    ground_below_home_m: float = 0.0,
) -> np.ndarray:
    """Pixels spanned by an object ``person_m`` across the line of sight at each of
    ``centres_uv`` ``[N, 2]``: ``person_m * f / R`` with ``R`` the slant range to the ground
    plane through that pixel and ``f`` the focal length in pixels. NaN where the pixel has no
    ground (at or above the horizon, camera at or below the plane, pose not finite)."""
    uv = np.asarray(centres_uv, dtype=float).reshape(-1, 2)
    out = np.full(len(uv), np.nan)
    height = pose.rel_alt_m + ground_below_home_m
    if not len(uv) or not pose.finite() or not np.isfinite(height) or height <= 0.0:
        return out
    camera = pose.camera_pose(height)
    rays = pixel_rays(intrinsics, camera, uv)
    points, valid = intersect_ground(camera, rays, 0.0)
    ranges = np.linalg.norm(points - camera.position_ned[None, :], axis=1)
    focal = (intrinsics.fx + intrinsics.fy) / 2.0
    ok = valid & np.isfinite(ranges) & (ranges > 0)
    out[ok] = person_m * focal / ranges[ok]
    return out
