"""Buffered autopilot telemetry, interpolated to a frame's capture time.

Sources, per kind (newest wins when two give the same time):

- position: GLOBAL_POSITION_INT (lat, lon, relative_alt, alt, vx/vy/vz, hdg). ``0, 0`` is ignored
  (ArduPilot reports it until its EKF has a GPS origin).
- vehicle attitude: ATTITUDE (ZYX Euler) and ATTITUDE_QUATERNION (``q1..q4 = w, x, y, z``).
- gimbal attitude: GIMBAL_DEVICE_ATTITUDE_STATUS, its frame from ``flags``
  (:func:`~sarmission.geo.frames.gimbal_frame_from_flags`). A vehicle-frame ``q`` with a finite
  ``delta_yaw`` is turned into the earth frame on arrival, ``R_earth = Rz(delta_yaw) R_vehicle``
  (``q_earth = q_delta_yaw * q``), so interpolation happens in one frame; without ``delta_yaw``
  it stays in the vehicle frame and is combined with the interpolated vehicle yaw. Else
  MOUNT_ORIENTATION (degrees; roll/pitch relative to the horizon, ``yaw_absolute`` from north
  when finite, else ``yaw`` relative to the heading). If no gimbal message was ever received the
  fixed mount given to the constructor is used (a hard mount, or an autopilot without a gimbal
  driver). Once a gimbal has reported, it must keep reporting: stale gimbal data is no pose.
- HOME_POSITION: home ``(lat, lon, alt)``, the ground plane for geolocation.
- GPS_RAW_INT ``h_acc`` (mm, when non-zero) as the 1-sigma GNSS error per horizontal axis.

Clock: samples carry the autopilot's ``time_boot_ms``. With ``latency = arrival - capture`` and
``offset = local - boot``, ``arrival - boot = offset + latency >= offset``; the offset is estimated
as the minimum of ``arrival - boot`` over a sliding window (the least-delayed message), so a
sample's local time is ``boot + min(arrival - boot) - transport_latency_s``. Each sample is mapped
with the estimate current at its arrival. A backwards jump of the boot time (autopilot reboot)
restarts the estimate. The local clock is ``time.monotonic()`` unless arrival times are given.

Interpolation: position linearly (lat, lon, altitudes), beyond the newest sample extrapolated
with the reported velocity; attitudes by slerp, held beyond the ends. A pose is refused (a
:class:`StaleTelemetry` reason) when the requested time is more than ``stale_after_s`` past the
newest sample, before the oldest, or inside a gap where both neighbours are further than that.
"""

from __future__ import annotations

import bisect
import math
import threading
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from sarmission.geo.frames import (
    GIMBAL_FRAMES,
    euler_to_quaternion,
    gimbal_frame_from_flags,
    matrix_to_quaternion,
    quaternion_to_euler,
    quaternion_to_matrix,
    rot_z,
    slerp,
)
from sarmission.geo.geolocate import PlatformPose
from sarmission.geo.wgs84 import ned_to_geodetic

__all__ = ["MESSAGE_TYPES", "BootClock", "StaleTelemetry", "TelemetryBuffer"]

#: Message types :meth:`TelemetryBuffer.handle_message` uses (subscribe the link to these).
MESSAGE_TYPES = (
    "GLOBAL_POSITION_INT",
    "ATTITUDE",
    "ATTITUDE_QUATERNION",
    "GIMBAL_DEVICE_ATTITUDE_STATUS",
    "MOUNT_ORIENTATION",
    "HOME_POSITION",
    "GPS_RAW_INT",
    "SYSTEM_TIME",
)


@dataclass(frozen=True)
class StaleTelemetry:
    """Why there is no pose for time ``t`` (e.g. "no position for 3.2 s", "no attitude yet")."""

    t: float
    reason: str

    def __str__(self) -> str:
        return self.reason


class BootClock:
    """Maps autopilot boot time (s) to the local clock: ``local = boot + min(arrival - boot)``.

    The minimum runs over the last ``window_s`` seconds of arrivals (monotonic deque, O(1)
    amortised per observation), so slow drift between the clocks is followed and delayed
    messages never pull the estimate. ``transport_latency_s`` (known minimum delay) is
    subtracted. A boot time more than ``reboot_jump_s`` behind the previous one resets it.
    """

    def __init__(
        self, window_s: float = 30.0, transport_latency_s: float = 0.0, reboot_jump_s: float = 1.0
    ) -> None:
        self.window_s = window_s
        self.transport_latency_s = transport_latency_s
        self.reboot_jump_s = reboot_jump_s
        self._mins: deque[tuple[float, float]] = deque()  # (arrival, arrival - boot), increasing
        self._last_boot: float | None = None

    def observe(self, boot_s: float, arrival: float) -> float:
        """Record one message's ``(boot time, arrival time)``; return its local capture time."""
        if self._last_boot is not None and boot_s < self._last_boot - self.reboot_jump_s:
            self._mins.clear()
        self._last_boot = boot_s
        delay = arrival - boot_s
        while self._mins and self._mins[-1][1] >= delay:
            self._mins.pop()
        self._mins.append((arrival, delay))
        while self._mins[0][0] < arrival - self.window_s:
            self._mins.popleft()
        return self.to_local(boot_s)

    @property
    def offset(self) -> float | None:
        """Current estimate of ``local - boot`` (None before the first observation)."""
        if not self._mins:
            return None
        return self._mins[0][1] - self.transport_latency_s

    def to_local(self, boot_s: float) -> float:
        """Local time of boot time ``boot_s`` (needs one observation first)."""
        off = self.offset
        if off is None:
            raise RuntimeError("no clock observation yet")
        return boot_s + off


class _Series:
    """Time-sorted samples of one kind, trimmed to ``max_age_s`` behind the newest."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.times: list[float] = []
        self.values: list[Any] = []

    def insert(self, t: float, value: Any, max_age_s: float) -> None:
        i = bisect.bisect_left(self.times, t)
        if i < len(self.times) and abs(self.times[i] - t) < 1e-6:
            self.values[i] = value
        else:
            self.times.insert(i, t)
            self.values.insert(i, value)
        cut = bisect.bisect_left(self.times, self.times[-1] - max_age_s)
        if cut:
            del self.times[:cut], self.values[:cut]

    def bracket(self, t: float, stale_s: float) -> tuple[int, int, float] | StaleTelemetry:
        """``(i0, i1, s)`` with ``t = (1-s) t[i0] + s t[i1]`` (clamped ends), or why not."""
        if not self.times:
            return StaleTelemetry(t, f"no {self.name} yet")
        newest, oldest = self.times[-1], self.times[0]
        if t - newest > stale_s:
            return StaleTelemetry(t, f"no {self.name} for {t - newest:.1f} s")
        if oldest - t > stale_s:
            return StaleTelemetry(t, f"{self.name} starts {oldest - t:.1f} s after this time")
        i = bisect.bisect_right(self.times, t)
        if i == 0:
            return 0, 0, 0.0
        if i == len(self.times):
            return i - 1, i - 1, 0.0
        t0, t1 = self.times[i - 1], self.times[i]
        if min(t - t0, t1 - t) > stale_s:
            return StaleTelemetry(t, f"{self.name} gap of {t1 - t0:.1f} s around this time")
        return i - 1, i, (t - t0) / (t1 - t0)


@dataclass(frozen=True)
class _Position:
    lat: float
    lon: float
    rel_alt_m: float
    alt_m: float
    velocity_ned: tuple[float, float, float]


def _as_quaternion(q_or_rpy: Sequence[float] | np.ndarray) -> np.ndarray:
    v = np.asarray(q_or_rpy, dtype=float).reshape(-1)
    if v.size == 4:
        return v / np.linalg.norm(v)
    if v.size == 3:
        return euler_to_quaternion(*v)
    raise ValueError(f"expected a quaternion (w, x, y, z) or (roll, pitch, yaw), got {v.size}")


class TelemetryBuffer:
    """Thread-safe telemetry store with interpolation; produces :class:`PlatformPose`.

    Feed it with :meth:`handle_message` (as a :class:`~sarmission.mavlink.connection.MavlinkLink`
    subscriber) or the ``push_*`` methods (replay; times in the caller's clock). ``mount_rpy``
    (radians) in ``mount_frame`` is the camera mount used while no gimbal has reported.
    ``gnss_sigma_m``, ``alt_sigma_m`` and ``attitude_sigma_rad`` are the default 1-sigma
    accuracies copied into each pose (GPS_RAW_INT ``h_acc`` overrides the GNSS one).
    """

    def __init__(
        self,
        max_age_s: float = 30.0,
        stale_after_s: float = 1.0,
        mount_rpy: tuple[float, float, float] = (0.0, -math.pi / 2, 0.0),
        mount_frame: str = "body",
        gnss_sigma_m: float = 1.0,
        alt_sigma_m: float = 1.0,
        attitude_sigma_rad: float = math.radians(0.5),
        clock: BootClock | None = None,
    ) -> None:
        if mount_frame not in GIMBAL_FRAMES:
            raise ValueError(f"mount_frame must be one of {GIMBAL_FRAMES}, got {mount_frame!r}")
        if max_age_s <= 0 or stale_after_s <= 0:
            raise ValueError("max_age_s and stale_after_s must be positive")
        self.max_age_s = max_age_s
        self.stale_after_s = stale_after_s
        self.mount_rpy = mount_rpy
        self.mount_frame = mount_frame
        self.gnss_sigma_m = gnss_sigma_m
        self.alt_sigma_m = alt_sigma_m
        self.attitude_sigma_rad = attitude_sigma_rad
        self.clock = clock or BootClock()
        self._position = _Series("position")
        self._attitude = _Series("attitude")
        self._gimbal = _Series("gimbal attitude")
        self._home: tuple[float, float, float] | None = None
        self._lock = threading.Lock()

    # -- MAVLink input -------------------------------------------------------------------------
    def handle_message(self, msg: Any, arrival: float | None = None) -> None:
        """Take one pymavlink message (other types are ignored); ``arrival`` local time."""
        mtype = msg.get_type()
        if mtype not in MESSAGE_TYPES:
            return
        now = time.monotonic() if arrival is None else arrival
        if mtype == "HOME_POSITION":
            self.set_home(msg.latitude / 1e7, msg.longitude / 1e7, msg.altitude / 1000.0)
            return
        if mtype == "GPS_RAW_INT":
            h_acc = getattr(msg, "h_acc", 0)
            if h_acc:
                self.gnss_sigma_m = h_acc / 1000.0
            return
        with self._lock:
            t = self.clock.observe(msg.time_boot_ms / 1000.0, now)
        if mtype == "GLOBAL_POSITION_INT":
            if msg.lat == 0 and msg.lon == 0:
                return
            self.push_position(
                t,
                msg.lat / 1e7,
                msg.lon / 1e7,
                msg.relative_alt / 1000.0,
                alt_m=msg.alt / 1000.0,
                velocity_ned=(msg.vx / 100.0, msg.vy / 100.0, msg.vz / 100.0),
            )
        elif mtype == "ATTITUDE":
            self.push_attitude(t, msg.roll, msg.pitch, msg.yaw)
        elif mtype == "ATTITUDE_QUATERNION":
            self.push_attitude_quaternion(t, (msg.q1, msg.q2, msg.q3, msg.q4))
        elif mtype == "GIMBAL_DEVICE_ATTITUDE_STATUS":
            q = np.asarray(msg.q, dtype=float)
            if not np.all(np.isfinite(q)) or not np.any(q):
                return
            frame = gimbal_frame_from_flags(int(msg.flags))
            if frame == "vehicle" and math.isfinite(msg.delta_yaw):
                q = matrix_to_quaternion(rot_z(msg.delta_yaw) @ quaternion_to_matrix(q))
                frame = "earth"
            self.push_gimbal(t, q, frame)
        elif mtype == "MOUNT_ORIENTATION":
            roll, pitch = math.radians(msg.roll), math.radians(msg.pitch)
            if math.isfinite(msg.yaw_absolute):
                self.push_gimbal(t, (roll, pitch, math.radians(msg.yaw_absolute)), "earth")
            else:
                self.push_gimbal(t, (roll, pitch, math.radians(msg.yaw)), "vehicle")

    # -- direct input (replay, simulator) ------------------------------------------------------
    def push_position(
        self,
        t: float,
        lat: float,
        lon: float,
        rel_alt_m: float,
        alt_m: float = math.nan,
        velocity_ned: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> None:
        """Vehicle position at time ``t``: degrees, metres above home (and AMSL), m/s NED."""
        v = (float(velocity_ned[0]), float(velocity_ned[1]), float(velocity_ned[2]))
        sample = _Position(float(lat), float(lon), float(rel_alt_m), float(alt_m), v)
        with self._lock:
            self._position.insert(t, sample, self.max_age_s)

    def push_attitude(self, t: float, roll: float, pitch: float, yaw: float) -> None:
        """Vehicle attitude at ``t``: ZYX Euler radians (MAVLink ATTITUDE)."""
        self.push_attitude_quaternion(t, euler_to_quaternion(roll, pitch, yaw))

    def push_attitude_quaternion(self, t: float, q: Sequence[float] | np.ndarray) -> None:
        """Vehicle attitude at ``t`` as quaternion ``(w, x, y, z)`` of ``R_ned_body``."""
        with self._lock:
            self._attitude.insert(t, _as_quaternion(q), self.max_age_s)

    def push_gimbal(
        self, t: float, q_or_rpy: Sequence[float] | np.ndarray, frame: str = "vehicle"
    ) -> None:
        """Gimbal attitude at ``t``: quaternion ``(w, x, y, z)`` or ZYX ``(roll, pitch, yaw)``
        radians, in ``frame`` ("body", "vehicle" or "earth")."""
        if frame not in GIMBAL_FRAMES:
            raise ValueError(f"frame must be one of {GIMBAL_FRAMES}, got {frame!r}")
        with self._lock:
            self._gimbal.insert(t, (_as_quaternion(q_or_rpy), frame), self.max_age_s)

    def set_home(self, lat: float, lon: float, alt_m: float) -> None:
        """Home ``(lat, lon, alt AMSL)``: NED origin and default ground plane."""
        self._home = (float(lat), float(lon), float(alt_m))

    @property
    def home(self) -> tuple[float, float, float] | None:
        """Home from HOME_POSITION or :meth:`set_home`, None until known."""
        return self._home

    def newest_time(self, kind: str) -> float | None:
        """Local time of the newest "position", "attitude" or "gimbal" sample (None if none)."""
        series = {"position": self._position, "attitude": self._attitude, "gimbal": self._gimbal}
        with self._lock:
            times = series[kind].times
            return times[-1] if times else None

    # -- queries -------------------------------------------------------------------------------
    def pose_at(self, t: float) -> PlatformPose | None:
        """The pose at local time ``t``, or None (see :meth:`lookup` for the reason)."""
        result = self.lookup(t)
        return result if isinstance(result, PlatformPose) else None

    def lookup(self, t: float) -> PlatformPose | StaleTelemetry:
        """The interpolated pose at local time ``t`` or a :class:`StaleTelemetry` reason."""
        with self._lock:
            pos = self._interp_position(t)
            if isinstance(pos, StaleTelemetry):
                return pos
            att = self._interp_attitude(t)
            if isinstance(att, StaleTelemetry):
                return att
            gim = self._interp_gimbal(t)
            if isinstance(gim, StaleTelemetry):
                return gim
        roll, pitch, yaw = quaternion_to_euler(att)
        gimbal_rpy, frame = gim
        return PlatformPose(
            lat=pos.lat,
            lon=pos.lon,
            rel_alt_m=pos.rel_alt_m,
            roll=roll,
            pitch=pitch,
            yaw=yaw,
            gimbal_rpy=gimbal_rpy,
            gimbal_frame=frame,
            gnss_sigma_m=self.gnss_sigma_m,
            alt_sigma_m=self.alt_sigma_m,
            attitude_sigma_rad=self.attitude_sigma_rad,
            t=t,
        )

    def _interp_position(self, t: float) -> _Position | StaleTelemetry:
        br = self._position.bracket(t, self.stale_after_s)
        if isinstance(br, StaleTelemetry):
            return br
        i0, i1, s = br
        a, b = self._position.values[i0], self._position.values[i1]
        dt = t - self._position.times[i1]
        if i0 == i1 and dt > 0:  # past the newest sample: dead-reckon with its velocity
            vn, ve, vd = a.velocity_ned
            lat, lon, _ = ned_to_geodetic(vn * dt, ve * dt, 0.0, a.lat, a.lon, 0.0)
            return _Position(
                float(lat), float(lon), a.rel_alt_m - vd * dt, a.alt_m - vd * dt, a.velocity_ned
            )

        def lerp(x: float, y: float) -> float:
            return x + s * (y - x)

        return _Position(
            lerp(a.lat, b.lat),
            lerp(a.lon, b.lon),
            lerp(a.rel_alt_m, b.rel_alt_m),
            lerp(a.alt_m, b.alt_m),
            tuple(lerp(x, y) for x, y in zip(a.velocity_ned, b.velocity_ned, strict=True)),
        )

    def _interp_attitude(self, t: float) -> np.ndarray | StaleTelemetry:
        br = self._attitude.bracket(t, self.stale_after_s)
        if isinstance(br, StaleTelemetry):
            return br
        i0, i1, s = br
        return slerp(self._attitude.values[i0], self._attitude.values[i1], s)

    def _interp_gimbal(self, t: float) -> tuple[tuple[float, float, float], str] | StaleTelemetry:
        if not self._gimbal.times:
            return self.mount_rpy, self.mount_frame
        br = self._gimbal.bracket(t, self.stale_after_s)
        if isinstance(br, StaleTelemetry):
            return br
        i0, i1, s = br
        (q0, f0), (q1, f1) = self._gimbal.values[i0], self._gimbal.values[i1]
        if f0 != f1:  # reference frame changed between the two: take the nearer sample
            q, frame = (q0, f0) if s < 0.5 else (q1, f1)
        else:
            q, frame = slerp(q0, q1, s), f0
        r, p, y = quaternion_to_euler(q)
        return (r, p, y), frame
