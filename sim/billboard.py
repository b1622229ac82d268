"""Upright parts (:class:`sim.scene.Upright`) drawn on a billboard that faces the camera.

A point ``z`` metres above an object's centre ``c`` projects, to first order in the object's
size, where ``c + z cos(delta) b`` does: ``delta`` is the depression of the line of sight and
``b`` the unit vector across the line of sight in its vertical plane ("up" in the image). So an
upright part becomes a flat part on the plane through ``c`` spanned by ``r`` (the viewer's
right, horizontal) and ``b``, its heights scaled by ``cos(delta)`` and its width the extent of
its footprint along ``r``; it stands on its footprint's edge nearest the camera, which shows
``sin(delta)`` times that edge's horizontal distance along the line of sight below ``c``. Seen
from straight above the upright parts shrink to nothing and the flat parts show the object;
seen from the side, the reverse.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sarmission.geo.camera import CameraIntrinsics, CameraPose
from sim.scene import Part, Upright
from sim.truth_camera import plane_homography


@dataclass(frozen=True)
class Billboard:
    """The plane upright parts are drawn on, for one object seen from one camera position.

    ``right_ned`` (horizontal) and ``up_ned`` (across the line of sight) are unit vectors;
    ``cos_depression`` scales heights, ``sin_depression`` horizontal offsets along the line of
    sight; ``right_local`` is ``right_ned`` in the object's own ``(x forward, y right)`` axes.
    """

    centre_ned: np.ndarray
    right_ned: np.ndarray
    up_ned: np.ndarray
    cos_depression: float
    sin_depression: float
    right_local: tuple[float, float]


def billboard_for(
    camera_ned: np.ndarray, centre_ned: np.ndarray, heading: float
) -> Billboard | None:
    """The billboard of an object at ``centre_ned`` with ``heading`` (radians from north) seen
    from ``camera_ned``; None when the camera is straight above it (no upright part shows)."""
    line = np.asarray(centre_ned, float) - np.asarray(camera_ned, float)
    distance = float(np.linalg.norm(line))
    horizontal = math.hypot(line[0], line[1])
    if distance < 1e-9 or horizontal < 1e-6 * distance:
        return None
    sight = line / distance
    right = np.array([-line[1] / horizontal, line[0] / horizontal, 0.0])
    up = np.array([0.0, 0.0, -1.0])
    across = up - float(up @ sight) * sight
    cos_depression = float(np.linalg.norm(across))
    c, s = math.cos(heading), math.sin(heading)
    right_local = (right[0] * c + right[1] * s, -right[0] * s + right[1] * c)
    return Billboard(
        np.asarray(centre_ned, float),
        right,
        across / cos_depression,
        cos_depression,
        float(sight[2]),
        right_local,
    )


def billboard_parts(uprights: list[Upright], board: Billboard) -> list[Part]:
    """The upright parts as flat parts in billboard metres (x to the viewer's right, y up)."""
    rx, ry = board.right_local
    fx, fy = ry, -rx  # away from the camera, in the object's axes
    k = board.cos_depression
    parts = []
    for u in uprights:
        across = u.x * rx + u.y * ry
        height = u.top - u.bottom
        if u.shape == "ellipse":
            half = math.hypot(u.half_length * rx, u.half_width * ry)
            depth = math.hypot(u.half_length * fx, u.half_width * fy)
        else:
            half = abs(u.half_length * rx) + abs(u.half_width * ry)
            depth = abs(u.half_length * fx) + abs(u.half_width * fy)
        foot = (u.x * fx + u.y * fy - depth) * board.sin_depression + k * u.bottom
        if u.tilt == 0.0:
            parts.append(
                Part(
                    u.shape,
                    across,
                    foot + k * height / 2,
                    half,
                    k * height / 2,
                    0.0,
                    u.bgr,
                    u.opacity,
                    u.shade,
                    u.in_box,
                )
            )
            continue
        # A leaning limb: from its foot along (sin tilt, cos tilt), heights compressed by k.
        st, ct = math.sin(u.tilt), math.cos(u.tilt)
        parts.append(
            Part(
                "ellipse",
                across + height / 2 * st,
                foot + k * height / 2 * ct,
                height / 2 * math.hypot(st, k * ct),
                u.half_width,
                math.atan2(k * ct, st),
                u.bgr,
                u.opacity,
                u.shade,
                u.in_box,
            )
        )
    return parts


def billboard_homography(intr: CameraIntrinsics, pose: CameraPose, board: Billboard) -> np.ndarray:
    """3x3 map from billboard metres ``(x, y, 1)`` to pixels ``(u w, v w, w)``."""
    return plane_homography(intr, pose, board.centre_ned, board.right_ned, board.up_ned)
