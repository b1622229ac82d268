"""A flight log in its own clock: positions, attitudes, gimbal angles, home, camera triggers.

Readers never hand out a sample they do not believe: :class:`LogBuilder` checks each one
(finite, in range, a 3D GNSS fix where the format says, no jump faster than an aircraft) and
counts the rest by reason in :attr:`FlightLog.rejected`. Times are seconds in the log's clock
(:attr:`FlightLog.clock` says which: the autopilot's boot time, the video's own time, ...);
``utc_offset_s`` turns them into POSIX seconds when the log knows UTC (GNSS time).

Angles are radians in :mod:`sarmission.geo.frames` conventions: vehicle attitude ZYX Euler of
``R_ned_body`` (or a ``(w, x, y, z)`` quaternion), gimbal ZYX Euler or quaternion in the
"body", "vehicle" or "earth" frame. Each reader documents how its format's signs map onto them.
"""

from __future__ import annotations

import bisect
import math
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sarmission.mavlink.telemetry_checks import MAX_SPEED_MPS, lat_lon_problem, quaternion_problem

#: Seconds between the POSIX and GPS epochs (1970-01-01 to 1980-01-06).
GPS_EPOCH_POSIX = 315_964_800
#: GPS - UTC in seconds since 2017-01-01 (no leap second has been added since).
GPS_LEAP_SECONDS = 18
#: Jump allowance on top of the fastest speed (metres): GNSS noise, EKF resets.
JUMP_SLACK_M = 10.0
#: Heights above home believed (metres).
REL_ALT_RANGE_M = (-1000.0, 12000.0)


class FlightLogError(ValueError):
    """A flight log cannot give telemetry (unreadable, truncated to nothing, no GNSS): the
    message is one line for the operator."""


@dataclass(frozen=True)
class Accuracy:
    """1-sigma accuracies a format's samples are taken to have when the log does not say:
    horizontal GNSS per axis (m), height above home (m), camera pointing per axis (deg)."""

    gnss_sigma_m: float
    alt_sigma_m: float
    attitude_sigma_deg: float


#: Per-format defaults (see docs/flightlogs.md for where the numbers come from).
ACCURACY = {
    "autopilot": Accuracy(gnss_sigma_m=2.0, alt_sigma_m=1.0, attitude_sigma_deg=1.0),
    "dji": Accuracy(gnss_sigma_m=1.5, alt_sigma_m=1.0, attitude_sigma_deg=1.5),
}


@dataclass(frozen=True)
class PositionSample:
    """Vehicle position: degrees, metres above home, metres AMSL (NaN: unknown), the
    horizontal 1-sigma of this fix (None: the format's default)."""

    t: float
    lat: float
    lon: float
    rel_alt_m: float
    alt_m: float = math.nan
    gnss_sigma_m: float | None = None


@dataclass(frozen=True)
class AttitudeSample:
    """Vehicle attitude: quaternion ``(w, x, y, z)`` of ``R_ned_body``."""

    t: float
    q: tuple[float, float, float, float]


@dataclass(frozen=True)
class GimbalSample:
    """Gimbal attitude: quaternion ``(w, x, y, z)`` in ``frame`` ("body", "vehicle", "earth")."""

    t: float
    q: tuple[float, float, float, float]
    frame: str


@dataclass
class FlightLog:
    """What one log says about a flight (see the module docstring).

    ``home`` is ``(lat, lon, alt AMSL)`` with ``home_note`` saying where it came from;
    ``triggers`` are camera trigger times; ``image_times`` maps an image file name to its
    capture time (formats that record per image). ``per_frame`` is True when the log's clock
    is the video's own (a subtitle sidecar). ``notes`` are lines for the operator.
    """

    fmt: str
    path: Path
    clock: str
    accuracy: Accuracy
    positions: list[PositionSample] = field(default_factory=list)
    attitudes: list[AttitudeSample] = field(default_factory=list)
    gimbal: list[GimbalSample] = field(default_factory=list)
    home: tuple[float, float, float] | None = None
    home_note: str = ""
    triggers: list[float] = field(default_factory=list)
    utc_offset_s: float | None = None
    image_times: dict[str, float] = field(default_factory=dict)
    per_frame: bool = False
    #: When the log says it began (POSIX seconds, its own clock's time zone, often local):
    #: only to tell a log of another day, not a time base.
    stated_start_posix: float | None = None
    rejected: Counter[str] = field(default_factory=Counter)
    notes: list[str] = field(default_factory=list)

    @property
    def span(self) -> tuple[float, float]:
        """``(first, last)`` position time."""
        return self.positions[0].t, self.positions[-1].t

    def utc_span(self) -> tuple[float, float] | None:
        """The positions' span in POSIX seconds, None when the log has no UTC."""
        if self.utc_offset_s is None:
            return None
        t0, t1 = self.span
        return t0 + self.utc_offset_s, t1 + self.utc_offset_s

    def summary(self) -> str:
        """One line: format, samples, span, what is missing."""
        t0, t1 = self.span
        parts = [
            f"{self.fmt} {self.path.name}: {len(self.positions)} positions over "
            f"{t1 - t0:.1f} s ({self.clock})",
            f"{len(self.attitudes)} attitudes" if self.attitudes else "no attitude",
            f"{len(self.gimbal)} gimbal angles" if self.gimbal else "no gimbal angles",
        ]
        if self.triggers:
            parts.append(f"{len(self.triggers)} camera triggers")
        if self.rejected:
            parts.append(
                f"{sum(self.rejected.values())} samples rejected ("
                + ", ".join(f"{n} {why}" for why, n in self.rejected.most_common(3))
                + ")"
            )
        return ", ".join(parts)


def gps_to_posix(week: int, ms: float) -> float:
    """GPS week and milliseconds of week as POSIX (UTC) seconds."""
    return GPS_EPOCH_POSIX + week * 604_800 + ms / 1000.0 - GPS_LEAP_SECONDS


def _finite(*values: float) -> bool:
    return all(
        isinstance(v, (int, float, np.floating, np.integer)) and math.isfinite(v) for v in values
    )


class LogBuilder:
    """Collects a reader's samples, checking each (see the module docstring)."""

    def __init__(
        self,
        fmt: str,
        path: Path,
        clock: str,
        accuracy: Accuracy,
        home_note: str = "home altitude from the first position (AMSL - height above home)",
    ) -> None:
        self.log = FlightLog(fmt, Path(path), clock, accuracy)
        #: What :meth:`build` says of a home taken from the first believed position (when the
        #: reader found none of its own).
        self.home_note = home_note

    def reject(self, reason: str) -> None:
        """Count one sample not believed."""
        self.log.rejected[reason] += 1

    def position(
        self,
        t: float,
        lat: float,
        lon: float,
        rel_alt_m: float,
        alt_m: float = math.nan,
        gnss_sigma_m: float | None = None,
    ) -> bool:
        """Add a position; False (counted) when implausible."""
        if not _finite(t, rel_alt_m):
            self.reject("position time or height not finite")
            return False
        if lat == 0 and lon == 0:
            self.reject("position 0, 0 (no fix)")
            return False
        problem = lat_lon_problem(lat, lon)
        if problem:
            self.reject("position out of range")
            return False
        if not REL_ALT_RANGE_M[0] <= rel_alt_m <= REL_ALT_RANGE_M[1]:
            self.reject("height above home out of range")
            return False
        if gnss_sigma_m is not None and not (_finite(gnss_sigma_m) and gnss_sigma_m > 0):
            gnss_sigma_m = None
        sample = PositionSample(
            float(t),
            float(lat),
            float(lon),
            float(rel_alt_m),
            float(alt_m) if _finite(alt_m) else math.nan,
            gnss_sigma_m,
        )
        positions = self.log.positions
        if positions and t < positions[-1].t:
            self.reject("position time going backwards")
            return False
        positions.append(sample)  # jumps are judged over the whole track in build()
        return True

    def attitude_euler(self, t: float, roll: float, pitch: float, yaw: float) -> bool:
        """Add a vehicle attitude from ZYX Euler radians."""
        if not _finite(t, roll, pitch, yaw):
            self.reject("attitude not finite")
            return False
        from sarmission.geo.frames import euler_to_quaternion

        return self.attitude_quaternion(t, euler_to_quaternion(roll, pitch, yaw))

    def attitude_quaternion(self, t: float, q: object) -> bool:
        """Add a vehicle attitude quaternion ``(w, x, y, z)``."""
        values = tuple(float(v) for v in np.asarray(q, dtype=float).reshape(-1))
        if not _finite(t) or quaternion_problem(values):
            self.reject("attitude not a unit quaternion")
            return False
        _insert(self.log.attitudes, AttitudeSample(float(t), _unit(values)))
        return True

    def gimbal_euler(self, t: float, roll: float, pitch: float, yaw: float, frame: str) -> bool:
        """Add a gimbal attitude from ZYX Euler radians in ``frame``."""
        if not _finite(t, roll, pitch, yaw):
            self.reject("gimbal angles not finite")
            return False
        from sarmission.geo.frames import euler_to_quaternion

        return self.gimbal_quaternion(t, euler_to_quaternion(roll, pitch, yaw), frame)

    def gimbal_quaternion(self, t: float, q: object, frame: str) -> bool:
        """Add a gimbal attitude quaternion ``(w, x, y, z)`` in ``frame``."""
        values = tuple(float(v) for v in np.asarray(q, dtype=float).reshape(-1))
        if not _finite(t) or quaternion_problem(values):
            self.reject("gimbal attitude not a unit quaternion")
            return False
        _insert(self.log.gimbal, GimbalSample(float(t), _unit(values), frame))
        return True

    def trigger(self, t: float) -> None:
        """Add a camera trigger time."""
        if _finite(t):
            bisect.insort(self.log.triggers, float(t))

    def build(self) -> FlightLog:
        """The log; :class:`FlightLogError` when it has no believable position."""
        log = self.log
        kept = consistent_track(log.positions)
        if len(kept) < len(log.positions):
            log.rejected["position jump faster than an aircraft"] += len(log.positions) - len(kept)
            log.positions = kept
        if not log.positions:
            why = (
                f" ({', '.join(f'{n} {r}' for r, n in log.rejected.most_common(2))})"
                if log.rejected
                else ""
            )
            raise FlightLogError(
                f"{log.path.name}: {log.fmt} without a usable GNSS "
                f"position{why}: no positions from it"
            )
        if log.home is None:
            first = next((p for p in log.positions if math.isfinite(p.alt_m)), None)
            if first is not None:
                log.home = (first.lat, first.lon, first.alt_m - first.rel_alt_m)
                log.home_note = self.home_note
            else:  # heights above home are all a flat-ground fix needs
                log.home = (log.positions[0].lat, log.positions[0].lon, math.nan)
                log.home_note = "home altitude AMSL not in the log (heights are above take-off)"
        return log


def consistent_track(positions: list[PositionSample]) -> list[PositionSample]:
    """The largest set of ``positions`` (in time order) an aircraft could have flown: each
    sample joins the longest chain whose latest sample it can be reached from at
    :data:`MAX_SPEED_MPS` (plus :data:`JUMP_SLACK_M`), else starts a chain of its own; the
    longest chain is kept. Judged against the previous believed sample only, one stale first
    fix (a previous flight's, a glitch) made every true position after it a jump."""
    if len(positions) < 2:
        return list(positions)
    # metres on a plane about the first sample: exact enough at the distances that decide
    # (an aircraft's reach in a few seconds); far glitches stay far on it
    lat0, lon0 = positions[0].lat, positions[0].lon
    scale = 111_320.0
    north = np.array([(p.lat - lat0) * scale for p in positions])
    east = np.array(
        [
            ((p.lon - lon0 + 180.0) % 360.0 - 180.0) * scale * math.cos(math.radians(lat0))
            for p in positions
        ]
    )
    times = np.array([p.t for p in positions])
    # chain ends: index of the latest sample, and the chain's length
    ends = np.zeros(len(positions), dtype=np.int64)
    lengths = np.zeros(len(positions), dtype=np.int64)
    member = np.zeros(len(positions), dtype=np.int64)
    chains = 0
    for i in range(len(positions)):
        if chains:
            last = ends[:chains]
            reach = MAX_SPEED_MPS * np.maximum(times[i] - times[last], 0.1) + JUMP_SLACK_M
            gap = np.hypot(north[i] - north[last], east[i] - east[last])
            able = np.flatnonzero(gap <= reach)
            if able.size:
                best = able[np.argmax(lengths[able] * len(positions) + last[able])]
                ends[best] = i
                lengths[best] += 1
                member[i] = best
                continue
        ends[chains] = i
        lengths[chains] = 1
        member[i] = chains
        chains += 1
    keep = int(np.argmax(lengths[:chains]))
    return [p for p, m in zip(positions, member, strict=True) if m == keep]


def _unit(q: tuple[float, ...]) -> tuple[float, float, float, float]:
    n = math.sqrt(sum(v * v for v in q))
    w, x, y, z = (v / n for v in q)
    return (w, x, y, z)


def _insert(series: list, sample: AttitudeSample | GimbalSample) -> None:
    if not series or sample.t >= series[-1].t:
        series.append(sample)
    else:
        bisect.insort(series, sample, key=lambda s: s.t)
