"""Pinhole camera with optional OpenCV distortion, posed in the local NED world frame.

Frames (see :mod:`sarmission.geo.frames` for the rotation conventions):

- World: NED metres relative to home; the ground is the plane ``down = ground_down`` (0 = home
  altitude; positive ground_down means the ground lies below home).
- Camera: OpenCV, x right, y down, z forward along the optical axis.
- Pixels: ``(u, v)`` = (column, row), pixel centres at integer coordinates (OpenCV convention), so
  the image spans ``u in [-0.5, width - 0.5]``.

Projection of a world point ``p`` with pose ``(c, R)`` (``c`` camera centre in NED, ``R`` =
``R_ned_cam``)::

    X_cam = R.T @ (p - c)                     # world -> camera
    x, y  = X/Z, Y/Z                          # normalised image coordinates (Z > 0: in front)
    x', y' = distort(x, y)                    # OpenCV k1,k2,p1,p2[,k3]
    u = fx * x' + cx,  v = fy * y' + cy

Back-projection inverts each step (undistortion by Newton iterations) and a ray
``c + t * d`` meets the ground at ``t = (ground_down - c_down) / d_down`` (needs ``d_down > 0``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from sarmission.geo.frames import rotation_ned_from_camera

__all__ = [
    "CameraIntrinsics",
    "CameraPose",
    "distort_normalized",
    "ground_to_image_homography",
    "intersect_ground",
    "pixel_rays",
    "project_points",
    "rotation_ned_from_camera",
    "undistort_normalized",
]

_MIN_DEPTH = 1e-6


@dataclass(frozen=True)
class CameraIntrinsics:
    """Pinhole intrinsics in pixels plus OpenCV distortion ``(k1, k2, p1, p2[, k3])``.

    ``distortion`` may be empty (ideal pinhole) or have 4 or 5 coefficients.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"image size must be positive, got {self.width}x{self.height}")
        if self.fx <= 0 or self.fy <= 0:
            raise ValueError(f"focal lengths must be positive, got fx={self.fx}, fy={self.fy}")
        if len(self.distortion) not in (0, 4, 5):
            raise ValueError(
                f"distortion must have 0, 4 or 5 coefficients (k1,k2,p1,p2[,k3]), "
                f"got {len(self.distortion)}"
            )
        object.__setattr__(self, "distortion", tuple(float(k) for k in self.distortion))

    @classmethod
    def from_hfov(cls, width: int, height: int, hfov_deg: float) -> CameraIntrinsics:
        """Ideal pinhole with square pixels whose outer pixel edges span ``hfov_deg``.

        ``fx = fy = (width / 2) / tan(hfov / 2)``, principal point at the image centre
        ``((width - 1) / 2, (height - 1) / 2)`` (pixel centres at integers).
        """
        if not 0.0 < hfov_deg < 180.0:
            raise ValueError(f"hfov_deg must be in (0, 180), got {hfov_deg}")
        f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        return cls(int(width), int(height), f, f, (width - 1) / 2.0, (height - 1) / 2.0)

    @property
    def hfov_deg(self) -> float:
        """Horizontal field of view between the outer pixel edges (ignoring distortion)."""
        return math.degrees(2.0 * math.atan((self.width / 2.0) / self.fx))

    @property
    def vfov_deg(self) -> float:
        """Vertical field of view between the outer pixel edges (ignoring distortion)."""
        return math.degrees(2.0 * math.atan((self.height / 2.0) / self.fy))

    def matrix(self) -> np.ndarray:
        """The 3x3 camera matrix ``K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def same_shape(self, width: int, height: int, tolerance: float = 0.01) -> bool:
        """Whether frames of ``width`` x ``height`` have this camera's aspect ratio (within a
        relative ``tolerance``)."""
        return abs((width / height) / (self.width / self.height) - 1.0) <= tolerance

    def for_frames(self, width: int, height: int) -> CameraIntrinsics:
        """The camera as it records frames of ``width`` x ``height``.

        Of this camera's aspect ratio: the same camera at that resolution (:meth:`scaled`).
        Of another: the same horizontal field of view and pixel shape, the image cropped or
        extended about its centre to the frames' height, as a video mode crops a photo
        sensor's height. Scaling each axis apart instead would stretch the pixels and move
        every position along the frame's height. Neither is known to be the footage's lens;
        a caller warns (:meth:`same_shape`).
        """
        if self.same_shape(width, height):
            return self.scaled(width, height)
        full_height = self.height * width / self.width  # both axes scaled alike
        uniform = self.scaled(width, full_height)
        extra = full_height - height  # rows of the scaled image beyond the frames'
        return dataclasses.replace(uniform, height=int(height), cy=uniform.cy - extra / 2.0)

    def scaled(self, width: int, height: int) -> CameraIntrinsics:
        """The same camera at another resolution (focal lengths and centre scaled per axis)."""
        sx, sy = width / self.width, height / self.height
        return CameraIntrinsics(
            int(width),
            int(height),
            self.fx * sx,
            self.fy * sy,
            (self.cx + 0.5) * sx - 0.5,
            (self.cy + 0.5) * sy - 0.5,
            self.distortion,
        )


@dataclass
class CameraPose:
    """Camera centre ``position_ned`` (3,) in metres and ``rotation_ned_from_camera`` (3, 3)."""

    position_ned: np.ndarray
    rotation_ned_from_camera: np.ndarray

    def __post_init__(self) -> None:
        self.position_ned = np.asarray(self.position_ned, dtype=float).reshape(3)
        self.rotation_ned_from_camera = np.asarray(self.rotation_ned_from_camera, dtype=float)
        if self.rotation_ned_from_camera.shape != (3, 3):
            raise ValueError("rotation_ned_from_camera must be 3x3")

    @classmethod
    def from_attitudes(
        cls,
        position_ned: np.ndarray,
        vehicle_rpy: tuple[float, float, float],
        gimbal_rpy: tuple[float, float, float],
        gimbal_frame: str = "body",
    ) -> CameraPose:
        """Pose from vehicle and gimbal Euler angles in radians (``rotation_ned_from_camera``)."""
        return cls(position_ned, rotation_ned_from_camera(vehicle_rpy, gimbal_rpy, gimbal_frame))

    @property
    def optical_axis_ned(self) -> np.ndarray:
        """Unit vector of the camera z axis in NED."""
        return self.rotation_ned_from_camera[:, 2].copy()


def _coeffs(distortion: tuple[float, ...]) -> tuple[float, float, float, float, float]:
    d = tuple(distortion) + (0.0,) * (5 - len(distortion))
    return d[0], d[1], d[2], d[3], d[4]


def distort_normalized(xy: np.ndarray, distortion: tuple[float, ...]) -> np.ndarray:
    """Apply the OpenCV distortion model to normalised coordinates ``xy`` [N, 2].

    ``r2 = x^2 + y^2``, ``radial = 1 + k1 r2 + k2 r2^2 + k3 r2^3``,
    ``x' = x radial + 2 p1 x y + p2 (r2 + 2 x^2)``, ``y' = y radial + p1 (r2 + 2 y^2) + 2 p2 x y``.
    """
    xy = np.asarray(xy, dtype=float)
    if not distortion or not any(distortion):
        return xy.copy()
    k1, k2, p1, p2, k3 = _coeffs(distortion)
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return np.stack([xd, yd], axis=1)


def undistort_normalized(
    xy_distorted: np.ndarray, distortion: tuple[float, ...], iterations: int = 20
) -> np.ndarray:
    """Invert :func:`distort_normalized` by Newton iterations with the analytic Jacobian."""
    xyd = np.asarray(xy_distorted, dtype=float)
    if not distortion or not any(distortion):
        return xyd.copy()
    k1, k2, p1, p2, k3 = _coeffs(distortion)
    xy = xyd.copy()
    for _ in range(iterations):
        x, y = xy[:, 0], xy[:, 1]
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        drad = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r2
        fx = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) - xyd[:, 0]
        fy = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y - xyd[:, 1]
        j11 = radial + 2.0 * x * x * drad + 2.0 * p1 * y + 6.0 * p2 * x
        j12 = 2.0 * x * y * drad + 2.0 * p1 * x + 2.0 * p2 * y
        j21 = 2.0 * x * y * drad + 2.0 * p1 * x + 2.0 * p2 * y
        j22 = radial + 2.0 * y * y * drad + 6.0 * p1 * y + 2.0 * p2 * x
        det = j11 * j22 - j12 * j21
        det = np.where(np.abs(det) < 1e-12, 1e-12, det)
        dx = (j22 * fx - j12 * fy) / det
        dy = (-j21 * fx + j11 * fy) / det
        xy = np.stack([x - dx, y - dy], axis=1)
        if (
            float(np.max(np.abs(dx), initial=0.0)) < 1e-14
            and float(np.max(np.abs(dy), initial=0.0)) < 1e-14
        ):
            break
    return xy


def project_points(
    intr: CameraIntrinsics, pose: CameraPose, points_ned: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Project NED points [N, 3] to pixels.

    Returns ``(uv [N, 2] float64, in_front [N] bool)``; ``in_front`` is ``Z_cam > 0``. Points behind
    the camera (or on its plane) get ``uv = NaN``. Points in front may still fall outside the image.
    """
    p = np.asarray(points_ned, dtype=float).reshape(-1, 3)
    cam = (p - pose.position_ned) @ pose.rotation_ned_from_camera  # rows: (R.T @ (p - c)).T
    z = cam[:, 2]
    in_front = z > _MIN_DEPTH
    safe_z = np.where(in_front, z, 1.0)
    xy = cam[:, :2] / safe_z[:, None]
    xy = distort_normalized(xy, intr.distortion)
    uv = np.empty((p.shape[0], 2))
    uv[:, 0] = intr.fx * xy[:, 0] + intr.cx
    uv[:, 1] = intr.fy * xy[:, 1] + intr.cy
    uv[~in_front] = np.nan
    return uv, in_front


def pixel_rays(intr: CameraIntrinsics, pose: CameraPose, uv: np.ndarray) -> np.ndarray:
    """Unit ray directions in NED [N, 3] through pixels ``uv`` [N, 2] (undistorted first)."""
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    xy = np.stack([(uv[:, 0] - intr.cx) / intr.fx, (uv[:, 1] - intr.cy) / intr.fy], axis=1)
    xy = undistort_normalized(xy, intr.distortion)
    cam = np.concatenate([xy, np.ones((xy.shape[0], 1))], axis=1)
    d = cam @ pose.rotation_ned_from_camera.T  # rows: (R @ cam_dir).T
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def intersect_ground(
    pose: CameraPose, directions: np.ndarray, ground_down: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Intersect rays from the camera centre with the plane ``down = ground_down``.

    ``t = (ground_down - c_down) / d_down``; a ray is valid when it points down (``d_down > 0``)
    and the camera is above the plane (``t > 0``). Returns ``(points_ned [N, 3], valid [N])`` with
    NaN rows where invalid.
    """
    d = np.asarray(directions, dtype=float).reshape(-1, 3)
    c = pose.position_ned
    dd = d[:, 2]
    valid = dd > 1e-9
    t = np.where(valid, (ground_down - c[2]) / np.where(valid, dd, 1.0), np.nan)
    valid &= t > 0
    pts = c[None, :] + t[:, None] * d
    pts[~valid] = np.nan
    return pts, valid


def ground_to_image_homography(
    intr: CameraIntrinsics, pose: CameraPose, ground_down: float = 0.0
) -> np.ndarray:
    """3x3 ``H`` mapping ground coordinates ``(north_m, east_m, 1)`` to pixels ``(u, v, 1)``.

    Input order is (north, east) in metres in the NED frame, on the plane ``down = ground_down``:
    ``[u w, v w, w]^T = H @ [north, east, 1]^T``. With ``M = R.T`` (world -> camera),
    ``H = K @ [M[:, 0], M[:, 1], M @ ([0, 0, ground_down] - c)]``. A ground point is in front of the
    camera where ``w > 0``. Distortion is ignored (a homography cannot represent it).

    To warp a ground texture whose pixel ``(col, row)`` lies at ``north = n0 - row * s``,
    ``east = e0 + col * s`` use ``H @ A`` with ``A = [[0, -s, n0], [s, 0, e0], [0, 0, 1]]``.
    """
    m = pose.rotation_ned_from_camera.T
    t = m @ (np.array([0.0, 0.0, ground_down]) - pose.position_ned)
    return intr.matrix() @ np.column_stack([m[:, 0], m[:, 1], t])
