"""Telemetry for offline replay, pushed into a :class:`TelemetryBuffer` in the frames' clock.

:func:`telemetry_source` picks what ``sarmission replay`` uses: nothing (alerts then carry
frame, time and pixel and no position: nothing is invented), a real flight log
(:mod:`sarmission.flightlog`, aligned with the footage), the dataset's meta, or the mission's
simulated flight only when asked for (``--telemetry sim``). Beside flight logs, two sources:

- a dataset's per-frame ``meta``, read with the file's conventions
  (:mod:`sarmission.data.meta_conventions`: the gimbal pitch's sign, height above take-off,
  headings from north) into a :class:`~sarmission.data.meta_conventions.MetaPose`: position,
  vehicle yaw from the compass heading, and the gimbal's earth-frame attitude. Roll and pitch of
  the vehicle are not in the data and are taken as level, which does not matter for an
  earth-stabilised gimbal. Home is the first frame's position at the take-off's altitude above
  sea level when the user gives it (``--takeoff-alt``), else at 0: meta heights are above
  take-off, so without it the ground plane is the take-off's (:func:`meta_ground`).
  A frame whose meta cannot place the camera (:class:`~sarmission.data.meta_conventions.NoMetaPose`)
  has no position, for the reason it gives (warned about at most every few seconds), and is
  never given a neighbour's.
- an exact flight state (anything with ``position_ned``, ``velocity_ned``, ``vehicle_rpy``,
  ``gimbal_rpy`` and ``gimbal_frame``, such as the simulator's ``VehicleState``) in the NED frame
  of the mission's home.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sarmission.data.meta_conventions import MetaConventions, MetaPose, NoMetaPose
from sarmission.flightlog.align import Alignment, AlignmentError, align_images, align_video
from sarmission.flightlog.detect import open_flight_log
from sarmission.flightlog.feed import LogFeeder
from sarmission.flightlog.model import FlightLog, FlightLogError
from sarmission.flightlog.video_time import creation_time
from sarmission.geo.geolocate import PlatformPose
from sarmission.geo.wgs84 import ned_to_geodetic
from sarmission.mavlink.telemetry import StaleTelemetry, TelemetryBuffer
from sarmission.ratelimit import RateLimitedLog

log = logging.getLogger(__name__)


def push_frame_telemetry(
    buffer: TelemetryBuffer, t: float, pose: MetaPose, takeoff_alt_m: float = 0.0
) -> None:
    """Push one frame's placement from dataset meta at time ``t``; sets home from the first
    frame pushed, at ``takeoff_alt_m`` (metres above sea level of the take-off, which meta
    heights are measured from; 0 when unknown: the ground plane is then the take-off's)."""
    if buffer.home is None:
        buffer.set_home(pose.latitude, pose.longitude, takeoff_alt_m)
    buffer.push_position(t, pose.latitude, pose.longitude, pose.height_m)
    buffer.push_attitude(t, 0.0, 0.0, math.radians(pose.heading_deg))
    buffer.push_gimbal(
        t,
        (
            math.radians(pose.gimbal_roll_deg),
            math.radians(pose.gimbal_pitch_deg),
            math.radians(pose.gimbal_heading_deg),
        ),
        "earth",
    )


def frame_pose(pose: MetaPose) -> PlatformPose:
    """One frame's placement as a replay looks it up, alone: pushed into a fresh buffer (home
    at the frame's own position) and read back at its own time. For tools and checks that
    geolocate single frames of a dataset the way ``sarmission replay`` does."""
    buffer = TelemetryBuffer()
    push_frame_telemetry(buffer, 0.0, pose)
    found = buffer.lookup(0.0)
    assert isinstance(found, PlatformPose), found  # a fresh buffer, read at its only sample
    return found


class MetaReplayTelemetry:
    """The telemetry of a replay from dataset meta: ``buffer`` holds the placed frames; a frame
    whose meta placed nothing answers its own reason instead of an interpolated neighbour.
    Everything else is the buffer's."""

    def __init__(self, buffer: TelemetryBuffer) -> None:
        self.buffer = buffer
        self.refused: dict[float, str] = {}
        self.warn = RateLimitedLog(log, 5.0)

    def refuse(self, t: float, reason: str) -> None:
        """Frame time ``t`` has no position, because of ``reason`` (one line)."""
        self.refused[t] = reason
        self.warn.event(reason, "dataset meta at t=%.2f s: %s; no position", t, reason)

    def lookup(self, t: float) -> PlatformPose | StaleTelemetry:
        reason = self.refused.get(t)
        if reason is not None:
            return StaleTelemetry(t, f"dataset meta: {reason}")
        return self.buffer.lookup(t)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.buffer, name)


def push_flight_state(
    buffer: TelemetryBuffer, t: float, state: Any, home: tuple[float, float, float]
) -> None:
    """Push an exact flight state (NED metres from ``home``) at time ``t``."""
    if buffer.home is None:
        buffer.set_home(*home)
    n, e, d = (float(v) for v in state.position_ned)
    lat, lon, _ = ned_to_geodetic(n, e, 0.0, *home)
    buffer.push_position(
        t,
        float(lat),
        float(lon),
        -d,
        alt_m=home[2] - d,
        velocity_ned=tuple(float(v) for v in state.velocity_ned),
    )
    buffer.push_attitude(t, *state.vehicle_rpy)
    buffer.push_gimbal(t, state.gimbal_rpy, state.gimbal_frame)


# -- sources for `sarmission replay` ---------------------------------------------------------
#: Spacing of the drone track kept for the report (seconds).
TRACK_STEP_S = 0.5


class NoTelemetry(TelemetryBuffer):
    """The buffer of a replay without telemetry: every lookup says so, nothing is invented."""

    REASON = "no telemetry"

    def __init__(self, reason: str = REASON) -> None:
        super().__init__()
        self.reason = reason

    def lookup(self, t: float) -> PlatformPose | StaleTelemetry:
        return StaleTelemetry(t, self.reason)


@dataclass
class ReplaySource:
    """Where a replay's telemetry comes from, and how frames map onto its clock.

    ``description`` follows "telemetry: " on the console, ``lines`` say more (alignment,
    what a log lacks). ``timestamp(frame_t, name)`` is the controller's clock for a frame
    (the log's clock for a flight log), ``before(buffer, t, meta)`` pushes what the frame
    needs. ``utc_offset_s`` turns the controller's clock into POSIX seconds when known.
    """

    description: str
    lines: list[str] = field(default_factory=list)
    kind: str = "none"  # "none", "meta", "sim", "log"
    flight: Any = None
    log: FlightLog | None = None
    alignment: Alignment | None = None
    feeder: LogFeeder | None = None
    utc_offset_s: float | None = None
    #: why a replay without telemetry has none (each alert's "position unknown" says it)
    none_reason: str = NoTelemetry.REASON
    #: ``(t, lat, lon)`` of the drone at the replayed frames, every TRACK_STEP_S
    flown: list[tuple[float, float, float]] = field(default_factory=list)
    #: dataset meta: the take-off's altitude above sea level, when the user gives it
    takeoff_alt_m: float | None = None

    def timestamp(self, frame_t: float, name: str | None = None) -> float:
        """The controller's time of a frame at ``frame_t`` in the footage."""
        if self.alignment is not None:
            return self.alignment.log_time(frame_t, name)
        return frame_t

    def buffer(self, make: Callable[[], TelemetryBuffer]) -> TelemetryBuffer:
        """The telemetry buffer for this source (``make`` builds the mission's)."""
        if self.kind == "none":
            return NoTelemetry(self.none_reason)
        buf = make()
        if self.log is not None:
            self.feeder = LogFeeder(self.log, buf)
        if self.kind == "meta":
            return MetaReplayTelemetry(buf)  # type: ignore[return-value]
        return buf

    def before(
        self,
        buffer: TelemetryBuffer,
        t: float,
        meta: MetaPose | NoMetaPose | None,
        home: tuple[float, float, float],
    ) -> None:
        """Push the telemetry frame time ``t`` (controller clock) needs; note the drone's
        position there for the track."""
        if self.kind == "meta" and isinstance(buffer, MetaReplayTelemetry):
            if isinstance(meta, MetaPose):
                push_frame_telemetry(buffer.buffer, t, meta, self.takeoff_alt_m or 0.0)
            else:
                buffer.refuse(t, meta.reason if meta is not None else "frame has no meta")
        elif self.kind == "sim" and self.flight is not None:
            push_flight_state(buffer, t, self.flight.state_at(t), home)
        elif self.feeder is not None:
            self.feeder.advance(t)

        if self.kind != "none" and (not self.flown or t - self.flown[-1][0] >= TRACK_STEP_S):
            pose = buffer.lookup(t)
            if isinstance(pose, PlatformPose):
                self.flown.append((t, pose.lat, pose.lon))


def telemetry_source(
    choice: str,
    *,
    input_path: Path,
    is_video: bool,
    names: list[str],
    fps: float,
    duration_s: float | None,
    with_meta: bool,
    offset_s: float | None,
    mission: Any,
    meta_conventions: MetaConventions | str | None = None,
) -> ReplaySource:
    """The replay's telemetry for ``--telemetry choice`` (auto, none, meta, sim or a file).

    ``auto`` takes the dataset's meta, else a DJI sidecar beside the video (``clip.SRT``), else
    nothing. A flight log that cannot be read or aligned gives one line and no telemetry.
    ``meta_conventions``: how the dataset's meta reads, or the one line saying why it cannot be
    read (mixed conventions): then no telemetry from it.
    """
    if isinstance(meta_conventions, str) and choice in ("meta", "auto"):
        return ReplaySource(
            f"none: dataset meta not used: {meta_conventions}",
            none_reason="dataset meta in mixed conventions",
        )
    if choice == "meta" and not with_meta:
        raise ValueError(
            f"{input_path}: no per-frame telemetry (meta with latitude, longitude, "
            "height above take-off, gimbal pitch and heading) to replay; use "
            "--telemetry sim"
        )
    if choice in ("meta", "auto") and with_meta:
        lines = (
            [f"meta read as: {meta_conventions.describe()}"]
            if isinstance(meta_conventions, MetaConventions)
            else []
        )
        return ReplaySource("dataset meta", lines=lines, kind="meta")
    if choice in ("sim", "flight"):
        from sim.flight import Flight

        return ReplaySource(
            "simulated flight of the mission (positions are the simulator's, not the footage's)",
            kind="sim",
            flight=Flight(mission),
        )
    if choice == "none":
        return ReplaySource("none (alerts carry frame, time and pixel, no position)")
    path: Path | None = Path(choice) if choice != "auto" else _sidecar(input_path)
    if path is None:
        return ReplaySource(
            "none given (alerts carry frame, time and pixel, no position; "
            "--telemetry FILE reads a flight log)"
        )
    return _log_source(path, input_path, is_video, names, fps, duration_s, offset_s)


def _sidecar(video: Path) -> Path | None:
    for suffix in (".SRT", ".srt"):
        candidate = video.with_suffix(suffix)
        if video.is_file() and candidate.is_file():
            return candidate
    return None


def _log_source(
    path: Path,
    input_path: Path,
    is_video: bool,
    names: list[str],
    fps: float,
    duration_s: float | None,
    offset_s: float | None,
) -> ReplaySource:
    try:
        log = open_flight_log(path)
    except FlightLogError as exc:
        return ReplaySource(f"none: {exc}")
    lines = [log.summary(), f"home: {_home_text(log)}"] + log.notes
    try:
        if is_video:
            alignment = align_video(
                log, created=creation_time(input_path), duration_s=duration_s, offset_s=offset_s
            )
        else:
            alignment = align_images(log, names, fps, offset_s)
    except AlignmentError as exc:
        return ReplaySource(f"none: {exc}", lines=lines)
    lines.append(f"alignment: {alignment.method}")
    return ReplaySource(
        f"{log.fmt} {path.name}",
        lines=lines,
        kind="log",
        log=log,
        alignment=alignment,
        utc_offset_s=log.utc_offset_s,
    )


def _home_text(log: FlightLog) -> str:
    if log.home is None:
        return "unknown"
    lat, lon, alt = log.home
    alt_text = f"{alt:.1f} m AMSL" if math.isfinite(alt) else "altitude unknown"
    return f"{lat:.7f}, {lon:.7f}, {alt_text} ({log.home_note})"


def meta_ground(source: ReplaySource, mission: Any, takeoff_alt_m: float | None, dem: bool) -> Any:
    """The mission a replay geolocates with, and the take-off altitude its source uses.

    Dataset meta gives heights above take-off, not above sea level, while a mission's
    ``ground_alt_m`` and a terrain model are above sea level. With ``takeoff_alt_m`` (metres
    above sea level) the two agree. Without it a terrain model cannot be used (ValueError) and
    the mission's ``ground_alt_m`` is left out, with a line in ``source.lines``: the ground
    plane is the take-off's. ``takeoff_alt_m`` with telemetry other than meta is a ValueError:
    a flight log or the simulated flight carries its own home altitude.
    """
    if source.kind != "meta":
        if takeoff_alt_m is not None:
            raise ValueError(
                "--takeoff-alt places a dataset's meta heights; this replay's telemetry is "
                f"{source.description}, which carries its own home altitude"
            )
        return mission
    if takeoff_alt_m is not None:
        if not math.isfinite(takeoff_alt_m) or not -500.0 <= takeoff_alt_m <= 9000.0:
            raise ValueError(
                f"--takeoff-alt must be metres above sea level, -500 to 9000, got {takeoff_alt_m}"
            )
        source.takeoff_alt_m = float(takeoff_alt_m)
        source.lines.append(f"take-off at {takeoff_alt_m:g} m above sea level (--takeoff-alt)")
        return mission
    if dem:
        raise ValueError(
            "--dem with dataset meta needs --takeoff-alt M (the take-off's altitude above sea "
            "level): meta heights are above take-off, the terrain above sea level"
        )
    ground = mission.area.ground_alt_m
    if ground is None:
        return mission
    source.lines.append(
        f"the mission's ground_alt_m ({ground:g} m above sea level) is not used: meta heights are "
        "above take-off, so the ground plane is the take-off's (--takeoff-alt M places it)"
    )
    return dataclasses.replace(mission, area=dataclasses.replace(mission.area, ground_alt_m=None))
