"""MAVLink telemetry logs (.tlog, as QGroundControl and MAVProxy write them), via pymavlink.

A tlog is every MAVLink packet the ground station received, each after an 8-byte big-endian
microsecond POSIX timestamp of its arrival. Only the autopilot is believed: the first sender
of an autopilot-type HEARTBEAT (:func:`~sarmission.mavlink.adoption.is_autopilot_heartbeat`:
not a ground station, camera or gimbal), and its system's gimbal for its angles; every message
goes through the same field checks as live telemetry
(:func:`~sarmission.mavlink.telemetry_checks.message_problem`).

Clock: the autopilot's ``time_boot_ms`` in seconds. A reboot (boot time back by more than a
second) ends what is read: samples of a later boot would sit on another timeline. UTC: from
SYSTEM_TIME (``time_unix_usec - time_boot_ms``, the autopilot's GNSS time) when it is set,
else the ground station's arrival stamps (the least-delayed ``arrival - boot``).

Messages and conventions (the live buffer's, :mod:`sarmission.mavlink.telemetry`):

- GLOBAL_POSITION_INT: lat/lon 1e-7 deg, ``relative_alt`` mm above home, ``alt`` mm AMSL;
  believed only while the newest GPS_RAW_INT (at most 5 s old) reports a 3D fix, whose
  ``h_acc`` (mm, when non-zero) is the fix's horizontal 1-sigma.
- ATTITUDE (ZYX Euler radians, pitch up positive, yaw clockwise from north) and
  ATTITUDE_QUATERNION.
- GIMBAL_DEVICE_ATTITUDE_STATUS: ``q`` in the frame its ``flags`` say; MOUNT_ORIENTATION:
  degrees, roll/pitch from the horizon (pitch -90 straight down), ``yaw_absolute`` from
  north when finite, else ``yaw`` relative to the heading.
- HOME_POSITION: home. CAMERA_FEEDBACK: a camera trigger at ``time_usec`` (UTC), else its
  arrival.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pymavlink import mavutil

from sarmission.flightlog.model import ACCURACY, FlightLog, FlightLogError, LogBuilder
from sarmission.geo.frames import gimbal_frame_from_flags
from sarmission.mavlink.adoption import GIMBAL_TYPES, is_autopilot_heartbeat, source_kind
from sarmission.mavlink.telemetry_checks import GPS_FIX_3D, message_problem

#: A GPS_RAW_INT older than this says nothing about the current fix (seconds).
GPS_FIX_MAX_AGE_S = 5.0
_TYPES = [
    "HEARTBEAT",
    "GLOBAL_POSITION_INT",
    "GPS_RAW_INT",
    "ATTITUDE",
    "ATTITUDE_QUATERNION",
    "GIMBAL_DEVICE_ATTITUDE_STATUS",
    "MOUNT_ORIENTATION",
    "HOME_POSITION",
    "SYSTEM_TIME",
    "CAMERA_FEEDBACK",
]


class _State:
    def __init__(self) -> None:
        self.autopilot: tuple[int, int] | None = None
        # (boot s or None: before any boot time was seen, fix type, h_acc m)
        self.gps: tuple[float | None, int, float | None] | None = None
        self.last_boot = -math.inf
        self.arrival_offsets: list[float] = []
        self.system_offsets: list[float] = []
        self.feedback_utc: list[float] = []
        self.feedback_arrival: list[float] = []
        self.rebooted = False


def read_tlog(path: str | Path) -> FlightLog:
    """Read a tlog (see the module docstring); :class:`FlightLogError` when it gives nothing."""
    path = Path(path)
    builder = LogBuilder("MAVLink tlog", path, "autopilot boot time", ACCURACY["autopilot"])
    try:
        # a tlog whatever its name (mavlink_connection picks the reader by the file name)
        mavutil.set_dialect("ardupilotmega")
        conn = mavutil.mavlogfile(str(path), robust_parsing=True)
    except Exception as exc:  # noqa: BLE001 - pymavlink raises anything on a bad file
        raise FlightLogError(f"{path.name}: not readable as a MAVLink tlog ({exc})") from exc
    state = _State()
    try:
        while not state.rebooted:
            try:
                msg = conn.recv_match(type=_TYPES)
            except Exception as exc:  # noqa: BLE001 - a corrupt tail ends the log
                builder.log.notes.append(
                    f"{path.name}: read stopped at a corrupt packet ({type(exc).__name__})"
                )
                break
            if msg is None:
                break
            _take(builder, state, msg)
    finally:
        conn.close()
    if state.autopilot is None:
        raise FlightLogError(
            f"{path.name}: no autopilot HEARTBEAT: not a MAVLink tlog of a "
            "flight (or truncated before one)"
        )
    log = builder.log
    if state.rebooted:
        log.notes.append(
            f"{path.name}: the autopilot rebooted during the log; read up to the reboot"
        )
    _place_in_utc(builder, state)
    return builder.build()


def _place_in_utc(builder: LogBuilder, state: _State) -> None:
    """The log's UTC offset from SYSTEM_TIME, else from the arrival stamps; camera triggers,
    stamped in UTC or on arrival, placed on the boot clock with it."""
    log = builder.log
    if state.system_offsets:
        log.utc_offset_s = statistics.median(state.system_offsets)
        log.clock += ", UTC from the autopilot's SYSTEM_TIME"
    elif state.arrival_offsets:
        log.utc_offset_s = min(state.arrival_offsets)
        log.clock += ", UTC from the ground station's arrival stamps"
    if log.utc_offset_s is not None:
        for utc in state.feedback_utc:
            builder.trigger(utc - log.utc_offset_s)
        for arrival in state.feedback_arrival:
            builder.trigger(arrival - log.utc_offset_s)


def _take(builder: LogBuilder, state: _State, msg: Any) -> None:
    mtype = msg.get_type()
    source = (msg.get_srcSystem(), msg.get_srcComponent())
    if mtype == "HEARTBEAT":
        # the live link's rule: a camera, gimbal or ground station heard first is no autopilot
        if state.autopilot is None and is_autopilot_heartbeat(msg):
            state.autopilot = source
        return
    kind = source_kind(source, state.autopilot)
    if kind != "autopilot" and not (kind == "gimbal" and mtype in GIMBAL_TYPES):
        return  # the live link's rule: the autopilot, and its system's gimbal for its angles
    problem = message_problem(msg)
    if problem:
        builder.reject(f"{mtype} implausible")
        return
    arrival = float(getattr(msg, "_timestamp", math.nan))
    if mtype == "HOME_POSITION":
        builder.log.home = (msg.latitude / 1e7, msg.longitude / 1e7, msg.altitude / 1000.0)
        builder.log.home_note = "home from HOME_POSITION"
    elif mtype == "CAMERA_FEEDBACK":
        _camera_feedback(state, msg, arrival)
    else:
        boot_s = _boot_seconds(state, msg, arrival)
        handler = _TIMED.get(mtype)
        if boot_s is not None and handler is not None:
            handler(builder, state, msg, boot_s)


def _camera_feedback(state: _State, msg: Any, arrival: float) -> None:
    if msg.time_usec > 0:
        state.feedback_utc.append(msg.time_usec / 1e6)
    elif math.isfinite(arrival):
        state.feedback_arrival.append(arrival)


def _boot_seconds(state: _State, msg: Any, arrival: float) -> float | None:
    """The message's autopilot boot time in seconds; None (and ``state.rebooted``) when it goes
    back by more than a second: the autopilot rebooted."""
    boot = getattr(msg, "time_boot_ms", None)
    if boot is None:  # GPS_RAW_INT: time_usec may be since boot or UNIX: take the newest boot
        return state.last_boot
    boot_s = boot / 1000.0
    if boot_s < state.last_boot - 1.0:
        state.rebooted = True
        return None
    state.last_boot = max(state.last_boot, boot_s)
    if math.isfinite(arrival):
        state.arrival_offsets.append(arrival - boot_s)
    return boot_s


def _system_time(builder: LogBuilder, state: _State, msg: Any, boot_s: float) -> None:
    if msg.time_unix_usec > 0:
        state.system_offsets.append(msg.time_unix_usec / 1e6 - boot_s)


def _gps_raw(builder: LogBuilder, state: _State, msg: Any, boot_s: float) -> None:
    h_acc = getattr(msg, "h_acc", 0)
    state.gps = (
        boot_s if math.isfinite(boot_s) else None,
        int(msg.fix_type),
        h_acc / 1000.0 if 0 < h_acc < 0xFFFFFFFF else None,
    )


def _attitude(builder: LogBuilder, state: _State, msg: Any, boot_s: float) -> None:
    builder.attitude_euler(boot_s, msg.roll, msg.pitch, msg.yaw)


def _attitude_quaternion(builder: LogBuilder, state: _State, msg: Any, boot_s: float) -> None:
    builder.attitude_quaternion(boot_s, (msg.q1, msg.q2, msg.q3, msg.q4))


def _gimbal_status(builder: LogBuilder, state: _State, msg: Any, boot_s: float) -> None:
    frame = gimbal_frame_from_flags(int(msg.flags))
    builder.gimbal_quaternion(boot_s, msg.q, frame)


def _mount_orientation(builder: LogBuilder, state: _State, msg: Any, boot_s: float) -> None:
    roll, pitch = math.radians(msg.roll), math.radians(msg.pitch)
    if math.isfinite(msg.yaw_absolute):
        builder.gimbal_euler(boot_s, roll, pitch, math.radians(msg.yaw_absolute), "earth")
    else:
        builder.gimbal_euler(boot_s, roll, pitch, math.radians(msg.yaw), "vehicle")


def _position(builder: LogBuilder, state: _State, msg: Any, boot_s: float) -> None:
    gps = state.gps
    if gps is None:
        builder.reject("position before any GPS_RAW_INT (fix unknown)")
        return
    if gps[0] is not None and boot_s - gps[0] > GPS_FIX_MAX_AGE_S:
        builder.reject("position with a GPS_RAW_INT older than 5 s (fix unknown)")
        return
    if gps[1] < GPS_FIX_3D:
        builder.reject("position without a 3D GPS fix")
        return
    builder.position(
        boot_s, msg.lat / 1e7, msg.lon / 1e7, msg.relative_alt / 1000.0, msg.alt / 1000.0, gps[2]
    )


#: What each message with a boot time adds to the log.
_TIMED: dict[str, Callable[[LogBuilder, _State, Any, float], None]] = {
    "SYSTEM_TIME": _system_time,
    "GPS_RAW_INT": _gps_raw,
    "GLOBAL_POSITION_INT": _position,
    "ATTITUDE": _attitude,
    "ATTITUDE_QUATERNION": _attitude_quaternion,
    "GIMBAL_DEVICE_ATTITUDE_STATUS": _gimbal_status,
    "MOUNT_ORIENTATION": _mount_orientation,
}
