"""Telemetry as an autopilot would report it: sampled, noisy, late; plus the exact truth.

Each message kind is sampled at capture times ``k / rate`` and becomes available to a reader
``latency_s`` later (``t_available``); its timestamp (``time_boot_ms``) is the capture time.
Noise is deterministic from the seed and indexed by capture time on a 100 Hz grid, so the same
sample is identical whatever order or rate it is asked in:

- GNSS position: first-order Gauss-Markov per axis, ``x_{k+1} = phi x_k + sqrt(1 - phi^2) sigma e``,
  ``phi = exp(-dt / tau)``, stationary std ``gnss_noise_m`` horizontally (1.5x vertically);
  velocity white noise ``0.1 * gnss_noise_m`` m/s per axis.
- Vehicle and gimbal attitude: white noise, std ``attitude_noise_deg`` per Euler angle.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sarmission.geo.camera import CameraPose
from sarmission.mission.config import MissionConfig
from sim.flight import VehicleState
from sim.flight_model import FlightModel
from sim.truth_frames import ned_to_geodetic, zyx_angles, zyx_quaternion, zyx_rotation

#: How the gimbal reports its attitude: yaw relative to the vehicle's heading (with the heading
#: as ``delta_yaw``, as ArduPilot's mounts do) or relative to north.
GIMBAL_REPORTS = ("vehicle", "earth")
_LOCKS = mavlink2.GIMBAL_DEVICE_FLAGS_ROLL_LOCK | mavlink2.GIMBAL_DEVICE_FLAGS_PITCH_LOCK
_GIMBAL_FLAGS = {
    "vehicle": _LOCKS | mavlink2.GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME,
    "earth": _LOCKS
    | mavlink2.GIMBAL_DEVICE_FLAGS_YAW_LOCK
    | mavlink2.GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME,
}

NOISE_RATE_HZ = 100.0
_BLOCK = 4096

#: Default rates (Hz) of an autopilot streaming to a companion computer.
DEFAULT_RATES_HZ = {"position": 10.0, "attitude": 20.0, "gimbal": 5.0}


@dataclass(frozen=True)
class PositionSample:
    """GLOBAL_POSITION_INT content. ``alt_m`` AMSL, ``relative_alt_m`` above home, velocity NED."""

    t: float
    t_available: float
    lat_deg: float
    lon_deg: float
    alt_m: float
    relative_alt_m: float
    velocity_ned: tuple[float, float, float]
    heading_deg: float
    position_ned: tuple[float, float, float]


@dataclass(frozen=True)
class AttitudeSample:
    """ATTITUDE content: ZYX Euler (rad) and body angular rates (rad/s)."""

    t: float
    t_available: float
    roll: float
    pitch: float
    yaw: float
    rollspeed: float
    pitchspeed: float
    yawspeed: float


@dataclass(frozen=True)
class GimbalSample:
    """GIMBAL_DEVICE_ATTITUDE_STATUS content.

    ``q`` is ``(w, x, y, z)`` of the gimbal attitude in ``frame`` ("vehicle": roll/pitch relative
    to the horizon, yaw relative to the vehicle heading; flags ROLL_LOCK | PITCH_LOCK |
    YAW_IN_VEHICLE_FRAME; "earth": yaw relative to north, flags ROLL_LOCK | PITCH_LOCK |
    YAW_LOCK | YAW_IN_EARTH_FRAME). ``delta_yaw`` is the vehicle yaw (rad) relating the vehicle
    frame to the earth frame: ``q_earth = q(delta_yaw about z) * q``.
    """

    t: float
    t_available: float
    q: tuple[float, float, float, float]
    flags: int
    frame: str
    delta_yaw: float
    roll: float
    pitch: float
    yaw: float


class _NoiseStream:
    """Lazily generated noise on the 100 Hz grid, extended in fixed blocks (deterministic)."""

    def __init__(self, seed: int, stream: int, dims: int, sigma: np.ndarray, tau_s: float | None):
        self._rng = np.random.default_rng([seed, stream])
        self._dims = dims
        self._sigma = sigma
        self._phi = 0.0 if tau_s is None else math.exp(-1.0 / (NOISE_RATE_HZ * tau_s))
        self._data = np.zeros((0, dims))
        self._state: np.ndarray | None = None
        self._lock = threading.Lock()

    def _extend(self) -> None:
        e = self._rng.standard_normal((_BLOCK, self._dims))
        if self._phi == 0.0:
            block = e * self._sigma
        else:
            block = np.empty_like(e)
            x = e[0] * self._sigma if self._state is None else self._state
            if self._state is not None:
                x = self._phi * x + math.sqrt(1 - self._phi**2) * self._sigma * e[0]
            block[0] = x
            for i in range(1, _BLOCK):
                x = self._phi * x + math.sqrt(1 - self._phi**2) * self._sigma * e[i]
                block[i] = x
            self._state = x
        self._data = np.concatenate([self._data, block])

    def at(self, t: float) -> np.ndarray:
        k = max(0, int(round(t * NOISE_RATE_HZ)))
        with self._lock:
            while k >= len(self._data):
                self._extend()
            return self._data[k].copy()


class TelemetryModel:
    """Noisy, delayed telemetry of a flight (:class:`~sim.flight_model.FlightModel`) plus exact
    truth for rendering."""

    def __init__(
        self,
        flight: FlightModel,
        mission: MissionConfig | None = None,
        seed: int = 0,
        rates_hz: dict[str, float] | None = None,
        gimbal_report: str = "vehicle",
    ) -> None:
        if gimbal_report not in GIMBAL_REPORTS:
            raise ValueError(
                f"gimbal_report must be one of {GIMBAL_REPORTS}, got {gimbal_report!r}"
            )
        self.gimbal_report = gimbal_report
        self.flight = flight
        self.mission = mission or flight.mission
        self.seed = seed
        self.rates_hz = dict(DEFAULT_RATES_HZ)
        if rates_hz:
            self.rates_hz.update(rates_hz)
        tc = self.mission.telemetry
        self.latency_s = tc.latency_s
        g = tc.gnss_noise_m
        att = math.radians(tc.attitude_noise_deg)
        self._gnss = _NoiseStream(seed, 1, 3, np.array([g, g, 1.5 * g]), tc.gnss_noise_tau_s)
        self._vel = _NoiseStream(seed, 2, 3, np.full(3, 0.1 * g), None)
        self._att = _NoiseStream(seed, 3, 3, np.full(3, att), None)
        self._gim = _NoiseStream(seed, 4, 3, np.full(3, att), None)
        self.home = self.mission.area.home

    # -- truth ---------------------------------------------------------------------------------
    def truth(self, t: float) -> VehicleState:
        """Exact vehicle state at capture time ``t`` (for the renderer and ground truth)."""
        return self.flight.state_at(t)

    def camera_pose(self, t: float) -> CameraPose:
        """Exact camera pose at a frame's capture time ``t``."""
        return self.flight.camera_pose_at(t)

    # -- measured samples ------------------------------------------------------------------------
    def position(self, t: float) -> PositionSample:
        """GLOBAL_POSITION_INT measured at capture time ``t``."""
        s = self.flight.state_at(t)
        p = s.position_ned + self._gnss.at(t)
        v = s.velocity_ned + self._vel.at(t)
        lat, lon, h = ned_to_geodetic(p[0], p[1], p[2], *self.home)
        return PositionSample(
            t=t,
            t_available=t + self.latency_s,
            lat_deg=float(lat),
            lon_deg=float(lon),
            alt_m=float(h),
            relative_alt_m=float(-p[2]),
            velocity_ned=(float(v[0]), float(v[1]), float(v[2])),
            heading_deg=math.degrees(s.yaw) % 360.0,
            position_ned=(float(p[0]), float(p[1]), float(p[2])),
        )

    def attitude(self, t: float, rate_dt: float = 0.02) -> AttitudeSample:
        """ATTITUDE measured at ``t``; body rates from the exact attitude ``t +- rate_dt / 2``.

        ``omega_body = vee(log(R(t-)^T R(t+))) / rate_dt``.
        """
        s = self.flight.state_at(t)
        n = self._att.at(t)
        r0 = zyx_rotation(*self.flight.state_at(t - rate_dt / 2).vehicle_rpy)
        r1 = zyx_rotation(*self.flight.state_at(t + rate_dt / 2).vehicle_rpy)
        w = _log_so3(r0.T @ r1) / rate_dt if t >= rate_dt / 2 else np.zeros(3)
        yaw = (s.yaw + n[2] + math.pi) % (2 * math.pi) - math.pi
        return AttitudeSample(
            t=t,
            t_available=t + self.latency_s,
            roll=s.roll + float(n[0]),
            pitch=s.pitch + float(n[1]),
            yaw=yaw,
            rollspeed=float(w[0]),
            pitchspeed=float(w[1]),
            yawspeed=float(w[2]),
        )

    def gimbal(self, t: float) -> GimbalSample | None:
        """GIMBAL_DEVICE_ATTITUDE_STATUS measured at ``t``; None without a gimbal (hard mount)."""
        s = self.flight.state_at(t)
        if s.gimbal_frame != "vehicle":
            return None
        n = self._gim.at(t)
        rotation = zyx_rotation(s.gimbal_roll + n[0], s.gimbal_pitch + n[1], s.gimbal_yaw + n[2])
        if self.gimbal_report == "earth":
            rotation = zyx_rotation(0.0, 0.0, s.yaw) @ rotation
        q = zyx_quaternion(*zyx_angles(rotation))
        # Report the canonical Euler triple of the noisy rotation (pitch stays within +-90 deg).
        roll, pitch, yaw = zyx_angles(rotation)
        return GimbalSample(
            t=t,
            t_available=t + self.latency_s,
            q=(float(q[0]), float(q[1]), float(q[2]), float(q[3])),
            flags=_GIMBAL_FLAGS[self.gimbal_report],
            frame=self.gimbal_report,
            delta_yaw=s.yaw,
            roll=roll,
            pitch=pitch,
            yaw=yaw,
        )

    def sample(self, kind: str, t: float) -> PositionSample | AttitudeSample | GimbalSample | None:
        """One sample of ``kind`` ("position", "attitude" or "gimbal") at capture time ``t``."""
        if kind == "position":
            return self.position(t)
        if kind == "attitude":
            return self.attitude(t)
        if kind == "gimbal":
            return self.gimbal(t)
        raise ValueError(f"unknown telemetry kind {kind!r}")

    def capture_times(
        self, kind: str, t0: float, t1: float, rate_hz: float | None = None
    ) -> np.ndarray:
        """Capture times ``k / rate`` in ``[t0, t1)`` for a message kind (default rate)."""
        rate = self.rates_hz[kind] if rate_hz is None else rate_hz
        k0 = math.ceil(t0 * rate - 1e-9)
        k1 = math.ceil(t1 * rate - 1e-9)
        return np.arange(k0, k1) / rate

    def samples(self, kind: str, t0: float, t1: float, rate_hz: float | None = None) -> list:
        """All samples of ``kind`` *available* (capture + latency) within ``[t0, t1)``."""
        lat = self.latency_s
        out = []
        for t in self.capture_times(kind, t0 - lat, t1 - lat, rate_hz):
            if t < 0:
                continue
            s = self.sample(kind, float(t))
            if s is not None:
                out.append(s)
        return out


def _log_so3(r: np.ndarray) -> np.ndarray:
    """Rotation vector of a rotation matrix (small and moderate angles)."""
    cos_a = max(-1.0, min(1.0, (np.trace(r) - 1.0) / 2.0))
    a = math.acos(cos_a)
    v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if a < 1e-9:
        return v / 2.0
    return v * (a / (2.0 * math.sin(a)))
