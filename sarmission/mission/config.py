"""Mission file (TOML) -> typed configuration, with precedence code defaults < file < overrides.

A mission file has the sections ``[area]``, ``[flight]``, ``[camera]``, ``[detector]``, ``[lock]``,
``[actions]``, ``[telemetry]``, ``[geolocation]``, ``[confirm]``, ``[alerts]`` and ``[sim]``; every
key is optional and falls back to the default of the dataclass below. Unknown sections or keys, and
values of the wrong type, raise :class:`MissionConfigError` naming the file, the key and what was
expected.

Overrides (from the command line) are dotted keys: ``{"flight.altitude_m": 80}`` or the strings
``"flight.altitude_m=80"`` parsed by :func:`parse_override` (the value is TOML: ``80``,
``"alert"``, ``["alert", "roi"]``, ``true``; a bare word is taken as a string).

Example::

    [area]
    home_lat = 54.1700
    home_lon = 7.8900
    rectangle_m = [40.0, -120.0, 240.0, 120.0]   # north_min, east_min, north_max, east_max
    leg_spacing_m = 60.0
    heading_deg = 90.0                            # legs run east-west

    [flight]
    altitude_m = 70.0
    speed_m_s = 10.0
"""

from __future__ import annotations

import copy
import dataclasses
import math
import tomllib
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sarmission.errors import SarmissionError
from sarmission.geo.camera import CameraIntrinsics
from sarmission.mission.config_rules import ACTION_POLICIES as ACTION_POLICIES
from sarmission.mission.config_rules import DEFAULT_MODEL, SECTION_RULES, mission_id_problem
from sarmission.models import CONFIRM_MIN_SCORE, DEFAULT_HEAD, is_head_name
from sarmission.perception.types import (
    DEFAULT_COLOUR_SHARE,
    DEFAULT_CROP_SCALES,
)


class MissionConfigError(SarmissionError):
    """A mission file or override that cannot be used; the message names file, key and problem."""


@dataclass
class AreaConfig:
    """Search area and lawnmower pattern.

    Home is the NED origin (``home_alt_m`` AMSL metres). The area is one of ``rectangle_m``
    (``[north_min, east_min, north_max, east_max]`` metres from home), ``polygon_m``
    (``[[north, east], ...]`` metres) or ``polygon_latlon`` (``[[lat, lon], ...]`` degrees).
    Legs run along ``heading_deg`` (clockwise from north) and are ``leg_spacing_m`` apart.
    ``ground_alt_m`` (AMSL) is the ground plane for geolocation; unset means home altitude.
    """

    home_lat: float = 54.17
    home_lon: float = 7.89
    home_alt_m: float = 0.0
    rectangle_m: tuple[float, ...] | None = None
    polygon_m: list[list[float]] | None = None
    polygon_latlon: list[list[float]] | None = None
    leg_spacing_m: float = 60.0
    heading_deg: float = 0.0
    ground_alt_m: float | None = None

    @property
    def ground_down_m(self) -> float:
        """Ground plane as NED down (metres below home; 0 when ``ground_alt_m`` is unset)."""
        return 0.0 if self.ground_alt_m is None else self.home_alt_m - self.ground_alt_m

    def polygon_ne(self) -> list[tuple[float, float]]:
        """The area as (north, east) metres from home, whichever way the file gave it."""
        if self.polygon_m is not None:
            return [(float(p[0]), float(p[1])) for p in self.polygon_m]
        if self.polygon_latlon is not None:
            from sarmission.geo.wgs84 import geodetic_to_ned

            lat = [p[0] for p in self.polygon_latlon]
            lon = [p[1] for p in self.polygon_latlon]
            n, e, _ = geodetic_to_ned(lat, lon, self.home_alt_m, *self.home)
            return [(float(a), float(b)) for a, b in zip(n, e, strict=True)]
        n0, e0, n1, e1 = self.rectangle_m or (40.0, -100.0, 200.0, 100.0)
        return [(n0, e0), (n0, e1), (n1, e1), (n1, e0)]

    @property
    def home(self) -> tuple[float, float, float]:
        """``(lat_deg, lon_deg, alt_m)`` of home, the NED origin."""
        return self.home_lat, self.home_lon, self.home_alt_m


@dataclass
class FlightConfig:
    """Survey flight: altitude above home, cruise speed, climb rate, turn acceleration.

    ``takeoff = false`` starts the flight already at altitude at the first leg (short demos).
    """

    altitude_m: float = 70.0
    speed_m_s: float = 10.0
    climb_rate_m_s: float = 4.0
    max_accel_m_s2: float = 2.5
    max_lateral_accel_m_s2: float = 3.0
    takeoff: bool = True


@dataclass
class CameraConfig:
    """Camera sensor and mount. Calibration (fx, fy, cx, cy, distortion) overrides ``hfov_deg``.

    ``mount_pitch_deg`` is the fixed (or default gimbal) pitch: -90 nadir, 0 horizon.
    ``gimbal = true``: a stabilised gimbal reporting GIMBAL_DEVICE_ATTITUDE_STATUS; false: a hard
    mount fixed to the body (no gimbal messages, the camera tilts with the vehicle).
    ``gimbal_component`` / ``gimbal_device_id``: the gimbal whose attitude is the camera's
    (its MAVLink component, e.g. 154, or the autopilot's for a gimbal it drives; its
    ``gimbal_device_id``); unset: the first gimbal heard. Others are ignored.
    """

    width: int = 3840
    height: int = 2160
    hfov_deg: float = 70.0
    mount_pitch_deg: float = -90.0
    gimbal: bool = True
    gimbal_component: int | None = None
    gimbal_device_id: int | None = None
    fx: float | None = None
    fy: float | None = None
    cx: float | None = None
    cy: float | None = None
    distortion: tuple[float, ...] = ()

    def describe(self) -> str:
        """The lens in one line, for a replay's console: positions are only as right as it."""
        if self.fx is not None:
            return f"calibrated, fx {self.fx:g} px at {self.width}x{self.height}"
        return f"{self.hfov_deg:g} degrees across at {self.width}x{self.height}"

    def intrinsics(self) -> CameraIntrinsics:
        """Calibrated intrinsics if fx is given, else the ideal pinhole from ``hfov_deg``."""
        if self.fx is None:
            base = CameraIntrinsics.from_hfov(self.width, self.height, self.hfov_deg)
            return dataclasses.replace(base, distortion=tuple(self.distortion))
        fy = self.fy if self.fy is not None else self.fx
        cx = self.cx if self.cx is not None else (self.width - 1) / 2.0
        cy = self.cy if self.cy is not None else (self.height - 1) / 2.0
        return CameraIntrinsics(self.width, self.height, self.fx, fy, cx, cy, self.distortion)


@dataclass
class DetectorConfig:
    """MITE-Net run-time settings: vSTMD down-sampling ``ds``, proposals ``topn`` (of which the
    share ``colour_share`` comes from colour anomalies), the head's ``crop_scales`` and the
    first-crop score from which a proposal gets the further ones, ``refine_threshold`` (None: the
    detection threshold; see :class:`~sarmission.perception.mitenet.MiteNet`), whether a
    proposal is cropped again where the head placed the target, ``recentre`` (off: measured in
    docs/recentring.md), in how many ``orientations`` each would-be detection is scored (1, 4
    or 8, averaged; off: docs/experiments.md), whether each box is fitted to the object
    against its surroundings, ``fit_boxes`` (docs/box_fit.md), the detection threshold;
    crops sized to a person ``person_m`` across from the autopilot's pose, their logits lowered
    by ``range_shift`` per doubling (0: off; docs/range_crops.md);
    ``model`` the head: a
    shipped one by name (``"default"`` or ``"maritime"``, ``"land"``: :mod:`sarmission.models`) or a
    ``.pt``/``.pth``/``.onnx`` file, relative to the mission file's folder when written there (a
    head fine-tuned for the area's sea or land goes with its mission)."""

    model: str = DEFAULT_MODEL
    ds: int = 2
    topn: int = 25
    colour_share: float = DEFAULT_COLOUR_SHARE
    crop_scales: tuple[float, ...] = DEFAULT_CROP_SCALES
    refine_threshold: float | None = None
    recentre: bool = False
    orientations: int = 1
    fit_boxes: bool = True
    score_threshold: float = 0.3
    person_m: float = 0.0
    range_shift: float = 0.0


@dataclass
class LockConfig:
    """m-of-k confirmation: a track locks when matched in ``m`` of the last ``k`` frames by a
    detection scored at least ``min_score`` (lower-scored ones keep the track alive but do not
    count, as in the evaluation's lock)."""

    m: int = 3
    k: int = 5
    min_score: float = 0.5


@dataclass
class ActionsConfig:
    """What to do with a confirmed target, in order: ``alert`` (STATUSTEXT), ``loiter``
    (DO_REPOSITION to the target), ``roi`` (DO_SET_ROI_LOCATION), ``mission`` (upload a mission
    item to the target). Every command waits ``ack_timeout_s`` for its ACK, ``retries`` times.
    After ``roi_hold_s`` seconds on the newest target the camera is released (DO_SET_ROI_NONE)
    so that the search goes on at the survey view (a long hold keeps it on the target).
    STATUSTEXT has no acknowledgement, so the alert is sent ``statustext_repeats`` times,
    ``statustext_repeat_interval_s`` apart: with 30 % independent loss 5 sends reach the
    autopilot 99.8 % of the time (1 - 0.3^5; 4 would give 99.2 %, little margin for bursts).
    Commands that move the aircraft (``loiter``, ``mission``; also ``roi``) go only to targets
    whose position error is at most ``max_error_m`` and that lie inside the area or within
    ``area_margin_m`` of it; ``loiter`` and ``mission`` follow one visit plan, at most one move
    every ``visit_interval_s``, nearest target first, targets within ``visit_group_radius_m``
    of it covered by the same visit; ``mission`` loiters ``visit_loiter_s`` at each. With
    ``min_confidence`` above 0 they also go only to targets at least that likely to be a person
    (:mod:`sarmission.mission.confidence`; an alert without a confidence, e.g. one an operator
    confirmed, is not held back): the aircraft is not sent to debris the head called a
    swimmer. A target held back is visited once the operator's decisions rate it likely
    enough."""

    policy: list[str] = field(default_factory=lambda: ["alert"])
    retries: int = 3
    ack_timeout_s: float = 1.5
    loiter_altitude_m: float | None = None
    roi_hold_s: float = 10.0
    statustext_repeats: int = 5
    statustext_repeat_interval_s: float = 1.0
    max_error_m: float = 25.0
    area_margin_m: float = 200.0
    visit_interval_s: float = 60.0
    visit_group_radius_m: float = 30.0
    visit_loiter_s: float = 30.0
    min_confidence: float = 0.0


@dataclass
class TelemetryConfig:
    """Telemetry quality (simulated noise) and staleness limit for geolocation."""

    gnss_noise_m: float = 0.8
    gnss_noise_tau_s: float = 2.0
    attitude_noise_deg: float = 0.3
    latency_s: float = 0.05
    stale_after_s: float = 1.0


@dataclass
class ConfirmConfig:
    """When a locked candidate becomes a confirmed alert (:mod:`sarmission.mission.confirmation`):
    seen for ``min_seen_s`` in ``min_sightings`` geolocated frames, at least ``min_seen_share``
    of the frames since its first sighting, drifting no faster than ``max_speed_m_s``,
    ``min_size_m``-``max_size_m`` across the line of sight, the object under it (measured against
    its surroundings: :mod:`sarmission.perception.extent`) at most ``max_extent_m`` across (0:
    not measured), its scores' mean at least ``min_score``; discarded if not confirmed within
    ``give_up_s``. ``score_window_s`` > 0 judges the score over the latest seconds only and
    lets a low one wait for a better view instead of discarding it (0: the mean of all
    sightings, decided once). ``min_look_change`` > 0 keeps a candidate whose look stays the
    same over a second (:mod:`sarmission.perception.look`) waiting (0: not asked). The
    defaults were chosen on the development scenarios
    (``tools/candidate_features.py``, ``tools/confirmation_rules.py``), ``min_seen_s``,
    ``min_seen_share`` and ``min_score`` on held-out validation clips (``tools/heldout_alerts.py
    --split validation``), never on the scored suite or a test clip. ``max_extent_m`` was 3 m
    on the held-out validation clips (``tools/object_extent_study.py``) and is 4 m since a
    test flight showed 3 m cutting a swimmer merged with a foam streak (docs/experiments.md).
    ``min_score`` is the maritime head's; a mission that leaves it unset and flies another
    shipped head takes that head's (:data:`sarmission.models.CONFIRM_MIN_SCORE`), since each
    head's scores run on their own scale."""

    min_seen_s: float = 2.0
    min_sightings: int = 20
    min_seen_share: float = 0.3
    max_speed_m_s: float = 1.5
    min_size_m: float = 0.15
    max_size_m: float = 2.5
    max_extent_m: float = 4.0
    min_score: float = CONFIRM_MIN_SCORE[DEFAULT_HEAD]
    give_up_s: float = 20.0
    score_window_s: float = 0.0
    min_look_change: float = 0.0


@dataclass
class GeolocationConfig:
    """When a fix may be computed: only while the drone is at least ``min_height_m`` above the
    ground plane (on the ground, or landing, everything in view is at the drone's own place),
    and only for a ray at most ``max_off_nadir_deg`` from straight down with an error estimate
    of at most ``max_error_m`` (grazing views: the alert says why it has no position)."""

    min_height_m: float = 5.0
    max_off_nadir_deg: float = 85.0
    max_error_m: float = 250.0


@dataclass
class AlertsConfig:
    """Where confirmed alerts go besides the autopilot and the feed: ``cot``, the team's TAK
    destinations (``udp://``, ``tcp://`` or ``tls://`` URLs, as ``run --cot`` takes them; the
    command line's are added to these)."""

    cot: list[str] = field(default_factory=list)


@dataclass
class SimConfig:
    """Simulator weather: mean wind (``wind_from_deg`` is where it blows from) and gusts."""

    wind_speed_m_s: float = 3.0
    wind_from_deg: float = 250.0
    gust_m_s: float = 1.5
    drag_per_s: float = 0.12


@dataclass
class MissionConfig:
    """A whole mission; ``source`` is the file it was read from (None for pure defaults)."""

    area: AreaConfig = field(default_factory=AreaConfig)
    flight: FlightConfig = field(default_factory=FlightConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    detector: DetectorConfig = field(default_factory=DetectorConfig)
    lock: LockConfig = field(default_factory=LockConfig)
    actions: ActionsConfig = field(default_factory=ActionsConfig)
    telemetry: TelemetryConfig = field(default_factory=TelemetryConfig)
    geolocation: GeolocationConfig = field(default_factory=GeolocationConfig)
    confirm: ConfirmConfig = field(default_factory=ConfirmConfig)
    alerts: AlertsConfig = field(default_factory=AlertsConfig)
    sim: SimConfig = field(default_factory=SimConfig)
    name: str = "mission"
    source: str | None = None
    #: The ``section.key`` settings the file or an override gave (the rest are defaults).
    explicit: set[str] = field(default_factory=set, compare=False, repr=False)

    def as_dict(self) -> dict[str, Any]:
        """Plain nested dict of the effective values (for ``--help`` and logs)."""
        values = dataclasses.asdict(self)
        values.pop("explicit")
        return values


_SECTIONS: dict[str, type] = {
    k: v
    for k, v in typing.get_type_hints(MissionConfig).items()
    if k not in ("name", "source", "explicit")
}


def _type_name(tp: Any) -> str:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        return " or ".join(_type_name(a) for a in args)
    if origin in (list, tuple):
        inner = typing.get_args(tp)[0]
        return f"array of {_type_name(inner)}"
    return {float: "number", int: "integer", str: "string", bool: "boolean"}.get(tp, str(tp))


def _describe(value: Any) -> str:
    kind = {
        bool: "boolean",
        int: "integer",
        float: "number",
        str: "string",
        list: "array",
        dict: "table",
    }.get(type(value), type(value).__name__)
    text = repr(value)
    return f"{kind} {text[:40] + '...' if len(text) > 43 else text}"


def _coerce(value: Any, tp: Any, where: str) -> Any:
    """Check ``value`` against annotation ``tp`` (int promotes to float); raise with ``where``."""
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        return _coerce_union(value, tp, where)
    if origin in (list, tuple):
        if not isinstance(value, list | tuple):
            raise MissionConfigError(f"{where}: expected {_type_name(tp)}, got {_describe(value)}")
        inner = typing.get_args(tp)[0]
        items = [_coerce(v, inner, f"{where}[{i}]") for i, v in enumerate(value)]
        return tuple(items) if origin is tuple else items
    return _coerce_scalar(value, tp, where)


def _coerce_union(value: Any, tp: Any, where: str) -> Any:
    """``value`` as the first member of the union ``tp`` that takes it (None where allowed)."""
    args = typing.get_args(tp)
    if value is None and type(None) in args:
        return None
    for a in args:
        if a is type(None):
            continue
        try:
            return _coerce(value, a, where)
        except MissionConfigError:
            continue
    raise MissionConfigError(f"{where}: expected {_type_name(tp)}, got {_describe(value)}")


def _coerce_scalar(value: Any, tp: Any, where: str) -> Any:
    """``value`` as a finite float, an int, a bool or a str (no bool where a number is due)."""
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise MissionConfigError(f"{where}: expected number, got {_describe(value)}")
        if not math.isfinite(float(value)):
            raise MissionConfigError(f"{where}: expected a finite number, got {value!r}")
        return float(value)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise MissionConfigError(f"{where}: expected integer, got {_describe(value)}")
        return value
    if tp is bool or tp is str:
        if not isinstance(value, tp):
            raise MissionConfigError(f"{where}: expected {_type_name(tp)}, got {_describe(value)}")
        return value
    raise TypeError(f"unsupported annotation {tp!r}")


def _apply_section(obj: Any, values: Mapping[str, Any], section: str, origin: str) -> None:
    hints = typing.get_type_hints(type(obj))
    names = [f.name for f in dataclasses.fields(obj)]
    for key, value in values.items():
        where = f"{origin}: [{section}] {key}"
        if key not in names:
            raise MissionConfigError(
                f"{origin}: unknown key '{key}' in [{section}] (known: {', '.join(names)})"
            )
        setattr(obj, key, _coerce(value, hints[key], where))


def _apply(cfg: MissionConfig, data: Mapping[str, Any], origin: str) -> None:
    for section, values in data.items():
        if section == "name":
            cfg.name = _coerce(values, str, f"{origin}: name")
            continue
        if section not in _SECTIONS:
            raise MissionConfigError(
                f"{origin}: unknown section [{section}] (known: {', '.join(_SECTIONS)}, name)"
            )
        if not isinstance(values, Mapping):
            raise MissionConfigError(
                f"{origin}: [{section}] must be a table, got {_describe(values)}"
            )
        _apply_section(getattr(cfg, section), values, section, origin)
        cfg.explicit.update(f"{section}.{key}" for key in values)


def _validate(cfg: MissionConfig, origin: str) -> None:
    """Raise for a name that cannot be a mission id (:func:`mission_id_problem`), then for
    the first section that breaks its rule (:data:`SECTION_RULES`)."""
    problem = mission_id_problem(cfg.name)
    if problem is not None:
        raise MissionConfigError(f"{origin}: name: {problem}")
    for section, rule in SECTION_RULES.items():
        problem = rule(getattr(cfg, section))
        if problem is not None:
            key, expected = problem
            where = f"[{section}] {key}" if key else f"[{section}]"
            raise MissionConfigError(f"{origin}: {where}: {expected}")


def parse_override(text: str) -> tuple[str, Any]:
    """``"section.key=value"`` -> ``("section.key", value)`` with the value read as TOML."""
    if "=" not in text:
        raise MissionConfigError(f"override '{text}': expected section.key=value")
    key, raw = (s.strip() for s in text.split("=", 1))
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    return key, value


def _nest(overrides: Mapping[str, Any] | list[str]) -> dict[str, Any]:
    items = (
        [parse_override(o) for o in overrides]
        if isinstance(overrides, list)
        else list(overrides.items())
    )
    nested: dict[str, Any] = {}
    for key, value in items:
        if key == "name":
            nested["name"] = value
            continue
        if key.count(".") != 1:
            raise MissionConfigError(
                f"override '{key}': expected section.key (e.g. flight.altitude_m)"
            )
        section, name = key.split(".")
        nested.setdefault(section, {})[name] = value
    return nested


def load_mission(
    path: str | Path | None = None,
    overrides: Mapping[str, Any] | list[str] | None = None,
) -> MissionConfig:
    """Defaults, then the TOML file at ``path`` (if any), then ``overrides``; validated.

    ``overrides`` is a mapping of dotted keys to values or a list of ``"section.key=value"``.
    Raises :class:`MissionConfigError` on unreadable/invalid TOML, unknown keys, wrong types or
    out-of-range values.
    """
    cfg = MissionConfig()
    origin = "defaults"
    if path is not None:
        p = Path(path)
        origin = str(p)
        try:
            text = p.read_text(encoding="utf-8-sig")  # a byte-order mark is no TOML error
        except OSError as exc:
            raise MissionConfigError(f"{p}: cannot read mission file ({exc.strerror})") from exc
        except UnicodeDecodeError as exc:
            raise MissionConfigError(
                f"{p}: not UTF-8 text (byte {exc.start}: {exc.reason}); save it as UTF-8"
            ) from None
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise MissionConfigError(f"{p}: invalid TOML: {exc}") from exc
        cfg.name = p.stem
        cfg.source = str(p)
        _apply(cfg, data, origin)
        model = cfg.detector.model
        if not is_head_name(model) and not Path(model).is_absolute():
            cfg.detector.model = str(p.parent / model)
    if overrides:
        before = copy.deepcopy(cfg)
        _apply(cfg, _nest(overrides), f"{origin} (override)")
        try:
            _validate(cfg, origin)
        except MissionConfigError as exc:
            try:  # the file alone passes: the command line's value broke the rule
                _validate(before, origin)
            except MissionConfigError:
                raise exc from None
            raise MissionConfigError(
                str(exc).replace(f"{origin}: ", "command line (an option or --set): ", 1)
            ) from None
        return cfg
    _validate(cfg, origin)
    return cfg
