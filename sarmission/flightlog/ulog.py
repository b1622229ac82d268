"""PX4 ULog (.ulg), via pyulog.

Clock: each topic's ``timestamp`` (microseconds since the autopilot booted) in seconds. UTC
from the GNSS receiver's ``time_utc_usec`` (topic ``sensor_gps``, ``vehicle_gps_position`` in
older logs): the median of ``UTC - timestamp``.

Topics (instance 0) and conventions:

- vehicle_global_position: ``lat``/``lon`` degrees, ``alt`` AMSL, ``eph`` the horizontal
  1-sigma (m). Height above home is ``alt - home_position.alt``. Believed only while the
  newest GNSS sample (at most 5 s old) has ``fix_type`` >= 3.
- vehicle_attitude: ``q[0..3]`` = ``(w, x, y, z)``, Hamilton, rotating body FRD into NED: the
  same quaternion as MAVLink's ATTITUDE_QUATERNION, so pitch up is positive and yaw runs
  clockwise from north.
- gimbal_device_attitude_status: ``q[0..3]`` in the frame ``device_flags`` say (MAVLink
  GIMBAL_DEVICE_FLAGS: yaw in the earth frame with YAW_LOCK or YAW_IN_EARTH_FRAME, else in
  the vehicle frame); pitch -90 deg straight down.
- home_position: home (without it, no height above home: the log gives no positions). Rows
  at 0, 0 or not finite are left out; when home is set again during the log (armed again),
  each position's height is above the home of its time.
- camera_capture, camera_trigger: camera triggers (``timestamp``).
"""

from __future__ import annotations

import bisect
import math
import statistics
from pathlib import Path
from typing import Any

import numpy as np

from sarmission.flightlog.model import ACCURACY, FlightLog, FlightLogError, LogBuilder
from sarmission.geo.frames import gimbal_frame_from_flags
from sarmission.mavlink.telemetry_checks import lat_lon_problem

GPS_FIX_MAX_AGE_S = 5.0
#: A home that moves more than this in height during a log is worth a note (metres).
HOME_MOVED_NOTE_M = 2.0
_TOPICS = [
    "vehicle_global_position",
    "vehicle_gps_position",
    "sensor_gps",
    "vehicle_attitude",
    "home_position",
    "gimbal_device_attitude_status",
    "camera_capture",
    "camera_trigger",
]


def _topics(path: Path) -> dict[str, dict[str, np.ndarray]]:
    from pyulog import ULog

    try:
        ulog = ULog(str(path), _TOPICS)
    except Exception as exc:  # noqa: BLE001 - pyulog raises anything on a bad file
        raise FlightLogError(f"{path.name}: not readable as a PX4 ULog ({exc})") from exc
    topics: dict[str, dict[str, np.ndarray]] = {}
    for data in ulog.data_list:
        if data.multi_id == 0 and data.name not in topics:
            topics[data.name] = data.data
    if getattr(ulog, "file_corruption", False):
        topics["_corrupt"] = {}
    return topics


def _seconds(topic: dict[str, np.ndarray]) -> np.ndarray:
    return np.asarray(topic["timestamp"], dtype=float) / 1e6


def read_ulog(path: str | Path) -> FlightLog:
    """Read a ULog (see the module docstring)."""
    path = Path(path)
    topics = _topics(path)
    builder = LogBuilder("PX4 ULog", path, "autopilot boot time (timestamp)", ACCURACY["autopilot"])
    log = builder.log
    if "_corrupt" in topics:
        log.notes.append(f"{path.name}: pyulog found corrupt data; read what it could")
    gps = topics.get("sensor_gps") or topics.get("vehicle_gps_position")
    homes = _valid_homes(builder, topics.get("home_position"))
    if homes:
        log.home = homes[0][1]
        log.home_note = "home from home_position"
        moved = max(h[2] for _, h in homes) - min(h[2] for _, h in homes)
        if moved > HOME_MOVED_NOTE_M:
            log.notes.append(
                f"{path.name}: home_position moved {moved:.1f} m in height during the log "
                "(set again, e.g. when armed again); heights use the home of their time"
            )
    if gps is not None:
        _utc(log, gps)
    _positions(builder, topics.get("vehicle_global_position"), gps, homes)
    att = topics.get("vehicle_attitude")
    if att is not None:
        for t, *q in zip(_seconds(att), *(att[f"q[{i}]"] for i in range(4)), strict=True):
            builder.attitude_quaternion(t, q)
    gim = topics.get("gimbal_device_attitude_status")
    if gim is not None:
        flags = gim.get("device_flags", np.zeros(len(gim["timestamp"])))
        for t, f, *q in zip(_seconds(gim), flags, *(gim[f"q[{i}]"] for i in range(4)), strict=True):
            builder.gimbal_quaternion(t, q, gimbal_frame_from_flags(int(f)))
    for name in ("camera_capture", "camera_trigger"):
        topic = topics.get(name)
        if topic is not None:
            for t in _seconds(topic):
                builder.trigger(float(t))
            break
    return builder.build()


def _utc(log: FlightLog, gps: dict[str, np.ndarray]) -> None:
    utc = np.asarray(gps.get("time_utc_usec", []), dtype=float)
    t = _seconds(gps)
    ok = utc > 0
    if np.any(ok):
        log.utc_offset_s = float(statistics.median(utc[ok] / 1e6 - t[ok]))
        log.clock += ", UTC from GNSS time"


def _valid_homes(
    builder: LogBuilder, home: dict[str, np.ndarray] | None
) -> list[tuple[float, tuple[float, float, float]]]:
    """The ``home_position`` rows that are a place (``(t, (lat, lon, alt))`` in time order):
    a home at 0, 0 or not finite (sent before the estimator had one) is counted and left out;
    believed, it put the ground 100 m off and every fix hundreds of metres away."""
    if home is None:
        return []
    rows = []
    for t, lat, lon, alt in zip(_seconds(home), home["lat"], home["lon"], home["alt"], strict=True):
        lat, lon, alt = float(lat), float(lon), float(alt)
        if (lat == 0 and lon == 0) or lat_lon_problem(lat, lon) or not math.isfinite(alt):
            builder.reject("home_position not a place (0, 0 or not finite)")
            continue
        rows.append((float(t), (lat, lon, alt)))
    return rows


def _home_at(homes: list[tuple[float, tuple[float, float, float]]], t: float) -> float:
    """Altitude of the home in effect at ``t`` (the first one before any)."""
    i = bisect.bisect_right(homes, t, key=lambda home: home[0]) - 1
    return homes[max(i, 0)][1][2]


def _positions(
    builder: LogBuilder,
    pos: dict[str, np.ndarray] | None,
    gps: dict[str, np.ndarray] | None,
    homes: list[tuple[float, tuple[float, float, float]]],
) -> None:
    if pos is None or not len(pos["timestamp"]):
        return
    if not homes:
        builder.reject("vehicle_global_position without home_position (height unknown)")
        return
    if gps is None:
        builder.reject("vehicle_global_position without GNSS status (fix unknown)")
        return
    gps_t = _seconds(gps)
    fix = np.asarray(gps["fix_type"], dtype=int)
    eph = pos.get("eph")
    for k, t in enumerate(_seconds(pos)):
        i = int(np.searchsorted(gps_t, t, side="right")) - 1
        if i < 0 or t - gps_t[i] > GPS_FIX_MAX_AGE_S:
            builder.reject("position without a recent GNSS sample (fix unknown)")
            continue
        if fix[i] < 3:
            builder.reject("position without a 3D GNSS fix")
            continue
        alt = float(pos["alt"][k])
        sigma: Any = float(eph[k]) if eph is not None else None
        builder.position(
            float(t),
            float(pos["lat"][k]),
            float(pos["lon"][k]),
            alt - _home_at(homes, float(t)),
            alt,
            sigma,
        )
