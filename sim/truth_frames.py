"""The simulator's own geometry for ground truth: where its camera points, and NED <-> WGS84.

The simulator is the truth that geolocation is tested against, so it must not share code with
``sarmission.geo``: a sign or axis error there would otherwise move the truth and the estimate
together and go unseen. Rotations come from SciPy's ``Rotation`` (aerospace ZYX Euler: yaw about
down, then pitch about the new right axis, then roll about the new forward axis), positions from
pymap3d directly. Conventions are MAVLink's: NED world, FRD body and gimbal (gimbal x is the
optical axis), OpenCV camera (x right, y down in the image, z forward). Projection through
the camera is :mod:`sim.truth_camera`'s.
"""

from __future__ import annotations

import warnings

import numpy as np
import pymap3d
from scipy.spatial.transform import Rotation

#: Camera (OpenCV) axes in the gimbal's FRD frame: image right is gimbal right, image down is
#: gimbal down, the optical axis is gimbal forward.
_CAMERA_AXES_IN_GIMBAL = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def zyx_rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``R`` taking FRD vectors to NED for aerospace Euler angles (radians)."""
    return Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()


def zyx_quaternion(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """``(w, x, y, z)`` with ``w >= 0`` of :func:`zyx_rotation` (MAVLink's order)."""
    x, y, z, w = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_quat()
    q = np.array([w, x, y, z])
    return -q if q[0] < 0 else q


def zyx_angles(r: np.ndarray) -> tuple[float, float, float]:
    """``(roll, pitch, yaw)`` of an FRD -> NED matrix; at pitch +-90 deg roll is 0."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # "Gimbal lock detected": roll set to 0
        yaw, pitch, roll = Rotation.from_matrix(np.asarray(r, dtype=float)).as_euler("ZYX")
    return float(roll), float(pitch), float(yaw)


def camera_rotation(
    vehicle_rpy: tuple[float, float, float],
    gimbal_rpy: tuple[float, float, float],
    gimbal_frame: str,
) -> np.ndarray:
    """``R_ned_camera`` for a gimbal whose angles are relative to the body ("body"), to the
    horizon with yaw from the heading ("vehicle"), or to the horizon and north ("earth")."""
    gimbal = zyx_rotation(*gimbal_rpy)
    if gimbal_frame == "body":
        ned_gimbal = zyx_rotation(*vehicle_rpy) @ gimbal
    elif gimbal_frame == "vehicle":
        ned_gimbal = zyx_rotation(0.0, 0.0, vehicle_rpy[2]) @ gimbal
    elif gimbal_frame == "earth":
        ned_gimbal = gimbal
    else:
        raise ValueError(f"unknown gimbal frame {gimbal_frame!r}")
    return ned_gimbal @ _CAMERA_AXES_IN_GIMBAL


def ned_to_geodetic(north, east, down, lat0: float, lon0: float, h0: float):
    """WGS84 ``(lat, lon, h)`` of NED offsets from ``(lat0, lon0, h0)`` (pymap3d)."""
    return pymap3d.ned2geodetic(north, east, down, lat0, lon0, h0)


def geodetic_to_ned(lat, lon, h, lat0: float, lon0: float, h0: float):
    """NED offsets ``(north, east, down)`` of WGS84 points from ``(lat0, lon0, h0)``."""
    return pymap3d.geodetic2ned(lat, lon, h, lat0, lon0, h0)
