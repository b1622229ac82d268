"""What makes each section of a mission file valid: one rule function per section.

Each rule returns the first problem it finds as ``(key, what was expected)``, or None. The
loader (:mod:`sarmission.mission.config`) runs them in :data:`SECTION_RULES` order and names
the file and ``[section] key`` in its error. Sets of valid values come from the code that
uses them (e.g. :data:`~sarmission.perception.types.VALID_DS`), so the file, the model and the
command line accept the same values. Comparisons are written so that NaN fails them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from sarmission.alerts.cot import parse_cot_url
from sarmission.errors import SarmissionError
from sarmission.models import DEFAULT_NAME, SHIPPED_HEADS, is_head_name
from sarmission.perception.orientations import ORIENTATION_COUNTS
from sarmission.perception.types import MAX_CROP_SCALE, VALID_DS

if TYPE_CHECKING:
    from sarmission.mission.config import (
        ActionsConfig,
        AlertsConfig,
        AreaConfig,
        CameraConfig,
        ConfirmConfig,
        DetectorConfig,
        FlightConfig,
        GeolocationConfig,
        LockConfig,
        TelemetryConfig,
    )

ACTION_POLICIES = ("alert", "loiter", "roi", "mission")
#: ``[detector] model`` value that names the package's default head (the other shipped heads
#: go by their names, :data:`sarmission.models.SHIPPED_HEADS`).
DEFAULT_MODEL = DEFAULT_NAME
#: File name endings of a head model.
MODEL_SUFFIXES = (".pt", ".pth", ".onnx")

Problem = tuple[str, str] | None


def area_problem(a: AreaConfig) -> Problem:
    if not -90.0 <= a.home_lat <= 90.0 or not -180.0 <= a.home_lon <= 180.0:
        return "home_lat/home_lon", "expected latitude in [-90, 90] and longitude in [-180, 180]"
    shapes = [
        s for s in ("rectangle_m", "polygon_m", "polygon_latlon") if getattr(a, s) is not None
    ]
    if len(shapes) > 1:
        return "", (
            f"give only one of rectangle_m, polygon_m, polygon_latlon (got {', '.join(shapes)})"
        )
    r = a.rectangle_m
    if r is not None and (len(r) != 4 or r[0] >= r[2] or r[1] >= r[3]):
        return "rectangle_m", "expected [north_min, east_min, north_max, east_max] with min < max"
    for s in ("polygon_m", "polygon_latlon"):
        poly = getattr(a, s)
        if poly is not None and (len(poly) < 3 or any(len(p) != 2 for p in poly)):
            return s, "expected at least 3 points of 2 numbers each"
    if a.polygon_latlon is not None and any(
        not (-90.0 <= p[0] <= 90.0 and -180.0 <= p[1] <= 180.0) for p in a.polygon_latlon
    ):
        return "polygon_latlon", "expected [latitude, longitude] points (latitude first)"
    if not a.leg_spacing_m >= MIN_LEG_SPACING_M:
        return "leg_spacing_m", f"expected at least {MIN_LEG_SPACING_M:g} m"
    return _area_extent_problem(a)


#: Farthest an area's corner may lie from home (metres): a search a multicopter flies from
#: its home, and a bound that catches a polygon given longitude first (GeoJSON order).
MAX_AREA_RADIUS_M = 50_000.0
#: Closest legs of a survey (metres), and most legs of one (a lawnmower of more would take
#: days and, planned, hang the planner).
MIN_LEG_SPACING_M = 1.0
MAX_LEGS = 2000


def _area_extent_problem(a: AreaConfig) -> Problem:
    corners = a.polygon_ne()
    far = max(math.hypot(n, e) for n, e in corners)
    shape = next(
        (s for s in ("polygon_latlon", "polygon_m", "rectangle_m") if getattr(a, s) is not None),
        "rectangle_m",
    )
    if not far <= MAX_AREA_RADIUS_M:
        hint = " (polygon_latlon: latitude first?)" if shape == "polygon_latlon" else ""
        return shape, (
            f"a corner lies {far / 1000:,.0f} km from home; an area within "
            f"{MAX_AREA_RADIUS_M / 1000:g} km of home is expected{hint}"
        )
    across = max(math.hypot(n1 - n0, e1 - e0) for n0, e0 in corners for n1, e1 in corners)
    if across / a.leg_spacing_m > MAX_LEGS:
        return "leg_spacing_m", (
            f"{across / a.leg_spacing_m:,.0f} legs across an area {across:,.0f} m wide; "
            f"at most {MAX_LEGS} (a wider spacing or a smaller area)"
        )
    return None


def flight_problem(f: FlightConfig) -> Problem:
    for key in (
        "altitude_m",
        "speed_m_s",
        "climb_rate_m_s",
        "max_accel_m_s2",
        "max_lateral_accel_m_s2",
    ):
        if getattr(f, key) <= 0:
            return key, "expected a positive number"
    return None


def camera_problem(c: CameraConfig) -> Problem:
    if c.width <= 0 or c.height <= 0:
        return "width/height", "expected positive integers"
    if not 0.0 < c.hfov_deg < 180.0:
        return "hfov_deg", "expected a number in (0, 180)"
    if not -90.0 <= c.mount_pitch_deg <= 0.0:
        return "mount_pitch_deg", "expected -90 (nadir) .. 0 (horizon)"
    if len(c.distortion) not in (0, 4, 5):
        return "distortion", "expected 0, 4 or 5 numbers (k1, k2, p1, p2[, k3])"
    if c.fx is not None and c.fx <= 0 or c.fy is not None and c.fy <= 0:
        return "fx/fy", "expected positive focal lengths in pixels"
    return None


def detector_problem(d: DetectorConfig) -> Problem:
    if not is_head_name(d.model) and not d.model.lower().endswith(MODEL_SUFFIXES):
        names = ", ".join(f'"{n}"' for n in (DEFAULT_MODEL, *SHIPPED_HEADS))
        return "model", f"expected {names} or a path ending in {', '.join(MODEL_SUFFIXES)}"
    if d.ds not in VALID_DS:
        return "ds", f"expected one of {', '.join(map(str, VALID_DS))} (vSTMD pooling factor)"
    if d.topn < 1:
        return "topn", "expected an integer >= 1"
    if not 0.0 <= d.colour_share <= 1.0:
        return "colour_share", "expected a number in [0, 1]"
    if not d.crop_scales or any(not 0.0 < s <= MAX_CROP_SCALE for s in d.crop_scales):
        return "crop_scales", f"expected a list of numbers in (0, {MAX_CROP_SCALE:g}]"
    if not 0.0 <= d.score_threshold <= 1.0:
        return "score_threshold", "expected a number in [0, 1]"
    if isinstance(d.orientations, bool) or d.orientations not in ORIENTATION_COUNTS:
        return "orientations", f"expected one of {', '.join(map(str, ORIENTATION_COUNTS))}"
    if d.refine_threshold is not None and not 0.0 <= d.refine_threshold <= 1.0:
        return "refine_threshold", "expected a number in [0, 1]"
    if not 0.0 <= d.person_m <= 10.0:
        return "person_m", "expected metres in [0, 10] (0: crops as at the survey's ranges)"
    if not 0.0 <= d.range_shift <= 10.0:
        return "range_shift", "expected a number in [0, 10]"
    return None


def lock_problem(lock: LockConfig) -> Problem:
    if not 0.0 <= lock.min_score <= 1.0:
        return "min_score", "expected a number in [0, 1]"
    if not 1 <= lock.m <= lock.k:
        return "m/k", f"expected 1 <= m <= k, got m={lock.m}, k={lock.k}"
    return None


def actions_problem(a: ActionsConfig) -> Problem:
    return _policy_problem(a.policy) or _action_limits_problem(a)


def _policy_problem(policy: list[str]) -> Problem:
    for p in policy:
        if p not in ACTION_POLICIES:
            return "policy", f"unknown action '{p}' (expected any of {', '.join(ACTION_POLICIES)})"
    if "loiter" in policy and "mission" in policy:
        return "policy", "loiter and mission both move the aircraft: choose one"
    return None


def _action_limits_problem(a: ActionsConfig) -> Problem:
    if a.retries < 0 or a.ack_timeout_s <= 0:
        return "retries/ack_timeout_s", "expected retries >= 0 and a positive timeout"
    if not a.roi_hold_s > 0:
        return "roi_hold_s", "expected a positive number of seconds"
    if not 1 <= a.statustext_repeats <= 20:
        return "statustext_repeats", "expected an integer from 1 to 20"
    if not 0 < a.statustext_repeat_interval_s <= 60:
        return "statustext_repeat_interval_s", "expected seconds above 0 and at most 60"
    for key in ("max_error_m", "visit_loiter_s"):
        if not getattr(a, key) > 0:
            return key, "expected a positive number"
    for key in ("area_margin_m", "visit_interval_s", "visit_group_radius_m"):
        if getattr(a, key) < 0:
            return key, "expected a number >= 0"
    if not 0 <= a.min_confidence < 1:
        return "min_confidence", "expected a probability from 0 (every target) up to below 1"
    if a.loiter_altitude_m is not None and not 0 < a.loiter_altitude_m <= MAX_LOITER_ALTITUDE_M:
        return "loiter_altitude_m", (
            f"expected a height above home above 0 and at most {MAX_LOITER_ALTITUDE_M:g} m "
            "(sent to the autopilot as the visit's altitude)"
        )
    return None


#: Highest visit altitude sent to the autopilot (metres above home).
MAX_LOITER_ALTITUDE_M = 1000.0


def telemetry_problem(t: TelemetryConfig) -> Problem:
    for key in ("gnss_noise_m", "attitude_noise_deg", "latency_s"):
        if getattr(t, key) < 0:
            return key, "expected a number >= 0"
    if t.stale_after_s <= 0 or t.gnss_noise_tau_s <= 0:
        return "stale_after_s/gnss_noise_tau_s", "expected positive numbers"
    return None


def confirm_problem(c: ConfirmConfig) -> Problem:
    if c.min_sightings < 1 or not c.min_seen_s >= 0 or not c.give_up_s > c.min_seen_s:
        return (
            "min_sightings/min_seen_s/give_up_s",
            "expected min_sightings >= 1, min_seen_s >= 0 and give_up_s > min_seen_s",
        )
    if (
        not 0 < c.min_size_m < c.max_size_m
        or c.max_speed_m_s < 0
        or not 0 <= c.min_score <= 1
        or not 0 <= c.min_seen_share <= 1
    ):
        return (
            "sizes/speed/score",
            "expected 0 < min_size_m < max_size_m, max_speed_m_s >= 0, min_score 0-1",
        )
    if not (c.max_extent_m == 0 or c.max_extent_m >= c.max_size_m):
        return "max_extent_m", "expected 0 (not measured) or at least max_size_m"
    if not 0 <= c.score_window_s <= c.give_up_s:
        return "score_window_s", "expected 0 (all sightings) up to give_up_s"
    if not 0 <= c.min_look_change < 1:
        return "min_look_change", "expected 0 (not asked) up to below 1"
    return None


def geolocation_problem(g: GeolocationConfig) -> Problem:
    if g.min_height_m < 0:
        return "min_height_m", "expected a number >= 0"
    if not 0 < g.max_off_nadir_deg <= 90:
        return "max_off_nadir_deg", "expected a number in (0, 90]"
    if not g.max_error_m > 0:
        return "max_error_m", "expected a positive number"
    return None


def alerts_problem(a: AlertsConfig) -> Problem:
    for i, url in enumerate(a.cot):
        try:
            parse_cot_url(url)
        except SarmissionError as exc:
            return f"cot[{i}]", str(exc)
    return None


def mission_id_problem(value: str) -> str | None:
    """Why ``value`` cannot name a mission, or None. The name (or ``--mission-id``) is the id
    the alerts are stored under and goes into every CoT event and KML export, which are XML:
    a control character there makes them invalid, so only printable characters are taken."""
    bad = [c for c in value if not c.isprintable()]
    if bad:
        return f"expected printable characters only, got {bad[0]!r} in {value!r}"
    return None


#: Section name -> its rule, in the order they are checked. Sections without rules ([sim])
#: only need values of the right type.
SECTION_RULES: dict[str, Callable[[Any], Problem]] = {
    "area": area_problem,
    "flight": flight_problem,
    "camera": camera_problem,
    "detector": detector_problem,
    "lock": lock_problem,
    "actions": actions_problem,
    "telemetry": telemetry_problem,
    "confirm": confirm_problem,
    "geolocation": geolocation_problem,
    "alerts": alerts_problem,
}
