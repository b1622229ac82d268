"""The simulator's own pinhole camera: projection, back-projection and plane homographies.

The simulator renders frames and computes their ground truth (boxes, culling, sea shading) with
this module, never with :mod:`sarmission.geo.camera`, which geolocation is tested through: a
projection error there must show up as a disagreement with the truth, not move both together.
:class:`~sarmission.geo.camera.CameraIntrinsics` and :class:`~sarmission.geo.camera.CameraPose`
are used only as containers of numbers (``fx, fy, cx, cy, width, height``; the camera centre
``position_ned`` and ``rotation_ned_from_camera``).

Conventions (shared with the rest of the project, derived here from scratch):

- World: NED metres. Camera: OpenCV axes, x to the image's right, y down the image, z forward
  along the optical axis; ``rotation_ned_from_camera`` has the camera axes as its columns.
- Pixels ``(u, v)`` = (column, row) with pixel centres at integers.
- Ideal pinhole only: a point at camera coordinates ``(X, Y, Z)`` with ``Z > 0`` lies at
  ``u = cx + fx X / Z``, ``v = cy + fy Y / Z``. Lens distortion is refused, as the renderer
  does not draw it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from sarmission.geo.camera import CameraIntrinsics, CameraPose


def _check_pinhole(intr: CameraIntrinsics) -> None:
    if intr.distortion and any(float(c) != 0.0 for c in intr.distortion):
        raise ValueError("sim.truth_camera models an ideal pinhole; distortion is not supported")


def intrinsic_matrix(intr: CameraIntrinsics) -> np.ndarray:
    """``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``: camera coordinates to homogeneous pixels."""
    _check_pinhole(intr)
    return np.array(
        [
            [float(intr.fx), 0.0, float(intr.cx)],
            [0.0, float(intr.fy), float(intr.cy)],
            [0.0, 0.0, 1.0],
        ]
    )


def camera_coordinates(pose: CameraPose, points_ned: np.ndarray) -> np.ndarray:
    """Camera-frame coordinates [N, 3] of NED points [N, 3]: each row holds the offset from the
    camera centre resolved along the camera's right, down-the-image and forward axes."""
    offsets = np.atleast_2d(np.asarray(points_ned, dtype=float)) - np.asarray(
        pose.position_ned, dtype=float
    )
    axes = np.asarray(pose.rotation_ned_from_camera, dtype=float)
    right, down, forward = axes[:, 0], axes[:, 1], axes[:, 2]
    return np.stack([offsets @ right, offsets @ down, offsets @ forward], axis=1)


def project(
    intr: CameraIntrinsics, pose: CameraPose, points_ned: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Pixels ``uv`` [N, 2] of NED points [N, 3] and whether each lies in front (``Z > 0``).

    Points on or behind the camera's plane get ``uv = NaN``.
    """
    _check_pinhole(intr)
    cam = camera_coordinates(pose, points_ned)
    depth = cam[:, 2]
    in_front = depth > 0.0
    uv = np.full((len(cam), 2), np.nan)
    z = depth[in_front]
    uv[in_front, 0] = float(intr.cx) + float(intr.fx) * cam[in_front, 0] / z
    uv[in_front, 1] = float(intr.cy) + float(intr.fy) * cam[in_front, 1] / z
    return uv, in_front


def rays(intr: CameraIntrinsics, pose: CameraPose, uv: np.ndarray) -> np.ndarray:
    """Unit NED directions [N, 3] of the rays from the camera centre through pixels ``uv`` [N, 2].

    Pixel ``(u, v)`` sees the camera-frame direction ``((u - cx) / fx, (v - cy) / fy, 1)``.
    """
    _check_pinhole(intr)
    uv = np.atleast_2d(np.asarray(uv, dtype=float))
    x = (uv[:, 0] - float(intr.cx)) / float(intr.fx)
    y = (uv[:, 1] - float(intr.cy)) / float(intr.fy)
    axes = np.asarray(pose.rotation_ned_from_camera, dtype=float)
    d = x[:, None] * axes[:, 0] + y[:, None] * axes[:, 1] + axes[:, 2]
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def plane_homography(
    intr: CameraIntrinsics,
    pose: CameraPose,
    origin_ned: np.ndarray,
    axis_a_ned: np.ndarray,
    axis_b_ned: np.ndarray,
) -> np.ndarray:
    """3x3 ``H`` with ``[u w, v w, w]^T = H [a, b, 1]^T`` for the plane point
    ``origin + a * axis_a + b * axis_b`` (NED); ``w`` is that point's depth, > 0 in front.

    A plane point's camera coordinates are affine in ``(a, b)``: the columns of ``H`` are the
    camera-frame images of ``axis_a``, ``axis_b`` (directions) and ``origin`` (a point), each
    taken through the intrinsic matrix.
    """
    to_camera = np.asarray(pose.rotation_ned_from_camera, dtype=float).T
    columns = np.column_stack(
        [
            to_camera @ np.asarray(axis_a_ned, dtype=float),
            to_camera @ np.asarray(axis_b_ned, dtype=float),
            to_camera
            @ (np.asarray(origin_ned, dtype=float) - np.asarray(pose.position_ned, dtype=float)),
        ]
    )
    return intrinsic_matrix(intr) @ columns


def ground_homography(
    intr: CameraIntrinsics, pose: CameraPose, ground_down: float = 0.0
) -> np.ndarray:
    """3x3 ``H`` from ``(north, east, 1)`` on the plane ``down = ground_down`` to pixels."""
    return plane_homography(
        intr,
        pose,
        np.array([0.0, 0.0, float(ground_down)]),
        np.array([1.0, 0.0, 0.0]),
        np.array([0.0, 1.0, 0.0]),
    )
