"""Where a target is as of its latest fix: a straight-line fit of its recent fixes.

People in the water drift with the current and people on land walk: over a minute a swimmer can
move tens of metres, so the mean of every fix a target ever had lies behind them, in the middle
of their path. The position an alert reports (and is refined to) is instead that of a fit of the
fixes of the latest ``window_s`` seconds, evaluated at the latest fix:

- a drift faster than twice its standard error, and no faster than a person moves
  (:data:`MAX_DRIFT_M_S`), is followed (the fit's line, at the latest fix's time);
- otherwise the target is taken as still, at the mean of the window's fixes (a slower drift
  moves it by less than the fixes' own error over the window).

The error (1-sigma DRMS) is honest rather than hopeful: the fixes share the pose's errors, which
wander over seconds, so averaging never takes it below the mean of the fixes' own errors; it is
at least the fixes' RMS distance from the fit (fixes that disagree more than their errors say do
not place the target better than that), and a followed drift adds its extrapolation error.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from sarmission.geo.wgs84 import geodetic_to_ned, ned_to_geodetic
from sarmission.mission.targets import PERSON_SPEED_M_S

#: Seconds of the latest fixes a position is fitted to.
WINDOW_S = 20.0
#: A drift is followed when its speed exceeds this many of its standard errors ...
DRIFT_SIGMAS = 2.0
#: ... and is one a person can have (m/s): faster, the fixes moved, not the person (a GNSS
#: jump, a pose error settling), and the target is taken as still with the scatter as error.
MAX_DRIFT_M_S = PERSON_SPEED_M_S


class Fix(Protocol):
    """What a fix needs here (:class:`~sarmission.mission.confirmation.Sighting` has it)."""

    t: float
    lat: float
    lon: float
    error_m: float


@dataclass(frozen=True)
class LineFit:
    """A straight-line fit of fixes over time, in metres north/east of ``origin``: the mean
    time and position, the velocity, the fixes' RMS distance from the line and from their
    mean, and the velocity's standard error per axis."""

    origin: tuple[float, float]
    t_mean: float
    mean_ne: np.ndarray
    velocity_ne: np.ndarray
    residual_rms_m: float
    spread_rms_m: float
    sigma_v_axis: float

    @property
    def speed_m_s(self) -> float:
        return float(np.hypot(*self.velocity_ne))

    @property
    def speed_sigma_m_s(self) -> float:
        """The speed's standard error (two axes)."""
        return self.sigma_v_axis * math.sqrt(2)


def line_fit(fixes: Sequence[Fix], origin: tuple[float, float]) -> LineFit | None:
    """The least-squares line through ``fixes`` (at least 3, ordered by time), or None when
    they span no time. The velocity's error is at least what two independent fixes at the
    ends of the span would give: successive fixes share the pose's errors, so the fit alone
    would trust a short span far too much."""
    if len(fixes) < 3:
        return None
    t = np.array([f.t for f in fixes])
    n, e, _ = geodetic_to_ned(
        np.array([f.lat for f in fixes]), np.array([f.lon for f in fixes]), 0.0, *origin, 0.0
    )
    pos = np.stack([np.asarray(n, float), np.asarray(e, float)], axis=1)
    dt = t - t.mean()
    spread = float(np.sum(dt**2))
    span = float(t.max() - t.min())
    if spread <= 0 or span <= 0:
        return None
    mean = pos.mean(axis=0)
    velocity = (dt[:, None] * (pos - mean)).sum(axis=0) / spread
    residual = pos - mean - dt[:, None] * velocity
    dof = max(1, len(t) - 2)
    sigma_fit = math.sqrt(float(np.sum(residual**2)) / (2 * dof))  # per axis
    sigma_fix = float(np.median([f.error_m for f in fixes])) / math.sqrt(2)  # per axis
    span_floor = math.sqrt(2) * sigma_fix / span
    return LineFit(
        origin,
        float(t.mean()),
        mean,
        velocity,
        math.sqrt(float(np.mean(np.sum(residual**2, axis=1)))),
        math.sqrt(float(np.mean(np.sum((pos - mean) ** 2, axis=1)))),
        max(sigma_fit / math.sqrt(spread), span_floor),
    )


@dataclass(frozen=True)
class PositionEstimate:
    """A target's position as of time ``t`` (its latest fix), its 1-sigma DRMS error, and its
    drift (m/s north, east; zero when taken as still)."""

    lat: float
    lon: float
    error_m: float
    t: float
    velocity_ne: tuple[float, float]

    @property
    def position(self) -> tuple[float, float]:
        return self.lat, self.lon

    @property
    def drifting(self) -> bool:
        return self.velocity_ne != (0.0, 0.0)


def latest_position(
    fixes: Sequence[Fix],
    window_s: float = WINDOW_S,
    drift_sigmas: float = DRIFT_SIGMAS,
    max_drift_m_s: float = MAX_DRIFT_M_S,
    min_fixes: int = 1,
    min_span_s: float = 0.0,
) -> PositionEstimate | None:
    """The position of the target seen in ``fixes`` (ordered by time) as of its latest fix
    (see the module docstring); None without fixes, or when the window holds fewer than
    ``min_fixes`` or spans less than ``min_span_s``: a new position needs as much evidence as
    a confirmation (a few fixes of a track that barely locked may be of something else)."""
    if not fixes:
        return None
    last = fixes[-1]
    start = bisect.bisect_left(fixes, last.t - window_s, key=lambda f: f.t)
    recent = fixes[start:]
    if len(recent) < min_fixes or last.t - recent[0].t < min_span_s:
        return None
    origin = (last.lat, last.lon)
    fix_error = float(np.mean([f.error_m for f in recent]))
    fit = line_fit(recent, origin)
    if fit is None:
        return PositionEstimate(last.lat, last.lon, fix_error, last.t, (0.0, 0.0))
    if drift_sigmas * fit.speed_sigma_m_s < fit.speed_m_s <= max_drift_m_s:
        ahead = last.t - fit.t_mean
        ne = fit.mean_ne + fit.velocity_ne * ahead
        extrapolation = fit.speed_sigma_m_s * ahead
        velocity = (float(fit.velocity_ne[0]), float(fit.velocity_ne[1]))
        scatter = fit.residual_rms_m
    else:
        ne = fit.mean_ne
        extrapolation = 0.0
        velocity = (0.0, 0.0)
        scatter = fit.spread_rms_m  # taken as still: the fixes' distance from their mean
    error = math.hypot(max(fix_error, scatter), extrapolation)
    lat, lon, _ = ned_to_geodetic(float(ne[0]), float(ne[1]), 0.0, *origin, 0.0)
    return PositionEstimate(float(lat), float(lon), error, last.t, velocity)
