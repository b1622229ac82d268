"""ArduPilot DataFlash logs (.bin onboard, .log as text), via pymavlink's DFReader.

Clock: ``TimeUS`` (microseconds since the autopilot booted) in seconds. UTC from the GPS
messages (``GWk``, ``GMS``: GPS week and milliseconds, minus the 18 leap seconds), the median
of ``UTC - TimeUS`` over the fixes.

Messages (first instance ``I`` 0 where there are several) and conventions:

- POS: the EKF position (``Lat``/``Lng`` degrees, ``Alt`` AMSL, ``RelHomeAlt`` above home);
  logs without POS use GPS (``Alt`` AMSL minus home's). Positions are believed only while the
  newest GPS (at most 5 s old) has ``Status`` >= 3 (3D fix); GPA ``HAcc`` (m) of that fix is
  its horizontal 1-sigma.
- ATT: ``Roll``, ``Pitch``, ``Yaw`` in degrees, aerospace ZYX (pitch up positive, yaw
  clockwise from north).
- MNT: the mount. ``Pitch`` is negative below the horizon (-90 straight down). For a mount
  with attitude feedback the documented meaning holds: ``Roll``/``Pitch`` from the horizon,
  ``YawE`` from north (``YawB`` relative to the heading when ``YawE`` is not a number). A
  servo mount (``MNT1_TYPE`` 1 in the log's parameters) has no feedback and logs the angles
  it commands its servos, which are relative to the airframe: ``Roll``, ``Pitch``, ``YawB``
  are then taken in the body frame (observed on ArduCopter 4.7 SITL: a -60 deg earth-frame
  demand at 12 deg nose-down logs ``Pitch`` -48).
- ORGN ``Type`` 1: home (``Type`` 0, the EKF origin, when no home is logged).
- CAM and TRIG: camera triggers (``TimeUS``).
"""

from __future__ import annotations

import dataclasses
import math
import statistics
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from sarmission.flightlog.model import (
    ACCURACY,
    FlightLog,
    FlightLogError,
    LogBuilder,
    gps_to_posix,
)

GPS_FIX_MAX_AGE_S = 5.0
_TYPES = ["GPS", "GPA", "POS", "ATT", "MNT", "CAM", "TRIG", "ORGN", "PARM"]
_SERVO_MOUNT = 1


class _State:
    def __init__(self) -> None:
        self.gps: tuple[float, int] | None = None  # (t, status) of the newest GPS
        self.h_acc: float | None = None
        self.utc_offsets: list[float] = []
        self.gps_positions: list[Any] = []
        self.has_pos = False
        self.origin: tuple[float, float, float] | None = None
        self.mount_type: int | None = None
        self.mounts: list[Any] = []


def _open_dataflash(path: Path) -> Any:
    """pymavlink's binary or text reader, chosen by the content (``mavlink_connection`` picks
    by the file name: a .BIN renamed .tlog, or a name with a colon, went astray)."""
    from pymavlink import DFReader

    with path.open("rb") as f:
        binary = f.read(2) == b"\xa3\x95"
    return DFReader.DFReader_binary(str(path)) if binary else DFReader.DFReader_text(str(path))


def read_dataflash(path: str | Path) -> FlightLog:
    """Read a DataFlash log (see the module docstring)."""
    path = Path(path)
    builder = LogBuilder(
        "ArduPilot DataFlash log", path, "autopilot boot time (TimeUS)", ACCURACY["autopilot"]
    )
    try:
        reader = _open_dataflash(path)
    except Exception as exc:  # noqa: BLE001 - DFReader raises anything on a bad header
        raise FlightLogError(f"{path.name}: not readable as a DataFlash log ({exc})") from exc
    state = _State()
    try:
        while True:
            try:
                msg = reader.recv_match(type=_TYPES)
            except Exception as exc:  # noqa: BLE001 - a corrupt tail ends the log
                builder.log.notes.append(
                    f"{path.name}: read stopped at a corrupt message ({type(exc).__name__})"
                )
                break
            if msg is None:
                break
            _take(builder, state, msg)
    finally:
        close = getattr(reader, "close", None)
        if close is not None:
            close()
    log = builder.log
    if not state.has_pos:
        _gps_positions(builder, state)
    frame = "body" if state.mount_type == _SERVO_MOUNT else None
    for msg in state.mounts:
        _mount(builder, msg, frame)
    if state.mounts and state.mount_type is None:
        _unknown_mount_frame(builder)
    if state.utc_offsets:
        log.utc_offset_s = statistics.median(state.utc_offsets)
        log.clock += ", UTC from GPS time"
    if log.home is None and state.origin is not None:
        log.home = state.origin
        log.home_note = "home from the EKF origin (ORGN type 0)"
    return builder.build()


def _t(msg: Any) -> float:
    return float(msg.TimeUS) / 1e6


def _take(builder: LogBuilder, state: _State, msg: Any) -> None:
    mtype = msg.get_type()
    if getattr(msg, "I", 0) not in (0, None):
        return
    if mtype == "PARM":
        if msg.Name == "MNT1_TYPE":
            state.mount_type = int(msg.Value)
        return
    handler = _TIMED.get(mtype)
    if handler is not None and hasattr(msg, "TimeUS"):
        handler(builder, state, msg, _t(msg))


def _gps(builder: LogBuilder, state: _State, msg: Any, t: float) -> None:
    state.gps = (t, int(msg.Status))
    if int(msg.Status) >= 3 and msg.GWk > 0:
        state.utc_offsets.append(gps_to_posix(int(msg.GWk), float(msg.GMS)) - t)
        state.gps_positions.append(msg)


def _gpa(builder: LogBuilder, state: _State, msg: Any, t: float) -> None:
    h_acc = float(msg.HAcc)
    state.h_acc = h_acc if math.isfinite(h_acc) and h_acc > 0 else None


def _pos(builder: LogBuilder, state: _State, msg: Any, t: float) -> None:
    state.has_pos = True
    if _fix_ok(builder, state, t):
        builder.position(
            t, float(msg.Lat), float(msg.Lng), float(msg.RelHomeAlt), float(msg.Alt), state.h_acc
        )


def _att(builder: LogBuilder, state: _State, msg: Any, t: float) -> None:
    builder.attitude_euler(
        t, math.radians(msg.Roll), math.radians(msg.Pitch), math.radians(msg.Yaw)
    )


def _mnt(builder: LogBuilder, state: _State, msg: Any, t: float) -> None:
    state.mounts.append(msg)  # its frame depends on MNT1_TYPE, which may come later


def _trigger(builder: LogBuilder, state: _State, msg: Any, t: float) -> None:
    builder.trigger(t)


def _orgn(builder: LogBuilder, state: _State, msg: Any, t: float) -> None:
    where = (float(msg.Lat), float(msg.Lng), float(msg.Alt))
    if int(msg.Type) == 1:
        builder.log.home = where
        builder.log.home_note = "home from ORGN (type 1)"
    elif int(msg.Type) == 0:
        state.origin = where


#: What each timed message adds to the log.
_TIMED: dict[str, Callable[[LogBuilder, _State, Any, float], None]] = {
    "GPS": _gps,
    "GPA": _gpa,
    "POS": _pos,
    "ATT": _att,
    "MNT": _mnt,
    "CAM": _trigger,
    "TRIG": _trigger,
    "ORGN": _orgn,
}


def _fix_ok(builder: LogBuilder, state: _State, t: float) -> bool:
    if state.gps is None:
        builder.reject("position before any GPS message (fix unknown)")
        return False
    if t - state.gps[0] > GPS_FIX_MAX_AGE_S:
        builder.reject("position with a GPS message older than 5 s (fix unknown)")
        return False
    if state.gps[1] < 3:
        builder.reject("position without a 3D GPS fix")
        return False
    return True


def _gps_positions(builder: LogBuilder, state: _State) -> None:
    """Positions from GPS where the log has no POS: height above home from the home altitude."""
    home = builder.log.home or state.origin
    if home is None:
        if state.gps_positions:
            builder.reject("GPS position without POS or a logged home (height unknown)")
        return
    for msg in state.gps_positions:
        builder.position(
            _t(msg), float(msg.Lat), float(msg.Lng), float(msg.Alt) - home[2], float(msg.Alt)
        )
    builder.log.notes.append(f"{builder.log.path.name}: no POS messages; positions from GPS")


def _unknown_mount_frame(builder: LogBuilder) -> None:
    """No ``MNT1_TYPE`` in the log: its MOUNT angles may be a servo mount's (relative to the
    airframe) or a stabilised one's (earth frame); they differ by the vehicle's tilt. The
    angles are read as a stabilised mount's, and the pointing error is widened so that twice
    it covers the tilt of 95 % of the flight: a fix then says how unsure it is (12.6 m off at
    a 1.8 m error before)."""
    log = builder.log
    tilts = [
        math.degrees(math.acos(min(1.0, abs(1.0 - 2.0 * (a.q[1] ** 2 + a.q[2] ** 2)))))
        for a in log.attitudes
    ]
    tilt = float(np.percentile(tilts, 95)) if tilts else UNKNOWN_TILT_DEG
    sigma = max(log.accuracy.attitude_sigma_deg, tilt / 2.0)
    log.accuracy = dataclasses.replace(log.accuracy, attitude_sigma_deg=sigma)
    log.notes.append(
        f"{log.path.name}: no MNT1_TYPE parameter: the mount's angles may be relative to the "
        f"airframe (a servo mount) or to the horizon; taken as the latter, with the pointing "
        f"error widened to {sigma:.1f} deg (the vehicle tilts up to {tilt:.0f} deg)"
    )


#: Tilt assumed when a log has no attitude to measure it by (degrees).
UNKNOWN_TILT_DEG = 20.0


def _mount(builder: LogBuilder, msg: Any, frame: str | None) -> None:
    t = _t(msg)
    roll, pitch = math.radians(msg.Roll), math.radians(msg.Pitch)
    if frame == "body":
        builder.gimbal_euler(t, roll, pitch, math.radians(msg.YawB), "body")
    elif math.isfinite(msg.YawE):
        builder.gimbal_euler(t, roll, pitch, math.radians(msg.YawE), "earth")
    else:
        builder.gimbal_euler(t, roll, pitch, math.radians(msg.YawB), "vehicle")
