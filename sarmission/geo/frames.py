"""Rotations between the world (NED), vehicle body (FRD), gimbal and camera (OpenCV) frames.

Conventions (all matrices are *active* rotations ``R_a_b`` that take a vector expressed in frame
``b`` to the same vector expressed in frame ``a``: ``v_a = R_a_b @ v_b``):

- World: local NED (x north, y east, z down), metres relative to home.
- Vehicle body: FRD (x forward, y right, z down). Attitude is aerospace ZYX Euler (radians):
  ``R_ned_body = Rz(yaw) @ Ry(pitch) @ Rx(roll)``, yaw from north clockwise seen from above,
  pitch positive nose up, roll positive right wing down. This is the MAVLink ATTITUDE convention.
- Gimbal: FRD-like frame whose x axis is the optical axis. Its Euler angles use the same ZYX
  convention, so gimbal pitch -90 deg points the optical axis straight down and 0 deg at the
  horizon. Three reference frames for the gimbal angles are supported (see
  :func:`rotation_ned_from_gimbal`).
- Camera: OpenCV (x right in the image, y down in the image, z forward along the optical axis).
  ``R_gimbal_cam`` maps camera x -> gimbal y (right), camera y -> gimbal z (down), camera z ->
  gimbal x (forward).

Quaternions are MAVLink order ``(w, x, y, z)``, Hamilton convention, and represent ``R_a_b`` in the
same sense as the matrices (ATTITUDE_QUATERNION and GIMBAL_DEVICE_ATTITUDE_STATUS ``q``).
"""

from __future__ import annotations

import math

import numpy as np

#: Camera (OpenCV) axes expressed in the gimbal FRD frame: columns are cam x, cam y, cam z.
R_GIMBAL_CAM = np.array(
    [
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
    ]
)

#: GIMBAL_DEVICE_FLAGS bits used to pick the gimbal reference frame (MAVLink common.xml).
GIMBAL_DEVICE_FLAGS_ROLL_LOCK = 4
GIMBAL_DEVICE_FLAGS_PITCH_LOCK = 8
GIMBAL_DEVICE_FLAGS_YAW_LOCK = 16
GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME = 32
GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME = 64

GIMBAL_FRAMES = ("body", "vehicle", "earth")


def rot_x(a: float) -> np.ndarray:
    """Rotation about x by ``a`` radians: ``[[1,0,0],[0,c,-s],[0,s,c]]``."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    """Rotation about y by ``a`` radians: ``[[c,0,s],[0,1,0],[-s,0,c]]``."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    """Rotation about z by ``a`` radians: ``[[c,-s,0],[s,c,0],[0,0,1]]``."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def euler_to_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """ZYX Euler (radians) to ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (child frame -> parent)."""
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def matrix_to_euler(r: np.ndarray) -> tuple[float, float, float]:
    """Inverse of :func:`euler_to_matrix`: ``(roll, pitch, yaw)`` in radians.

    ``pitch = -asin(R[2,0])``, ``roll = atan2(R[2,1], R[2,2])``, ``yaw = atan2(R[1,0], R[0,0])``;
    at pitch = +-90 deg roll is set to 0 and the remaining rotation goes into yaw.
    """
    r = np.asarray(r, dtype=float)
    sp = -float(np.clip(r[2, 0], -1.0, 1.0))
    pitch = math.asin(sp)
    if abs(sp) > 1.0 - 1e-9:
        roll = 0.0
        yaw = math.atan2(-r[0, 1], r[1, 1])
    else:
        roll = math.atan2(r[2, 1], r[2, 2])
        yaw = math.atan2(r[1, 0], r[0, 0])
    return roll, pitch, yaw


def quaternion_to_matrix(q: tuple[float, float, float, float] | np.ndarray) -> np.ndarray:
    """Unit quaternion ``(w, x, y, z)`` to rotation matrix (normalises the input)."""
    w, x, y, z = (float(v) for v in q)
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if n == 0.0:
        raise ValueError("zero quaternion")
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def matrix_to_quaternion(r: np.ndarray) -> np.ndarray:
    """Rotation matrix to unit quaternion ``(w, x, y, z)`` with ``w >= 0`` (Shepperd's method)."""
    m = np.asarray(r, dtype=float)
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    qa = np.array(q)
    qa /= np.linalg.norm(qa)
    return -qa if qa[0] < 0 else qa


def euler_to_quaternion(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """ZYX Euler (radians) to quaternion ``(w, x, y, z)``."""
    return matrix_to_quaternion(euler_to_matrix(roll, pitch, yaw))


def quaternion_to_euler(q: tuple[float, float, float, float] | np.ndarray) -> tuple[float, ...]:
    """Quaternion ``(w, x, y, z)`` to ZYX Euler ``(roll, pitch, yaw)`` in radians."""
    return matrix_to_euler(quaternion_to_matrix(q))


def gimbal_frame_from_flags(flags: int) -> str:
    """Reference frame of GIMBAL_DEVICE_ATTITUDE_STATUS ``q`` from its ``flags`` field.

    Per MAVLink common.xml: YAW_IN_EARTH_FRAME -> yaw relative to north ("earth");
    YAW_IN_VEHICLE_FRAME -> yaw relative to the vehicle heading ("vehicle"); if neither is set,
    YAW_LOCK -> "earth" else "vehicle" (backwards compatibility). In both frames roll and pitch are
    relative to the horizon (gimbal protocol v2), so the result is never "body".
    """
    if flags & GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME:
        return "earth"
    if flags & GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME:
        return "vehicle"
    return "earth" if flags & GIMBAL_DEVICE_FLAGS_YAW_LOCK else "vehicle"


def rotation_ned_from_gimbal(
    vehicle_rpy: tuple[float, float, float],
    gimbal_rpy: tuple[float, float, float],
    gimbal_frame: str = "body",
) -> np.ndarray:
    """``R_ned_gimbal`` for gimbal Euler angles (radians) given in one of three frames.

    - ``"body"``: angles relative to the vehicle body (a hard mount or a non-stabilised gimbal):
      ``R = R_ned_body(vehicle) @ Rzyx(gimbal)``.
    - ``"vehicle"``: MAVLink gimbal-protocol "vehicle frame": roll and pitch relative to the
      horizon, yaw relative to the vehicle heading: ``R = Rz(vehicle_yaw) @ Rzyx(gimbal)``
      (``q_earth = q_delta_yaw * q_vehicle`` in GIMBAL_DEVICE_ATTITUDE_STATUS terms).
    - ``"earth"``: roll and pitch relative to the horizon, yaw relative to north
      (GIMBAL_DEVICE_FLAGS_YAW_LOCK / YAW_IN_EARTH_FRAME): ``R = Rzyx(gimbal)``.
    """
    r_g = euler_to_matrix(*gimbal_rpy)
    if gimbal_frame == "body":
        return euler_to_matrix(*vehicle_rpy) @ r_g
    if gimbal_frame == "vehicle":
        return rot_z(vehicle_rpy[2]) @ r_g
    if gimbal_frame == "earth":
        return r_g
    raise ValueError(f"gimbal_frame must be one of {GIMBAL_FRAMES}, got {gimbal_frame!r}")


def rotation_ned_from_camera(
    vehicle_rpy: tuple[float, float, float],
    gimbal_rpy: tuple[float, float, float],
    gimbal_frame: str = "body",
) -> np.ndarray:
    """``R_ned_cam``: camera (OpenCV) -> gimbal -> body -> NED. All angles in radians.

    ``R_ned_cam = R_ned_gimbal(vehicle_rpy, gimbal_rpy, gimbal_frame) @ R_GIMBAL_CAM``.
    Example: level vehicle, yaw 0, gimbal pitch -pi/2 (nadir): the optical axis points down,
    image right (camera x) points east and image down (camera y) points south (north is up).
    """
    return rotation_ned_from_gimbal(vehicle_rpy, gimbal_rpy, gimbal_frame) @ R_GIMBAL_CAM


def slerp(q0: np.ndarray, q1: np.ndarray, s: float) -> np.ndarray:
    """Spherical linear interpolation between quaternions ``(w, x, y, z)``, ``s`` in [0, 1]."""
    a = np.asarray(q0, dtype=float) / np.linalg.norm(q0)
    b = np.asarray(q1, dtype=float) / np.linalg.norm(q1)
    dot = float(np.dot(a, b))
    if dot < 0.0:
        b, dot = -b, -dot
    if dot > 0.9995:
        q = a + s * (b - a)
        return q / np.linalg.norm(q)
    theta = math.acos(min(dot, 1.0))
    sin_t = math.sin(theta)
    return (math.sin((1 - s) * theta) * a + math.sin(s * theta) * b) / sin_t
