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
  One gimbal is used: the one pinned (``gimbal_pin``: component and/or ``gimbal_device_id``),
  else the first heard, as (system, component, ``gimbal_device_id``; MOUNT_ORIENTATION counts
  as device 0). Another one's attitude is rejected (counted, warned about at most every
  :data:`WARN_INTERVAL_S`): two attitudes mixed into one camera would alternate frame by frame.
  The one in use falling silent makes the pose stale; nothing switches to another.
- HOME_POSITION: home ``(lat, lon, alt)``, the ground plane for geolocation. With
  ``require_home`` (the default) there is no pose until the autopilot has reported it.
- HEARTBEAT: the armed state and flight mode (:mod:`~sarmission.mavlink.flight_mode`);
  :meth:`TelemetryBuffer.takeover_refusal` says whether the vehicle may be sent elsewhere.
- GPS_RAW_INT: ``fix_type`` (with ``require_gps_fix``, the default, GLOBAL_POSITION_INT is
  believed only while the newest GPS_RAW_INT, at most :data:`GPS_FIX_MAX_AGE_S` old, reports a
  3D fix) and ``h_acc`` (mm, when non-zero) as the 1-sigma GNSS error per horizontal axis.

Every message is checked first (:mod:`~sarmission.mavlink.telemetry_checks`: finite, in range,
unit quaternions); GLOBAL_POSITION_INT must also not jump faster than an aircraft flies: a
position further from its nearest believed neighbour than :data:`MAX_SPEED_MPS` times the time
between them (at least 0.1 s) plus :data:`JUMP_SLACK_M` is rejected, however long the gap. A
jump that persists (the rejected positions agree with one another for :data:`JUMP_CONFIRM_S`:
the autopilot's EKF or GNSS moved its position and keeps it there) is believed with one
warning, and the positions before it are dropped (no interpolation across it); an autopilot
reboot (its clock restarts) drops them too. A
rejected message is counted in :attr:`TelemetryBuffer.rejected` by reason and warned about at
most once per :data:`WARN_INTERVAL_S` per reason; it never raises.

Clock: samples carry the sender's ``time_boot_ms``, one :class:`BootClock` per sender (system,
component). With ``latency = arrival - capture`` and ``offset = local - boot``,
``arrival - boot = offset + latency >= offset``; the offset is estimated as the minimum of
``arrival - boot`` over a sliding window (the least-delayed message), so a sample's local time
is ``boot + min(arrival - boot) - transport_latency_s``. A sample off that timeline (boot time
back by more than a second, or a capture time after its own arrival) is rejected; only when a
new timeline holds for a while and the old one has gone quiet (an autopilot reboot) does the
clock start afresh, and every sample that sender gave is dropped with it. The local clock is
``time.monotonic()`` unless arrival times are given.

Interpolation: position linearly (lat, lon, altitudes), beyond the newest sample extrapolated
with the reported velocity; attitudes by slerp, held beyond the ends. A pose is refused (a
:class:`StaleTelemetry` reason) when the requested time is more than ``stale_after_s`` past the
newest sample, before the oldest, or inside a gap where both neighbours are further than that.
"""

from __future__ import annotations

import bisect
import logging
import math
import re
import threading
import time
from collections import Counter, deque
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
from sarmission.geo.wgs84 import geodetic_to_ned, ned_to_geodetic
from sarmission.mavlink.flight_mode import FlightState, takeover_refusal
from sarmission.mavlink.telemetry_checks import GPS_FIX_3D, MAX_SPEED_MPS, message_problem
from sarmission.ratelimit import RateLimitedLog

log = logging.getLogger(__name__)

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
    "HEARTBEAT",
)

_AUTOPILOT_TYPES = frozenset(("GLOBAL_POSITION_INT", "ATTITUDE", "ATTITUDE_QUATERNION"))
#: A GPS_RAW_INT older than this says nothing about the current fix (seconds).
GPS_FIX_MAX_AGE_S = 5.0
#: A position jump is believed once the rejected positions agree for this long (seconds).
JUMP_CONFIRM_S = 10.0
#: Jump allowance on top of the fastest speed: GNSS noise and EKF resets (metres).
JUMP_SLACK_M = 10.0
#: Least seconds between two warnings of the same rejection reason.
WARN_INTERVAL_S = 5.0
#: A satellite fix's vertical error is about this many times its horizontal one (the
#: satellites are all above): the height a fix rests on is taken as no better than that.
VERTICAL_PER_HORIZONTAL = 1.5
#: The smallest height sigma of the mission's buffer (metres): a barometer drifts about this
#: much, whatever the satellites say.
MIN_HEIGHT_SIGMA_M = 1.0
#: The smallest horizontal GNSS sigma a fix takes, whatever GPS_RAW_INT claims (metres): the
#: pixel, the lens calibration and the timing are never exact, so centimetres of RTK (or a
#: sender's 1 mm) must not make a fix's error bar that tight.
MIN_GNSS_SIGMA_M = 0.1
_NUMBER = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?(?:e[-+]?\d+)?(?![\w.])")


@dataclass(frozen=True)
class StaleTelemetry:
    """Why there is no pose for time ``t`` (e.g. "no position for 3.2 s", "no attitude yet")."""

    t: float
    reason: str

    def __str__(self) -> str:
        return self.reason


class BootClock:
    """Maps a sender's boot time (s) to the local clock: ``local = boot + min(arrival - boot)``.

    The minimum runs over the last ``window_s`` seconds of arrivals (monotonic deque, O(1)
    amortised per observation), so slow drift between the clocks is followed and delayed
    messages never pull the estimate. ``transport_latency_s`` (known minimum delay) is
    subtracted. A sample off the current timeline (boot time more than ``reboot_jump_s`` behind
    the newest, a capture more than ``future_tolerance_s`` after its arrival, or a delay more
    than ``late_tolerance_s`` beyond the least one: useless if late, a new timeline if not;
    an autopilot rebooted a second after its boot looks like that) is rejected
    (:meth:`observe` returns None); once such samples agree on a new timeline for
    ``confirm_s`` while the old one is silent, the clock restarts on it (``reboots`` counts it).
    """

    def __init__(
        self,
        window_s: float = 30.0,
        transport_latency_s: float = 0.0,
        reboot_jump_s: float = 1.0,
        future_tolerance_s: float = 1.0,
        confirm_s: float = 1.0,
        late_tolerance_s: float = 3.0,
    ) -> None:
        self.window_s = window_s
        self.transport_latency_s = transport_latency_s
        self.reboot_jump_s = reboot_jump_s
        self.future_tolerance_s = future_tolerance_s
        self.confirm_s = confirm_s
        self.late_tolerance_s = late_tolerance_s
        self.reboots = 0
        self.rejected = 0
        self._mins: deque[tuple[float, float]] = deque()  # (arrival, arrival - boot), increasing
        self._last_boot: float | None = None
        self._last_on_timeline: float = -math.inf  # arrival of the newest accepted sample
        self._candidate: tuple[float, float, int] | None = None  # (delay, first arrival, count)

    def observe(self, boot_s: float, arrival: float) -> float | None:
        """Record one message's ``(boot time, arrival time)``; return its local capture time,
        or None when it is off the current timeline (rejected)."""
        delay = arrival - boot_s
        if not self._on_timeline(boot_s, delay):
            if not self._confirms_new_timeline(delay, arrival):
                self.rejected += 1
                return None
            self._mins.clear()
            self._last_boot = None
            self.reboots += 1
        self._candidate = None
        self._last_boot = boot_s if self._last_boot is None else max(self._last_boot, boot_s)
        self._last_on_timeline = arrival
        while self._mins and self._mins[-1][1] >= delay:
            self._mins.pop()
        self._mins.append((arrival, delay))
        while self._mins[0][0] < arrival - self.window_s:
            self._mins.popleft()
        return self.to_local(boot_s)

    def _on_timeline(self, boot_s: float, delay: float) -> bool:
        if self._last_boot is None or not self._mins:
            return True
        if boot_s < self._last_boot - self.reboot_jump_s:
            return False  # back in time: a reboot, or a forged sample
        least = self._mins[0][1]
        return least - self.future_tolerance_s <= delay <= least + self.late_tolerance_s

    def _confirms_new_timeline(self, delay: float, arrival: float) -> bool:
        cand = self._candidate
        if cand is None or abs(delay - cand[0]) > self.future_tolerance_s:  # another new one
            self._candidate = (delay, arrival, 1)
            return False
        self._candidate = (cand[0], cand[1], cand[2] + 1)
        return (
            cand[2] + 1 >= 3
            and arrival - cand[1] >= self.confirm_s
            and arrival - self._last_on_timeline >= self.confirm_s
        )

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

    def clear(self) -> None:
        self.times.clear()
        self.values.clear()

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
class _JumpChain:
    """Positions rejected as a jump that agree with one another: the first one's time, the
    newest one's, and where the newest is."""

    first_t: float
    last_t: float
    lat: float
    lon: float
    count: int = 1


def _reach_m(dt: float) -> float:
    """How far an aircraft may be from where it was ``dt`` seconds before (metres)."""
    return MAX_SPEED_MPS * max(abs(dt), 0.1) + JUMP_SLACK_M


def _distance_m(lat: float, lon: float, lat0: float, lon0: float) -> float:
    n, e, _ = geodetic_to_ned(lat, lon, 0.0, lat0, lon0, 0.0)
    return math.hypot(float(n), float(e))


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


def _gimbal_text(key: GimbalKey) -> str:
    """A gimbal in words: "1/154 device 0"."""
    return f"{key[0]}/{key[1]} device {key[2]}"


def height_sigma_m(gnss_sigma_m: float, floor_m: float = MIN_HEIGHT_SIGMA_M) -> float:
    """The 1-sigma error of the height a fix rests on: at least :data:`VERTICAL_PER_HORIZONTAL`
    times the horizontal GNSS error, and at least ``floor_m``."""
    return max(floor_m, VERTICAL_PER_HORIZONTAL * gnss_sigma_m)


#: A gimbal: (system, component, gimbal_device_id).
GimbalKey = tuple[int, int, int]


class TelemetryBuffer:
    """Thread-safe telemetry store with interpolation; produces :class:`PlatformPose`.

    Feed it with :meth:`handle_message` (as a :class:`~sarmission.mavlink.connection.MavlinkLink`
    subscriber) or the ``push_*`` methods (replay; times in the caller's clock). ``mount_rpy``
    (radians) in ``mount_frame`` is the camera mount used while no gimbal has reported.
    ``gnss_sigma_m``, ``alt_sigma_m`` and ``attitude_sigma_rad`` are the default 1-sigma
    accuracies copied into each pose. GPS_RAW_INT ``h_acc`` overrides the GNSS one (at least
    :data:`MIN_GNSS_SIGMA_M`) and sets
    the height's to at least :data:`VERTICAL_PER_HORIZONTAL` times it (``alt_sigma_m`` stays
    its floor: a barometer drifts too).
    ``require_home``: no pose until a home is known (HOME_POSITION or :meth:`set_home`);
    ``require_gps_fix``: GLOBAL_POSITION_INT only while GPS_RAW_INT reports a 3D fix.
    ``gimbal_pin``: (component, gimbal_device_id) of the gimbal to use, either None for any;
    (None, None): the first gimbal heard.
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
        require_home: bool = True,
        require_gps_fix: bool = True,
        gimbal_pin: tuple[int | None, int | None] = (None, None),
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
        self._alt_sigma_floor_m = alt_sigma_m
        self.attitude_sigma_rad = attitude_sigma_rad
        self.clock = clock or BootClock()
        self.require_home = require_home
        self.require_gps_fix = require_gps_fix
        #: Messages not believed, by reason (e.g. "GLOBAL_POSITION_INT: lat 214.7 out of range").
        self.rejected: Counter[str] = Counter()
        self.resets = 0
        self._warn = RateLimitedLog(log, WARN_INTERVAL_S)
        self._clocks: dict[tuple[int, int], BootClock] = {}
        self._autopilot_source: tuple[int, int] | None = None
        self._series_source: dict[str, tuple[int, int]] = {}
        self._gps: tuple[float, int] | None = None  # (arrival, fix_type) of the newest GPS_RAW_INT
        self._flight: FlightState | None = None  # the newest HEARTBEAT's armed state and mode
        self._jump: _JumpChain | None = None  # positions rejected as a jump, while they agree
        self.gimbal_pin = gimbal_pin
        self._gimbal_key: GimbalKey | None = None  # the gimbal in use
        self._valid_from = -math.inf  # no pose before this time (the last autopilot switch)
        self._position = _Series("position")
        self._attitude = _Series("attitude")
        self._gimbal = _Series("gimbal attitude")
        self._home: tuple[float, float, float] | None = None
        self._lock = threading.Lock()

    # -- MAVLink input -------------------------------------------------------------------------
    def handle_message(self, msg: Any, arrival: float | None = None) -> None:
        """Take one pymavlink message (other types are ignored); ``arrival`` local time.

        The caller decides whom to believe (the adopted autopilot only); this checks what the
        message says. Never raises on bad content: it is counted and warned about instead."""
        mtype = msg.get_type()
        if mtype not in MESSAGE_TYPES:
            return
        now = time.monotonic() if arrival is None else arrival
        problem = message_problem(msg)
        if problem:
            self._reject(mtype, problem)
            return
        source = (int(msg.get_srcSystem()), int(msg.get_srcComponent()))
        if mtype == "HOME_POSITION":
            self._take_home(msg)
        elif mtype == "GPS_RAW_INT":
            self._take_gps(msg, now)
        elif mtype == "HEARTBEAT":
            self._take_heartbeat(msg, now)
        elif mtype in ("GIMBAL_DEVICE_ATTITUDE_STATUS", "MOUNT_ORIENTATION") and (
            not self._gimbal_in_use(mtype, msg, source)
        ):
            return
        elif mtype != "SYSTEM_TIME":
            t = self._sender_time(source, mtype, msg, now)
            if t is None:
                self._reject(mtype, "time_boot_ms off the sender's timeline")
            else:
                self._take_timed(mtype, msg, t, now, source)

    def _gimbal_in_use(self, mtype: str, msg: Any, source: tuple[int, int]) -> bool:
        """Whether a gimbal attitude comes from the gimbal in use (the pinned one, else the
        first heard, adopted here); another one's is rejected."""
        device = int(getattr(msg, "gimbal_device_id", 0) or 0)
        key = (source[0], source[1], device)
        pin_component, pin_device = self.gimbal_pin
        if (pin_component is not None and key[1] != pin_component) or (
            pin_device is not None and key[2] != pin_device
        ):
            self._reject(mtype, f"gimbal {_gimbal_text(key)} is not the configured one")
            return False
        if self._gimbal_key is None:
            self._gimbal_key = key
            log.info("gimbal %s in use for the camera's attitude", _gimbal_text(key))
            return True
        if key != self._gimbal_key:
            self._reject(
                mtype,
                f"a second gimbal {_gimbal_text(key)}; using {_gimbal_text(self._gimbal_key)} "
                "(pin one with [camera] gimbal_component / gimbal_device_id)",
            )
            return False
        return True

    def _take_gps(self, msg: Any, now: float) -> None:
        """GPS_RAW_INT: the fix type (no position is believed without a fix) and its accuracy."""
        self._gps = (now, int(msg.fix_type))
        h_acc = getattr(msg, "h_acc", 0)
        if 0 < h_acc < 0xFFFFFFFF:
            self.gnss_sigma_m = max(h_acc / 1000.0, MIN_GNSS_SIGMA_M)
            self.alt_sigma_m = height_sigma_m(self.gnss_sigma_m, self._alt_sigma_floor_m)

    def _take_heartbeat(self, msg: Any, now: float) -> None:
        """HEARTBEAT: the armed state and flight mode; a change is logged once."""
        state = FlightState.from_heartbeat(msg, now)
        old = self._flight
        if old is None or (old.armed, old.mode) != (state.armed, state.mode):
            log.info("autopilot %s, mode %s", "armed" if state.armed else "disarmed", state.mode)
        self._flight = state

    @property
    def flight_state(self) -> FlightState | None:
        """The newest HEARTBEAT's armed state and flight mode (None before one)."""
        return self._flight

    def takeover_refusal(self, now: float | None = None) -> str:
        """Why the vehicle may not be sent anywhere now ("" when it may): disarmed, a mode
        not known to be safe to take over (RTL, LAND...), or no current HEARTBEAT."""
        return takeover_refusal(self._flight, time.monotonic() if now is None else now)

    def _sender_time(
        self, source: tuple[int, int], mtype: str, msg: Any, now: float
    ) -> float | None:
        """The message's time on the local clock from the sender's boot clock (None when off
        its timeline); a sender whose clock restarted has its samples forgotten."""
        with self._lock:
            clock = self._clock_for(source, mtype)
            reboots = clock.reboots
            t = clock.observe(msg.time_boot_ms / 1000.0, now)
            if clock.reboots != reboots:
                self._forget_source(source, "its clock restarted (reboot)")
        return t

    def _take_timed(
        self, mtype: str, msg: Any, t: float, now: float, source: tuple[int, int]
    ) -> None:
        """A position, attitude or gimbal message at local time ``t``."""
        if mtype == "GLOBAL_POSITION_INT":
            self._take_position(msg, t, now)
        elif mtype == "ATTITUDE":
            self._series_source["attitude"] = source
            self.push_attitude(t, msg.roll, msg.pitch, msg.yaw)
        elif mtype == "ATTITUDE_QUATERNION":
            self._series_source["attitude"] = source
            self.push_attitude_quaternion(t, (msg.q1, msg.q2, msg.q3, msg.q4))
        elif mtype == "GIMBAL_DEVICE_ATTITUDE_STATUS":
            self._take_gimbal_status(msg, t, source)
        elif mtype == "MOUNT_ORIENTATION":
            self._take_mount(msg, t, source)

    def _take_gimbal_status(self, msg: Any, t: float, source: tuple[int, int]) -> None:
        """GIMBAL_DEVICE_ATTITUDE_STATUS; a vehicle-frame attitude with its delta_yaw is turned
        into the earth frame."""
        q = np.asarray(msg.q, dtype=float)
        frame = gimbal_frame_from_flags(int(msg.flags))
        if frame == "vehicle" and math.isfinite(msg.delta_yaw):
            q = matrix_to_quaternion(rot_z(msg.delta_yaw) @ quaternion_to_matrix(q))
            frame = "earth"
        self._series_source["gimbal"] = source
        self.push_gimbal(t, q, frame)

    def _take_mount(self, msg: Any, t: float, source: tuple[int, int]) -> None:
        """MOUNT_ORIENTATION: yaw from north when it is given, else relative to the vehicle."""
        roll, pitch = math.radians(msg.roll), math.radians(msg.pitch)
        self._series_source["gimbal"] = source
        if math.isfinite(msg.yaw_absolute):
            self.push_gimbal(t, (roll, pitch, math.radians(msg.yaw_absolute)), "earth")
        else:
            self.push_gimbal(t, (roll, pitch, math.radians(msg.yaw)), "vehicle")

    def _reject(self, mtype: str, reason: str) -> None:
        """Count a rejected message under its reason with the numbers left out (so a sender
        varying them cannot grow the counter or dodge the warning limit); warn with them."""
        key = f"{mtype}: {_NUMBER.sub('N', reason)}"
        with self._lock:
            self.rejected[key] += 1
        self._warn.event(key, "telemetry rejected: %s: %s", mtype, reason)

    def _clock_for(self, source: tuple[int, int], mtype: str) -> BootClock:
        clock = self._clocks.get(source)
        if clock is None:
            if self._autopilot_source is None and mtype in _AUTOPILOT_TYPES:
                self._autopilot_source = source
                clock = self.clock
            else:
                clock = BootClock(transport_latency_s=self.clock.transport_latency_s)
            self._clocks[source] = clock
        return clock

    def _forget_source(self, source: tuple[int, int], why: str) -> None:
        """Drop every sample ``source`` gave (its clock restarted); called under the lock."""
        dropped = []
        for name, series in (
            ("position", self._position),
            ("attitude", self._attitude),
            ("gimbal", self._gimbal),
        ):
            if self._series_source.get(name) == source and series.times:
                series.clear()
                dropped.append(name)
                if name == "position":
                    self._jump = None
        if source == self._autopilot_source:
            self._home = None
            self._gps = None
            dropped.append("home")
        self.resets += 1
        log.warning(
            "telemetry from %d/%d dropped (%s): %s",
            *source,
            why,
            ", ".join(dropped) or "nothing buffered",
        )

    def _take_home(self, msg: Any) -> None:
        lat, lon, alt = msg.latitude / 1e7, msg.longitude / 1e7, msg.altitude / 1000.0
        old = self._home
        if (
            old is None
            or abs(old[0] - lat) > 1e-6
            or abs(old[1] - lon) > 1e-6
            or abs(old[2] - alt) > 0.5
        ):
            log.info(
                "autopilot home %.7f, %.7f, %.1f m AMSL%s",
                lat,
                lon,
                alt,
                "" if old is None else " (changed)",
            )
        self.set_home(lat, lon, alt)

    def _take_position(self, msg: Any, t: float, arrival: float) -> None:
        if msg.lat == 0 and msg.lon == 0:
            self._reject("GLOBAL_POSITION_INT", "no position yet (0, 0)")
            return
        if self.require_gps_fix:
            gps = self._gps
            if gps is None:
                self._reject("GLOBAL_POSITION_INT", "no GPS_RAW_INT heard: GPS fix unknown")
                return
            if arrival - gps[0] > GPS_FIX_MAX_AGE_S:
                self._reject(
                    "GLOBAL_POSITION_INT",
                    f"GPS_RAW_INT older than {GPS_FIX_MAX_AGE_S:g} s: GPS fix unknown",
                )
                return
            if gps[1] < GPS_FIX_3D:
                self._reject("GLOBAL_POSITION_INT", f"no 3D GPS fix (fix type {gps[1]})")
                return
        lat, lon = msg.lat / 1e7, msg.lon / 1e7
        jump = self._position_jump(t, lat, lon)
        if jump and not self._jump_persists(t, lat, lon):
            self._reject("GLOBAL_POSITION_INT", jump)
            return
        self._series_source["position"] = (int(msg.get_srcSystem()), int(msg.get_srcComponent()))
        self.push_position(
            t,
            lat,
            lon,
            msg.relative_alt / 1000.0,
            alt_m=msg.alt / 1000.0,
            velocity_ned=(msg.vx / 100.0, msg.vy / 100.0, msg.vz / 100.0),
        )

    def _position_jump(self, t: float, lat: float, lon: float) -> str:
        """Why a position at ``t`` is implausible next to its nearest buffered neighbour: the
        allowance grows with the time between them, there is no time beyond which anything
        goes. One that fits the jump in progress better than the believed track joins the
        jump; a plausible one ends it (the glitch is over)."""
        with self._lock:
            times = self._position.times
            if not times:
                self._jump = None
                return ""
            i = bisect.bisect_left(times, t)
            nearest = min(
                (k for k in (i - 1, i) if 0 <= k < len(times)), key=lambda k: abs(times[k] - t)
            )
            near_t, near = times[nearest], self._position.values[nearest]
        dt = abs(t - near_t)
        distance = _distance_m(lat, lon, near.lat, near.lon)
        if distance > MAX_SPEED_MPS * max(dt, 0.1) + JUMP_SLACK_M:
            return f"position jump of {distance:.0f} m in {dt:.2f} s"
        chain_fit = self._jump_fit(t, lat, lon)
        if chain_fit <= 1.0 and chain_fit < distance / _reach_m(dt):
            return f"position agrees with a jump of {distance:.0f} m not yet believed"
        self._jump = None
        return ""

    def _jump_fit(self, t: float, lat: float, lon: float) -> float:
        """Distance of a position at ``t`` from the newest of the jump in progress, as a
        fraction of an aircraft's reach since then (<= 1: it continues the jump; inf: none)."""
        chain = self._jump
        if chain is None:
            return math.inf
        return _distance_m(lat, lon, chain.lat, chain.lon) / _reach_m(t - chain.last_t)

    def _jump_continues(self, t: float, lat: float, lon: float) -> bool:
        """Whether a position at ``t`` is reachable from the newest of the jump in progress."""
        return self._jump_fit(t, lat, lon) <= 1.0

    def _jump_persists(self, t: float, lat: float, lon: float) -> bool:
        """A rejected position joins the jump in progress (or starts one); True once the jump
        has held for :data:`JUMP_CONFIRM_S`: then it is believed (one warning) and the
        positions from before it are dropped."""
        chain = self._jump
        if chain is None or not self._jump_continues(t, lat, lon):
            self._jump = _JumpChain(t, t, lat, lon)
            return False
        chain = _JumpChain(chain.first_t, max(chain.last_t, t), lat, lon, chain.count + 1)
        if chain.last_t - chain.first_t < JUMP_CONFIRM_S:
            self._jump = chain
            return False
        newest = self.latest_position()
        moved = _distance_m(lat, lon, *newest) if newest is not None else math.nan
        with self._lock:
            self._position.clear()
            self._jump = None
            self.resets += 1
        log.warning(
            "position jumped %.0f m and stayed there for %.0f s (%d positions): believed as the "
            "autopilot's new position (an EKF or GNSS reset); earlier positions dropped",
            moved,
            chain.last_t - chain.first_t,
            chain.count,
        )
        return True

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

    def latest_position(self) -> tuple[float, float] | None:
        """The newest buffered ``(lat, lon)`` of the vehicle, None when there is none."""
        with self._lock:
            if not self._position.values:
                return None
            newest = self._position.values[-1]
            return newest.lat, newest.lon

    @property
    def gimbal_reported(self) -> bool:
        """Whether a gimbal attitude is buffered (a gimbal or mount is reporting)."""
        with self._lock:
            return bool(self._gimbal.times)

    def reset(self, why: str, at: float | None = None) -> None:
        """Forget every sample, the home and the clocks (e.g. another autopilot was adopted),
        and refuse poses for times before ``at`` (default now): a frame taken before the switch
        is never placed with the new autopilot's telemetry."""
        with self._lock:
            self._valid_from = time.monotonic() if at is None else at
            for series in (self._position, self._attitude, self._gimbal):
                series.clear()
            self._home = None
            self._gps = None
            self._flight = None
            self._jump = None
            self._gimbal_key = None
            self._clocks.clear()
            self._autopilot_source = None
            self._series_source.clear()
            self.clock = BootClock(
                window_s=self.clock.window_s, transport_latency_s=self.clock.transport_latency_s
            )
            self.resets += 1
        log.warning("telemetry buffer cleared: %s", why)

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
        if not math.isfinite(t):
            return StaleTelemetry(t, "frame time not finite")
        with self._lock:
            if t < self._valid_from:
                return StaleTelemetry(t, "taken before the autopilot was replaced")
            if self.require_home and self._home is None:
                return StaleTelemetry(t, "no home position from the autopilot yet")
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
