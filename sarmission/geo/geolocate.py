"""Pixel -> latitude/longitude on a ground plane, with a 1-sigma horizontal error estimate.

The drone's own position is the origin: a local NED frame at ``(pose.lat, pose.lon)``, the
camera ``h`` metres above the ground plane, ``h = rel_alt + ground_below_home`` (``rel_alt``
is the autopilot's height above its home; the plane sits ``ground_below_home`` metres below home,
0 = home altitude). Nothing else about home is needed, so a far-away or unknown home position
cannot move a fix; the caller must still only call this once the autopilot has reported its
home, since ``rel_alt`` means nothing before. Lever arm neglected.

1. The pixel ``(u, v)`` becomes a unit ray ``d`` in NED: undistort, ``(x, y, 1)`` in the camera
   frame, then ``d = R_ned_cam @ (x, y, 1) / |.|`` with
   ``R_ned_cam = R_ned_gimbal(vehicle rpy, gimbal rpy, gimbal frame) @ R_GIMBAL_CAM``.
2. The ray meets the plane at ``p = t d`` with slant range ``t = h / d_down``; it needs
   ``d_down > 0`` (below the horizon) and ``h >= min_height_m`` (a drone on the ground sees
   nothing it could place).
3. ``p`` (north, east) goes back to WGS84 around the drone with pymap3d.

Depression angle ``delta = asin(d_down)``: the angle of the ray below the horizon.

Error model (first-order propagation; independent Gaussian sources; horizontal covariance
``S`` (2x2, north/east) of the ground point):

- GNSS horizontal position, ``sigma_g`` per axis: ``S_gnss = sigma_g^2 I``.
- Height of the camera above the ground plane, ``sigma_h^2 = sigma_alt^2 + sigma_ground^2``:
  the point slides along the ray's horizontal direction ``u`` by ``sigma_h / tan(delta)``:
  ``S_alt = (sigma_h / tan(delta))^2 u u^T``.
- Pointing (vehicle + gimbal attitude), a small rotation ``dtheta ~ N(0, sigma_a^2 I)`` of the
  ray in NED: ``dd = dtheta x d = -[d]x dtheta``; ``dp = t (I - d e_z^T / d_down) dd``, so with
  ``J`` the north/east rows of ``-t (I - d e_z^T / d_down) [d]x``: ``S_att = sigma_a^2 J J^T``.
  Along the ray this is ``sigma_a t / sin(delta)``, across it ``sigma_a t``.

``error_m = sqrt(trace(S))``, the root-mean-square horizontal error (DRMS). Timing errors
(frame vs telemetry time) and lens calibration errors are not modelled. Any non-finite input
or result is no fix.

Near the horizon the estimate grows without bound (the pointing term goes as ``1/sin^2(delta)``)
and, once ``delta`` is within a few pointing sigmas, the first-order model no longer holds: the
true ray may be at or above the horizon, the range unbounded. :class:`FixLimits` refuses such
fixes (the ray within ``horizon_sigmas`` pointing sigmas of the horizon, further than
``max_off_nadir_deg`` from straight down, or an estimate above ``max_error_m``), so a grazing view
says "no fix" and why rather than giving a position whose error it cannot bound.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sarmission.geo.camera import CameraIntrinsics, CameraPose, pixel_rays
from sarmission.geo.frames import rotation_ned_from_camera
from sarmission.geo.wgs84 import ned_to_geodetic

__all__ = ["FixLimits", "GeoFix", "PlatformPose", "geolocate"]


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

    def finite(self) -> bool:
        """Every number of the pose is finite (a NaN or inf anywhere is no pose)."""
        values = (
            self.lat,
            self.lon,
            self.rel_alt_m,
            self.roll,
            self.pitch,
            self.yaw,
            *self.gimbal_rpy,
            self.gnss_sigma_m,
            self.alt_sigma_m,
            self.attitude_sigma_rad,
        )
        return all(math.isfinite(v) for v in values)

    def camera_pose(self, height_m: float) -> CameraPose:
        """Camera pose in the NED frame at the drone's ground point, ``height_m`` above it."""
        r = rotation_ned_from_camera(self.vehicle_rpy, self.gimbal_rpy, self.gimbal_frame)
        return CameraPose(np.array([0.0, 0.0, -float(height_m)]), r)


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


@dataclass(frozen=True)
class FixLimits:
    """When a fix is too uncertain to give (see the module docstring).

    ``max_off_nadir_deg``: the ray's angle from straight down (90 - depression) at most this;
    ``max_error_m``: the 1-sigma estimate at most this; ``horizon_sigmas``: the depression at
    least this many pointing sigmas (``attitude_sigma_rad``) of the pose.
    """

    max_off_nadir_deg: float = 90.0
    max_error_m: float = math.inf
    horizon_sigmas: float = 3.0

    def refusal(
        self, fix: GeoFix, attitude_sigma_rad: float, incidence_deg: float | None = None
    ) -> str:
        """Why ``fix`` is refused, or "" when it stands. ``incidence_deg``: the angle between the
        ray and the surface it meets (None: the depression, for a level plane); within
        ``horizon_sigmas`` pointing sigmas of grazing that surface the range is unbounded."""
        if not fix.ok or fix.error_m is None:
            return ""
        off_nadir = 90.0 - fix.depression_deg
        margin = math.degrees(self.horizon_sigmas * attitude_sigma_rad)
        if incidence_deg is None and fix.depression_deg < margin:
            return (
                f"ray {fix.depression_deg:.1f} deg below the horizon, within "
                f"{self.horizon_sigmas:g} pointing sigmas of it: range unbounded"
            )
        if incidence_deg is not None and incidence_deg < margin:
            return (
                f"ray {incidence_deg:.1f} deg from grazing the terrain, within "
                f"{self.horizon_sigmas:g} pointing sigmas of it: range unbounded"
            )
        if off_nadir > self.max_off_nadir_deg:
            return (
                f"ray {off_nadir:.1f} deg from straight down (a fix needs at most "
                f"{self.max_off_nadir_deg:g}; error estimate {fix.error_m:.0f} m)"
            )
        if fix.error_m > self.max_error_m:
            return (
                f"error estimate {fix.error_m:.0f} m (a fix needs at most "
                f"{self.max_error_m:g} m; ray {off_nadir:.1f} deg from straight down)"
            )
        return ""


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


def _no_fix(depression: float, note: str) -> GeoFix:
    return GeoFix(None, None, None, None, depression, note)


def geolocate(
    pixel_uv: tuple[float, float] | np.ndarray,
    intrinsics: CameraIntrinsics,
    pose: PlatformPose,
    ground_below_home_m: float = 0.0,
    ground_sigma_m: float = 0.0,
    min_height_m: float = 0.0,
    limits: FixLimits = FixLimits(),
) -> GeoFix:
    """Latitude/longitude of the ground seen at pixel ``(u, v)`` (see the module docstring).

    ``ground_below_home_m``: how far the ground plane lies below the autopilot's home (0: at
    home altitude); ``ground_sigma_m`` its 1-sigma uncertainty. ``min_height_m``: no fix when
    the camera is lower than this above the plane; ``limits``: no fix when the view is too
    grazing or the estimate too large. Without a fix ``lat``/``lon`` are None and ``note`` says
    why.
    """
    uv = np.asarray(pixel_uv, dtype=float).reshape(1, 2)
    if not (pose.finite() and np.all(np.isfinite(uv)) and math.isfinite(ground_below_home_m)):
        return _no_fix(math.nan, "pose or pixel not finite")
    height = pose.rel_alt_m + ground_below_home_m
    cam = pose.camera_pose(height)
    d = pixel_rays(intrinsics, cam, uv)[0]
    depression = math.degrees(math.asin(max(-1.0, min(1.0, float(d[2])))))
    if d[2] <= 1e-9:
        return _no_fix(depression, "ray at or above the horizon")
    if height <= 0.0:
        return _no_fix(depression, f"camera {-height:.1f} m below the ground plane")
    if height < min_height_m:
        return _no_fix(
            depression, f"drone {height:.1f} m above the ground (a fix needs {min_height_m:g} m)"
        )
    t = height / float(d[2])
    p = t * d
    lat, lon, _ = ned_to_geodetic(p[0], p[1], 0.0, pose.lat, pose.lon, 0.0)
    cov = _horizontal_covariance(d, t, pose, ground_sigma_m)
    error = math.sqrt(float(np.trace(cov)))
    lat, lon = float(lat), float(lon)
    if not all(math.isfinite(v) for v in (lat, lon, error, t)):
        return _no_fix(depression, "geolocation not finite")
    plane = (
        "home altitude" if ground_below_home_m == 0.0 else f"{ground_below_home_m:.1f} m below home"
    )
    fix = GeoFix(lat, lon, error, t, depression, f"ground plane at {plane}")
    refused = limits.refusal(fix, pose.attitude_sigma_rad)
    return _no_fix(depression, refused) if refused else fix
