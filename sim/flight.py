"""Synthetic multicopter flight: takeoff, lawnmower survey, runtime reposition and ROI.

Position is planned, attitude follows from the motion:

1. Path: home -> climb -> lawnmower legs over the search polygon at ``-altitude_m`` (NED down),
   every corner rounded by a circular arc (radius ``v^2 / a_lat`` where the segments allow).
2. Speed along the path: cruise speed, capped on arcs by ``sqrt(a_lat * r)`` and on climbs by the
   climb rate, ramped with ``max_accel`` (forward/backward pass over arc length).
3. Sampled on a 50 Hz time grid; acceleration is the smoothed second difference.
4. Attitude (multicopter): the thrust must supply ``T = a - g + c * (v - w)`` per unit mass,
   ``g = (0, 0, 9.81)`` NED, ``c`` the linear drag rate, ``w(t)`` the wind with seeded gusts.
   The body z axis (down) points along ``-T``, yaw follows the track, and roll/pitch follow from
   ``R_ned_body = [x_b, y_b, z_b]``; so the vehicle banks into turns and leans into the wind.

Runtime changes (called from the MAVLink vehicle) never rewrite the past, so frames rendered at
earlier times stay consistent: :meth:`Flight.reposition` starts a new trajectory at ``t`` from the
current state (fly there and hold), :meth:`Flight.set_roi` points the gimbal (or, with a hard
mount, the vehicle's nose) at a location from ``t`` on, slewing over ``roi_slew_s``.
"""

from __future__ import annotations

import bisect
import math
import threading
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from sarmission.geo.camera import CameraPose
from sarmission.mission.config import MissionConfig
from sim.truth_frames import camera_rotation, zyx_angles

GRAVITY = 9.80665
DT = 0.02  # trajectory grid step (s)


@dataclass
class VehicleState:
    """Exact vehicle state at time ``t`` (seconds since the start of the flight).

    Angles in radians. Vehicle attitude is ZYX Euler of ``R_ned_body``. Gimbal angles are ZYX
    Euler in ``gimbal_frame``: ``"vehicle"`` for a stabilised gimbal (roll/pitch relative to the
    horizon, yaw relative to the vehicle heading, as GIMBAL_DEVICE_ATTITUDE_STATUS with
    YAW_IN_VEHICLE_FRAME) or ``"body"`` for a hard mount.
    """

    t: float
    position_ned: np.ndarray
    velocity_ned: np.ndarray
    acceleration_ned: np.ndarray
    roll: float
    pitch: float
    yaw: float
    gimbal_roll: float
    gimbal_pitch: float
    gimbal_yaw: float
    gimbal_frame: str
    wind_ned: np.ndarray

    @property
    def vehicle_rpy(self) -> tuple[float, float, float]:
        return self.roll, self.pitch, self.yaw

    @property
    def gimbal_rpy(self) -> tuple[float, float, float]:
        return self.gimbal_roll, self.gimbal_pitch, self.gimbal_yaw

    def camera_pose(self) -> CameraPose:
        """Camera pose (camera centre at the vehicle position; lever arm neglected)."""
        r = camera_rotation(self.vehicle_rpy, self.gimbal_rpy, self.gimbal_frame)
        return CameraPose(self.position_ned.copy(), r)


def _wrap(a: np.ndarray | float) -> np.ndarray | float:
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


class WindModel:
    """Mean wind plus deterministic gusts: per axis a sum of 4 sinusoids with seeded frequencies
    (0.03-0.4 Hz) and phases; horizontal gust standard deviation ``gust_m_s``, vertical 30 %."""

    def __init__(self, speed_m_s: float, from_deg: float, gust_m_s: float, seed: int) -> None:
        to = math.radians(from_deg + 180.0)
        self.mean = np.array([speed_m_s * math.cos(to), speed_m_s * math.sin(to), 0.0])
        rng = np.random.default_rng([seed, 7])
        n = 4
        self.freq = rng.uniform(0.03, 0.4, (3, n)) * 2 * np.pi
        self.phase = rng.uniform(0, 2 * np.pi, (3, n))
        amp = gust_m_s * math.sqrt(2.0 / n)
        self.amp = np.array([amp, amp, 0.3 * amp])[:, None] * np.ones((3, n))

    def at(self, t: float) -> np.ndarray:
        """Wind velocity (m/s, NED, the direction the air moves) at time ``t``."""
        return self.mean + np.sum(self.amp * np.sin(self.freq * t + self.phase), axis=1)


def lawnmower_legs(
    polygon_ne: list[tuple[float, float]], spacing_m: float, heading_deg: float
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Parallel legs covering a polygon: ``[(start_ne, end_ne), ...]`` in flight order.

    Legs run along ``u = (cos h, sin h)`` (north, east) and are stacked along
    ``v = (-sin h, cos h)`` every ``spacing_m``, the first half a spacing inside the polygon.
    Each leg spans the polygon's extent along ``u`` at its offset; directions alternate.
    """
    h = math.radians(heading_deg)
    u = np.array([math.cos(h), math.sin(h)])
    v = np.array([-math.sin(h), math.cos(h)])
    pts = np.asarray(polygon_ne, dtype=float)
    a, c = pts @ u, pts @ v
    cmin, cmax = float(c.min()), float(c.max())
    width = cmax - cmin
    n_legs = max(1, math.ceil(width / spacing_m - 1e-9))
    first = cmin + (width - (n_legs - 1) * spacing_m) / 2.0
    legs = []
    for k in range(n_legs):
        ck = first + k * spacing_m
        hits = []
        for i in range(len(pts)):
            j = (i + 1) % len(pts)
            c0, c1 = c[i], c[j]
            if (c0 - ck) * (c1 - ck) <= 0 and c0 != c1:
                s = (ck - c0) / (c1 - c0)
                hits.append(a[i] + s * (a[j] - a[i]))
        if len(hits) < 2:
            continue
        a0, a1 = min(hits), max(hits)
        if k % 2:
            a0, a1 = a1, a0
        legs.append((a0 * u + ck * v, a1 * u + ck * v))
    return legs


@dataclass
class _Track:
    """Uniformly sampled trajectory starting at ``t0``; holds the last sample afterwards."""

    t0: float
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    yaw: np.ndarray  # unwrapped track yaw

    @property
    def t_end(self) -> float:
        return self.t0 + (len(self.pos) - 1) * DT

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        x = (t - self.t0) / DT
        n = len(self.pos)
        if x >= n - 1:
            return self.pos[-1].copy(), np.zeros(3), np.zeros(3), float(self.yaw[-1])
        x = max(x, 0.0)
        i = int(x)
        f = x - i
        j = min(i + 1, n - 1)

        def lerp(arr: np.ndarray) -> np.ndarray:
            return arr[i] * (1 - f) + arr[j] * f

        return lerp(self.pos), lerp(self.vel), lerp(self.acc), float(lerp(self.yaw))


def _track_yaw(vel: np.ndarray, initial_yaw: float, min_speed: float = 0.8) -> np.ndarray:
    """Yaw along the horizontal velocity where faster than ``min_speed``, held otherwise."""
    spd = np.hypot(vel[:, 0], vel[:, 1])
    raw = np.arctan2(vel[:, 1], vel[:, 0])
    yaw = np.empty(len(vel))
    last = initial_yaw
    for i in range(len(vel)):
        if spd[i] > min_speed:
            last = last + float(_wrap(raw[i] - last))
        yaw[i] = last
    return gaussian_filter1d(yaw, 0.4 / DT, mode="nearest")


def _finish_track(t0: float, pos: np.ndarray, initial_yaw: float) -> _Track:
    vel = np.gradient(pos, DT, axis=0)
    acc = gaussian_filter1d(np.gradient(vel, DT, axis=0), 0.15 / DT, axis=0, mode="nearest")
    return _Track(t0, pos, vel, acc, _track_yaw(vel, initial_yaw))


def _fillet_path(
    waypoints: np.ndarray, radius_pref: float, ds: float = 0.1
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sample a polyline with rounded corners every ``ds`` metres of arc length.

    Returns ``(points [M, 3], curvature [M], direction [M, 3])``. A corner turning by ``theta`` is
    replaced by a circular arc of radius ``r`` tangent to both segments at distance
    ``L = r tan(theta / 2)`` from the corner, ``r`` reduced so ``L`` is at most half of either
    segment.
    """
    wp = np.asarray(waypoints, dtype=float)
    seg = np.diff(wp, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    keep = np.concatenate([[True], seg_len > 1e-6])
    wp = wp[keep]
    seg = np.diff(wp, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    dirs = seg / seg_len[:, None]
    # Corner arcs: (tangent-in point, centre, radius, theta, d_in, n) per interior waypoint.
    corners: list[tuple[np.ndarray, np.ndarray, float, float, np.ndarray, np.ndarray] | None] = []
    cut = np.zeros((len(wp), 1))
    for i in range(1, len(wp) - 1):
        d_in, d_out = dirs[i - 1], dirs[i]
        cos_t = float(np.clip(d_in @ d_out, -1.0, 1.0))
        theta = math.acos(cos_t)
        if theta < 1e-4:
            corners.append(None)
            continue
        tan_half = math.tan(theta / 2.0)
        r = min(radius_pref, 0.5 * min(seg_len[i - 1], seg_len[i]) / tan_half)
        length = r * tan_half
        n = d_out - cos_t * d_in
        n /= np.linalg.norm(n)
        t1 = wp[i] - length * d_in
        corners.append((t1, t1 + r * n, r, theta, d_in, n))
        cut[i] = length
    pts, curv, dirn = [], [], []

    def line(p0: np.ndarray, p1: np.ndarray, d: np.ndarray) -> None:
        length = float(np.linalg.norm(p1 - p0))
        m = max(1, int(math.ceil(length / ds)))
        s = np.arange(m) / m
        pts.append(p0 + s[:, None] * (p1 - p0))
        curv.append(np.zeros(m))
        dirn.append(np.repeat(d[None, :], m, axis=0))

    start = wp[0]
    for i in range(1, len(wp)):
        d = dirs[i - 1]
        corner = corners[i - 1] if i < len(wp) - 1 else None
        end = wp[i] - (cut[i, 0] * d if corner is not None else 0.0)
        line(start, end, d)
        if corner is None:
            start = end if i < len(wp) - 1 else wp[i]
            continue
        t1, centre, r, theta, d_in, n = corner
        m = max(2, int(math.ceil(r * theta / ds)))
        phi = np.arange(m) / m * theta
        arc = centre + r * (-np.outer(np.cos(phi), n) + np.outer(np.sin(phi), d_in))
        tang = np.outer(np.cos(phi), d_in) + np.outer(np.sin(phi), n)
        pts.append(arc)
        curv.append(np.full(m, 1.0 / r))
        dirn.append(tang)
        start = centre + r * (-math.cos(theta) * n + math.sin(theta) * d_in)
    pts.append(wp[-1][None, :])
    curv.append(np.zeros(1))
    dirn.append(dirs[-1][None, :])
    return np.concatenate(pts), np.concatenate(curv), np.concatenate(dirn)


def _time_parametrise(
    points: np.ndarray,
    curvature: np.ndarray,
    direction: np.ndarray,
    cruise: float,
    climb: float,
    accel: float,
    lat_accel: float,
) -> np.ndarray:
    """Positions on the uniform ``DT`` grid along a sampled path, starting and ending at rest."""
    ds = np.linalg.norm(np.diff(points, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(ds)])
    vmax = np.full(len(points), cruise)
    on_arc = curvature > 0
    vmax[on_arc] = np.minimum(vmax[on_arc], np.sqrt(lat_accel / curvature[on_arc]))
    vertical = np.abs(direction[:, 2])
    horiz = np.sqrt(np.maximum(1.0 - vertical**2, 0.0))
    # Speed so that the vertical rate stays within the climb rate.
    vmax = np.minimum(vmax, np.where(vertical > 1e-6, climb / np.maximum(vertical, 1e-6), np.inf))
    vmax = np.maximum(vmax, 0.3 * np.minimum(cruise, climb) * (horiz + vertical))
    v = vmax.copy()
    v[0] = 0.0
    for i in range(1, len(v)):
        v[i] = min(v[i], math.sqrt(v[i - 1] ** 2 + 2 * accel * ds[i - 1]))
    v[-1] = 0.0
    for i in range(len(v) - 2, -1, -1):
        v[i] = min(v[i], math.sqrt(v[i + 1] ** 2 + 2 * accel * ds[i]))
    dt = 2.0 * ds / np.maximum(v[:-1] + v[1:], 1e-6)
    t = np.concatenate([[0.0], np.cumsum(dt)])
    grid = np.arange(0.0, t[-1] + DT, DT)
    s_grid = np.interp(grid, t, s)
    return np.column_stack([np.interp(s_grid, s, points[:, k]) for k in range(3)])


class Flight:
    """The flight of one mission: planned survey plus runtime changes; thread-safe.

    ``state_at(t)`` gives the exact :class:`VehicleState` at ``t`` seconds after the start.
    """

    #: It obeys DO_REPOSITION and ROI commands (see :class:`sim.flight_model.FlightModel`).
    steerable = True

    def __init__(self, mission: MissionConfig, seed: int = 0, roi_slew_s: float = 1.0) -> None:
        self.mission = mission
        self.seed = seed
        self.roi_slew_s = roi_slew_s
        fc = mission.flight
        self.wind = WindModel(
            mission.sim.wind_speed_m_s, mission.sim.wind_from_deg, mission.sim.gust_m_s, seed
        )
        self.drag = mission.sim.drag_per_s
        self.legs = lawnmower_legs(
            mission.area.polygon_ne(), mission.area.leg_spacing_m, mission.area.heading_deg
        )
        if not self.legs:
            raise ValueError("the search area yields no lawnmower legs")
        alt = -fc.altitude_m
        wps: list[np.ndarray] = []
        if fc.takeoff:
            wps += [np.zeros(3), np.array([0.0, 0.0, alt])]
        for a, b in self.legs:
            wps += [np.array([a[0], a[1], alt]), np.array([b[0], b[1], alt])]
        self.waypoints = np.array(wps)
        pts, curv, dirn = _fillet_path(self.waypoints, fc.speed_m_s**2 / fc.max_lateral_accel_m_s2)
        pos = _time_parametrise(
            pts,
            curv,
            dirn,
            fc.speed_m_s,
            fc.climb_rate_m_s,
            fc.max_accel_m_s2,
            fc.max_lateral_accel_m_s2,
        )
        first_leg = self.legs[0][1] - self.legs[0][0]
        yaw0 = math.atan2(first_leg[1], first_leg[0])
        if fc.takeoff:
            to_leg = self.legs[0][0]
            if np.linalg.norm(to_leg) > 1.0:
                yaw0 = math.atan2(to_leg[1], to_leg[0])
        survey = _finish_track(0.0, pos, yaw0)
        self.survey_duration = survey.t_end
        self._lock = threading.Lock()
        self._tracks: list[_Track] = [survey]
        self._track_starts: list[float] = [0.0]
        # ROI timeline: (t_start, target_ned or None)
        self._roi: list[tuple[float, np.ndarray | None]] = [(0.0, None)]
        self._has_gimbal = mission.camera.gimbal
        self._mount_pitch = math.radians(mission.camera.mount_pitch_deg)

    # -- runtime changes -------------------------------------------------------------------
    def reposition(self, t: float, target_ned: np.ndarray, speed_m_s: float | None = None) -> float:
        """From time ``t`` fly to ``target_ned`` and hold there (DO_REPOSITION / loiter).

        Guidance: desired velocity towards the target with magnitude
        ``min(speed, sqrt(2 a d), d / 1 s)``, acceleration limited to ``max_accel``.
        Returns the predicted arrival time.
        """
        fc = self.mission.flight
        vmax = fc.speed_m_s if speed_m_s is None or speed_m_s <= 0 else float(speed_m_s)
        amax = fc.max_accel_m_s2
        target = np.asarray(target_ned, dtype=float).reshape(3)
        with self._lock:
            track = self._track_for(t)
            p, v, _, yaw = track.sample(t)
        positions = [p.copy()]
        max_steps = int(3600.0 / DT)
        for _ in range(max_steps):
            delta = target - p
            dist = float(np.linalg.norm(delta))
            if dist < 0.02 and float(np.linalg.norm(v)) < 0.05:
                break
            speed = min(vmax, math.sqrt(2.0 * amax * 0.8 * dist), dist / 1.0)
            v_des = delta / dist * speed if dist > 1e-9 else np.zeros(3)
            a = (v_des - v) / 0.4
            na = float(np.linalg.norm(a))
            if na > amax:
                a *= amax / na
            v = v + a * DT
            p = p + v * DT
            positions.append(p.copy())
        positions.append(target.copy())
        new = _finish_track(t, np.array(positions), yaw)
        with self._lock:
            keep = bisect.bisect_right(self._track_starts, t)
            del self._tracks[keep:], self._track_starts[keep:]
            self._tracks.append(new)
            self._track_starts.append(t)
        return new.t_end

    def set_roi(self, t: float, target_ned: np.ndarray | None) -> None:
        """From ``t`` point the camera at ``target_ned`` (None cancels the ROI)."""
        target = None if target_ned is None else np.asarray(target_ned, dtype=float).reshape(3)
        with self._lock:
            keep = bisect.bisect_right([r[0] for r in self._roi], t)
            del self._roi[keep:]
            self._roi.append((t, target))

    # -- queries -----------------------------------------------------------------------------
    def _track_for(self, t: float) -> _Track:
        i = max(0, bisect.bisect_right(self._track_starts, t) - 1)
        return self._tracks[i]

    def _roi_angles(
        self, pos: np.ndarray, target: np.ndarray | None, yaw: float
    ) -> tuple[float, float, float, float]:
        """(gimbal roll, pitch, yaw, vehicle yaw) for an ROI target (or the default mount)."""
        if target is None:
            return 0.0, self._mount_pitch, 0.0, yaw
        d = target - pos
        bearing = math.atan2(d[1], d[0])
        pitch = -math.atan2(d[2], math.hypot(d[0], d[1]))  # negative when the target is below
        pitch = min(0.0, max(-math.pi / 2, pitch))
        if self._has_gimbal:
            return 0.0, pitch, float(_wrap(bearing - yaw)), yaw
        return 0.0, self._mount_pitch, 0.0, yaw + float(_wrap(bearing - yaw))

    def _pointing(self, t: float, pos: np.ndarray, yaw: float, idx: int) -> np.ndarray:
        start, target = self._roi[idx]
        cur = np.array(self._roi_angles(pos, target, yaw))
        s = (t - start) / self.roi_slew_s if self.roi_slew_s > 0 else 1.0
        if idx == 0 or s >= 1.0:
            return cur
        prev = self._pointing(t, pos, yaw, idx - 1)
        delta = cur - prev
        delta[2] = float(_wrap(delta[2]))
        delta[3] = float(_wrap(delta[3]))
        return prev + max(s, 0.0) * delta

    def state_at(self, t: float) -> VehicleState:
        """Exact state at time ``t`` (s). Before 0 the state at 0 is returned."""
        t = max(0.0, float(t))
        with self._lock:
            track = self._track_for(t)
            roi_idx = max(0, bisect.bisect_right([r[0] for r in self._roi], t) - 1)
            pos, vel, acc, track_yaw = track.sample(t)
            g_roll, g_pitch, g_yaw, yaw = self._pointing(t, pos, track_yaw, roi_idx)
        wind = self.wind.at(t)
        thrust = acc - np.array([0.0, 0.0, GRAVITY]) + self.drag * (vel - wind)
        z_b = -thrust / np.linalg.norm(thrust)
        # x_b perpendicular to the horizontal "right" vector y_c keeps the ZYX yaw exactly ``yaw``.
        y_c = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
        x_b = np.cross(y_c, z_b)
        x_b /= np.linalg.norm(x_b)
        y_b = np.cross(z_b, x_b)
        roll, pitch, yaw_out = zyx_angles(np.column_stack([x_b, y_b, z_b]))
        return VehicleState(
            t=t,
            position_ned=pos,
            velocity_ned=vel,
            acceleration_ned=acc,
            roll=roll,
            pitch=pitch,
            yaw=yaw_out,
            gimbal_roll=float(g_roll),
            gimbal_pitch=float(g_pitch),
            gimbal_yaw=float(_wrap(g_yaw)),
            gimbal_frame="vehicle" if self._has_gimbal else "body",
            wind_ned=wind,
        )

    def camera_pose_at(self, t: float) -> CameraPose:
        """Exact camera pose at time ``t``."""
        return self.state_at(t).camera_pose()
