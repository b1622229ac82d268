"""Plausibility checks of autopilot telemetry messages, field by field, before they are believed.

Every MAVLink message is untrusted input: a sender can put NaN, inf or absurd numbers in any
field. :func:`message_problem` returns "" for a message whose fields are finite and in range,
else a short reason ("lat 214.7 out of range"). The limits are physical, not tuned: a position
on Earth, a height an aircraft can fly at, a speed an aircraft can reach, unit quaternions.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

#: Heights above home and above mean sea level an aircraft plausibly reports (metres).
REL_ALT_RANGE_M = (-1000.0, 12000.0)
AMSL_RANGE_M = (-1000.0, 15000.0)
#: Fastest ground speed believed (m/s): fixed wings rarely exceed 60; 150 is a hard ceiling.
MAX_SPEED_MPS = 150.0
#: How far a quaternion's norm may stray from 1 (autopilots send normalised ones).
QUATERNION_NORM_TOLERANCE = 0.1
#: GPS_RAW_INT ``fix_type`` needed for a position: MAV_GPS_FIX_TYPE_3D_FIX or better.
GPS_FIX_3D = 3


def _finite(*values: float) -> bool:
    return all(isinstance(v, (int, float)) and math.isfinite(v) for v in values)


def lat_lon_problem(lat_deg: float, lon_deg: float) -> str:
    """ "" when ``lat``/``lon`` (degrees) are a place on Earth, else why not."""
    if not _finite(lat_deg, lon_deg):
        return "position not finite"
    if not -90.0 <= lat_deg <= 90.0:
        return f"lat {lat_deg:.7g} out of range"
    if not -180.0 <= lon_deg <= 180.0:
        return f"lon {lon_deg:.7g} out of range"
    return ""


def _in(value: float, bounds: tuple[float, float], what: str) -> str:
    if not _finite(value):
        return f"{what} not finite"
    if not bounds[0] <= value <= bounds[1]:
        return f"{what} {value:.6g} out of range"
    return ""


def quaternion_problem(q: Sequence[float]) -> str:
    """ "" for a finite quaternion of norm close to 1."""
    values = [float(v) for v in q]
    if len(values) != 4 or not _finite(*values):
        return "quaternion not finite"
    norm = math.sqrt(sum(v * v for v in values))
    if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        return f"quaternion norm {norm:.3g}"
    return ""


def _global_position_int(msg: Any) -> str:
    problem = lat_lon_problem(msg.lat / 1e7, msg.lon / 1e7)
    problem = problem or _in(msg.relative_alt / 1000.0, REL_ALT_RANGE_M, "relative_alt")
    problem = problem or _in(msg.alt / 1000.0, AMSL_RANGE_M, "alt")
    if problem:
        return problem
    speed = math.sqrt(msg.vx**2 + msg.vy**2 + msg.vz**2) / 100.0
    return f"speed {speed:.0f} m/s implausible" if speed > MAX_SPEED_MPS else ""


def _attitude(msg: Any) -> str:
    if not _finite(msg.roll, msg.pitch, msg.yaw):
        return "attitude not finite"
    if abs(msg.roll) > math.pi + 1e-3 or abs(msg.pitch) > math.pi / 2 + 1e-3:
        return f"roll/pitch {msg.roll:.3g}/{msg.pitch:.3g} rad out of range"
    if abs(msg.yaw) > 2 * math.pi + 1e-3:
        return f"yaw {msg.yaw:.3g} rad out of range"
    return ""


def _attitude_quaternion(msg: Any) -> str:
    return quaternion_problem((msg.q1, msg.q2, msg.q3, msg.q4))


def _gimbal_device_attitude_status(msg: Any) -> str:
    problem = quaternion_problem(msg.q)
    if problem:
        return f"gimbal {problem}"
    delta_yaw = getattr(msg, "delta_yaw", math.nan)
    if math.isinf(delta_yaw) or (math.isfinite(delta_yaw) and abs(delta_yaw) > 2 * math.pi + 1e-3):
        return f"gimbal delta_yaw {delta_yaw:.3g} out of range"
    return ""


def _mount_orientation(msg: Any) -> str:
    if not _finite(msg.roll, msg.pitch, msg.yaw):
        return "mount angles not finite"
    if max(abs(msg.roll), abs(msg.pitch), abs(msg.yaw)) > 360.0:
        return "mount angles out of range"
    yaw_abs = getattr(msg, "yaw_absolute", math.nan)
    if math.isinf(yaw_abs) or (math.isfinite(yaw_abs) and abs(yaw_abs) > 360.0):
        return "mount yaw_absolute out of range"
    return ""


def _home_position(msg: Any) -> str:
    lat, lon = msg.latitude / 1e7, msg.longitude / 1e7
    if lat == 0 and lon == 0:
        return "home at 0, 0"
    return lat_lon_problem(lat, lon) or _in(msg.altitude / 1000.0, AMSL_RANGE_M, "home altitude")


def _gps_raw_int(msg: Any) -> str:
    return "" if 0 <= int(msg.fix_type) <= 8 else f"fix_type {msg.fix_type} unknown"


_CHECKS: dict[str, Callable[[Any], str]] = {
    "GLOBAL_POSITION_INT": _global_position_int,
    "ATTITUDE": _attitude,
    "ATTITUDE_QUATERNION": _attitude_quaternion,
    "GIMBAL_DEVICE_ATTITUDE_STATUS": _gimbal_device_attitude_status,
    "MOUNT_ORIENTATION": _mount_orientation,
    "HOME_POSITION": _home_position,
    "GPS_RAW_INT": _gps_raw_int,
}


def message_problem(msg: Any) -> str:
    """ "" when every field of ``msg`` that telemetry uses is finite and plausible, else why not
    (types without a check pass)."""
    check = _CHECKS.get(msg.get_type())
    if check is None:
        return ""
    try:
        return check(msg)
    except (TypeError, ValueError, AttributeError, OverflowError) as exc:
        return f"malformed ({exc.__class__.__name__})"
