"""Pixel -> latitude/longitude on a ground plane, with a 1-sigma horizontal error estimate.

Geometry (frames and rotations as in :mod:`sarmission.geo.frames`, camera model as in
:mod:`sarmission.geo.camera`):

1. The vehicle position becomes a local NED point relative to home ``(lat0, lon0, h0)``:
   north/east from ``geodetic_to_ned(lat, lon, h0 + rel_alt)``, down ``= -rel_alt`` (height
   above home is measured along the local vertical; the camera centre, lever arm neglected).
2. The pixel ``(u, v)`` becomes a unit ray ``d`` in NED: undistort, ``(x, y, 1)`` in the camera
   frame, then ``d = R_ned_cam @ (x, y, 1) / |.|`` with
   ``R_ned_cam = R_ned_gimbal(vehicle rpy, gimbal rpy, gimbal frame) @ R_GIMBAL_CAM``.
3. The ray meets the ground plane ``down = g`` (``g = h0 - ground_alt``, 0 = home altitude) at
   ``p = c + t d`` with slant range ``t = (g - c_down) / d_down``; it needs ``d_down > 0`` (the
   ray points below the horizon) and ``t > 0`` (the camera is above the plane).
4. ``p`` (north, east, g) goes back to WGS84 with pymap3d.

Depression angle ``delta = asin(d_down)``: the angle of the ray below the horizon.

Error model (first-order propagation; independent Gaussian sources; horizontal covariance
``S`` (2x2, north/east) of the ground point):

- GNSS horizontal position, ``sigma_g`` per axis: ``S_gnss = sigma_g^2 I``.
- Height of the camera above the ground plane, ``sigma_h^2 = sigma_alt^2 + sigma_ground^2``:
  ``dp_h / dc_down = -d_h / d_down`` so the point slides along the ray's horizontal direction
  ``u`` by ``sigma_h / tan(delta)``: ``S_alt = (sigma_h / tan(delta))^2 u u^T``.
- Pointing (vehicle + gimbal attitude), a small rotation ``dtheta ~ N(0, sigma_a^2 I)`` of the
  ray in NED: ``dd = dtheta x d = -[d]x dtheta``; ``dp = t (I - d e_z^T / d_down) dd``, so with
  ``J`` the north/east rows of ``-t (I - d e_z^T / d_down) [d]x``: ``S_att = sigma_a^2 J J^T``.
  Along the ray this is ``sigma_a t / sin(delta)``, across it ``sigma_a t``.

``error_m = sqrt(trace(S))``, the root-mean-square horizontal error (DRMS): the expected squared
distance between the fix and the truth is ``error_m^2``. Timing errors (frame vs telemetry
time) and lens calibration errors are not modelled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sarmission.geo.camera import CameraIntrinsics, CameraPose, pixel_rays
from sarmission.geo.frames import rotation_ned_from_camera
from sarmission.geo.wgs84 import geodetic_to_ned, ned_to_geodetic

__all__ = ["GeoFix", "PlatformPose", "geolocate"]


@dataclass(frozen=True)
class PlatformPose:
    """Where the camera is and where it points at one instant (angles in radians).

    ``lat``/``lon`` degrees, ``rel_alt_m`` metres above home. Vehicle attitude is ZYX Euler of
    ``R_ned_body``; ``gimbal_rpy`` is ZYX Euler in ``gimbal_frame`` ("body", "vehicle" or
    "earth", see :func:`sarmission.geo.frames.rotation_ned_from_gimbal`). The sigmas are 1-sigma:
    ``gnss_sigma_m`` per horizontal axis, ``alt_sigma_m`` of ``rel_alt_m``,
    ``attitude_sigma_rad`` of the camera pointing per axis (vehicle and gimbal combined).
    ``t`` is the time the pose is for (the caller's clock), informational.
    """

    lat: float
    lon: float
    rel_alt_m: float
    roll: float
    pitch: float
    yaw: float
    gimbal_rpy: tuple[float, float, float] = (0.0, -math.pi / 2, 0.0)
    gimbal_frame: str = "body"
    gnss_sigma_m: float = 1.0
    alt_sigma_m: float = 1.0
    attitude_sigma_rad: float = math.radians(0.5)
    t: float = 0.0

    @property
    def vehicle_rpy(self) -> tuple[float, float, float]:
        return self.roll, self.pitch, self.yaw

    def camera_pose(self, home: tuple[float, float, float]) -> CameraPose:
        """Camera pose in the NED frame of ``home = (lat, lon, alt)``; down is ``-rel_alt_m``."""
        lat0, lon0, h0 = home
        n, e, _ = geodetic_to_ned(self.lat, self.lon, h0 + self.rel_alt_m, lat0, lon0, h0)
        r = rotation_ned_from_camera(self.vehicle_rpy, self.gimbal_rpy, self.gimbal_frame)
        return CameraPose(np.array([float(n), float(e), -self.rel_alt_m]), r)


@dataclass(frozen=True)
class GeoFix:
    """A geolocated pixel. ``lat``/``lon`` are None when there is no fix (``note`` says why).

    ``error_m``: 1-sigma (RMS) horizontal error estimate; ``range_m``: slant range camera ->
    ground point; ``depression_deg``: angle of the ray below the horizon (negative: above).
    """

    lat: float | None
    lon: float | None
    error_m: float | None
    range_m: float | None
    depression_deg: float
    note: str = ""

    @property
    def ok(self) -> bool:
        return self.lat is not None and self.lon is not None


def _horizontal_covariance(
    d: np.ndarray, t: float, pose: PlatformPose, ground_sigma_m: float
) -> np.ndarray:
    """North/east covariance (2x2) of the ground point; see the module docstring."""
    dz = d[2]
    cov = pose.gnss_sigma_m**2 * np.eye(2)
    sigma_h2 = pose.alt_sigma_m**2 + ground_sigma_m**2
    dh = d[:2] / dz  # dp_h / d(-c_down): horizontal slide per metre of height
    cov += sigma_h2 * np.outer(dh, dh)
    d_cross = np.array([[0.0, -d[2], d[1]], [d[2], 0.0, -d[0]], [-d[1], d[0], 0.0]])
    proj = np.eye(3) - np.outer(d, np.array([0.0, 0.0, 1.0])) / dz
    jac = (-t * proj @ d_cross)[:2]
    cov += pose.attitude_sigma_rad**2 * jac @ jac.T
    return cov


def geolocate(
    pixel_uv: tuple[float, float] | np.ndarray,
    intrinsics: CameraIntrinsics,
    pose: PlatformPose,
    home: tuple[float, float, float],
    ground_alt: float | None = None,
    ground_sigma_m: float = 0.0,
) -> GeoFix:
    """Latitude/longitude of the ground seen at pixel ``(u, v)``.

    ``home = (lat, lon, alt)`` is the NED origin and ``pose.rel_alt_m`` is relative to it;
    ``ground_alt`` (same datum as ``home[2]``) is the ground plane height, None = home altitude.
    ``ground_sigma_m`` is the 1-sigma uncertainty of that height. Returns a :class:`GeoFix`;
    without a fix (ray at or above the horizon, camera not above the ground) ``lat``/``lon`` are
    None and ``note`` explains.
    """
    lat0, lon0, h0 = home
    cam = pose.camera_pose(home)
    d = pixel_rays(intrinsics, cam, np.asarray(pixel_uv, dtype=float).reshape(1, 2))[0]
    depression = math.degrees(math.asin(max(-1.0, min(1.0, float(d[2])))))
    ground_down = 0.0 if ground_alt is None else h0 - ground_alt
    height = ground_down - float(cam.position_ned[2])
    if d[2] <= 1e-9:
        return GeoFix(None, None, None, None, depression, "ray at or above the horizon")
    if height <= 0.0:
        return GeoFix(
            None, None, None, None, depression, f"camera {-height:.1f} m below the ground plane"
        )
    t = height / float(d[2])
    p = cam.position_ned + t * d
    lat, lon, _ = ned_to_geodetic(p[0], p[1], ground_down, lat0, lon0, h0)
    cov = _horizontal_covariance(d, t, pose, ground_sigma_m)
    plane = "home altitude" if ground_alt is None else f"{ground_alt:.1f} m"
    return GeoFix(
        float(lat),
        float(lon),
        math.sqrt(float(np.trace(cov))),
        t,
        depression,
        f"ground plane at {plane}",
    )
