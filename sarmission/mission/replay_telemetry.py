"""Telemetry for offline replay, pushed into a :class:`TelemetryBuffer` in the frames' clock.

:func:`telemetry_source` picks what ``sarmission replay`` uses: nothing (alerts then carry
frame, time and pixel and no position: nothing is invented), a real flight log
(:mod:`sarmission.flightlog`, aligned with the footage), the dataset's meta, or the mission's
simulated flight only when asked for (``--telemetry sim``). Beside flight logs, two sources:

- a dataset's per-frame ``meta`` (:class:`~sarmission.data.coco_video.FrameTelemetry`,
  SeaDronesSee style): position (latitude, longitude, altitude above take-off), vehicle yaw from
  the compass heading, and the gimbal's earth-frame attitude (pitch from ``gimbal_pitch``,
  yaw from ``gimbal_heading``, else the compass heading; roll from ``gimbal_roll``). Roll and
  pitch of the vehicle are not in the data and are taken as level, which does not matter for an
  earth-stabilised gimbal. Home is the first frame's position at altitude 0 (take-off height).
- an exact flight state (anything with ``position_ned``, ``velocity_ned``, ``vehicle_rpy``,
  ``gimbal_rpy`` and ``gimbal_frame``, such as the simulator's ``VehicleState``) in the NED frame
  of the mission's home.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sarmission.data.coco_video import FrameTelemetry
from sarmission.flightlog.align import Alignment, AlignmentError, align_images, align_video
from sarmission.flightlog.detect import open_flight_log
from sarmission.flightlog.feed import LogFeeder
from sarmission.flightlog.model import FlightLog, FlightLogError
from sarmission.flightlog.video_time import creation_time
from sarmission.geo.geolocate import PlatformPose
from sarmission.geo.wgs84 import ned_to_geodetic
from sarmission.mavlink.telemetry import StaleTelemetry, TelemetryBuffer


def has_position(meta: FrameTelemetry) -> bool:
    """True when the frame's telemetry can place the camera (latitude, longitude, altitude)."""
    return None not in (meta.latitude, meta.longitude, meta.altitude)


def push_frame_telemetry(buffer: TelemetryBuffer, t: float, meta: FrameTelemetry) -> bool:
    """Push one frame's dataset telemetry at time ``t``; False (nothing pushed) when it lacks a
    position. Sets home from the first frame pushed."""
    if not has_position(meta):
        return False
    assert meta.latitude is not None and meta.longitude is not None and meta.altitude is not None
    if buffer.home is None:
        buffer.set_home(meta.latitude, meta.longitude, 0.0)
    buffer.push_position(t, meta.latitude, meta.longitude, meta.altitude)
    heading = math.radians(meta.compass_heading or 0.0)
    buffer.push_attitude(t, 0.0, 0.0, heading)
    if meta.gimbal_pitch is not None:
        gimbal_yaw = math.radians(meta.gimbal_heading) if meta.gimbal_heading is not None \
            else heading
        buffer.push_gimbal(t, (math.radians(meta.gimbal_roll or 0.0),
                               math.radians(meta.gimbal_pitch), gimbal_yaw), "earth")
    return True


def push_flight_state(buffer: TelemetryBuffer, t: float, state: Any,
                      home: tuple[float, float, float]) -> None:
    """Push an exact flight state (NED metres from ``home``) at time ``t``."""
    if buffer.home is None:
        buffer.set_home(*home)
    n, e, d = (float(v) for v in state.position_ned)
    lat, lon, _ = ned_to_geodetic(n, e, 0.0, *home)
    buffer.push_position(t, float(lat), float(lon), -d, alt_m=home[2] - d,
                         velocity_ned=tuple(float(v) for v in state.velocity_ned))
    buffer.push_attitude(t, *state.vehicle_rpy)
    buffer.push_gimbal(t, state.gimbal_rpy, state.gimbal_frame)


# -- sources for `sarmission replay` ---------------------------------------------------------
#: Spacing of the drone track kept for the report (seconds).
TRACK_STEP_S = 0.5


class NoTelemetry(TelemetryBuffer):
    """The buffer of a replay without telemetry: every lookup says so, nothing is invented."""

    REASON = "no telemetry"

    def lookup(self, t: float) -> PlatformPose | StaleTelemetry:
        return StaleTelemetry(t, self.REASON)


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
    #: ``(t, lat, lon)`` of the drone at the replayed frames, every TRACK_STEP_S
    flown: list[tuple[float, float, float]] = field(default_factory=list)

    def timestamp(self, frame_t: float, name: str | None = None) -> float:
        """The controller's time of a frame at ``frame_t`` in the footage."""
        if self.alignment is not None:
            return self.alignment.log_time(frame_t, name)
        return frame_t

    def buffer(self, make: Callable[[], TelemetryBuffer]) -> TelemetryBuffer:
        """The telemetry buffer for this source (``make`` builds the mission's)."""
        if self.kind == "none":
            return NoTelemetry()
        buf = make()
        if self.log is not None:
            self.feeder = LogFeeder(self.log, buf)
        return buf

    def before(self, buffer: TelemetryBuffer, t: float, meta: FrameTelemetry | None,
               home: tuple[float, float, float]) -> None:
        """Push the telemetry frame time ``t`` (controller clock) needs; note the drone's
        position there for the track."""
        if self.kind == "meta" and meta is not None:
            push_frame_telemetry(buffer, t, meta)
        elif self.kind == "sim" and self.flight is not None:
            push_flight_state(buffer, t, self.flight.state_at(t), home)
        elif self.feeder is not None:
            self.feeder.advance(t)

        if self.kind != "none" and (not self.flown or t - self.flown[-1][0] >= TRACK_STEP_S):
            pose = buffer.lookup(t)
            if isinstance(pose, PlatformPose):
                self.flown.append((t, pose.lat, pose.lon))


def telemetry_source(choice: str, *, input_path: Path, is_video: bool, names: list[str],
                     fps: float, duration_s: float | None, with_meta: bool,
                     offset_s: float | None, mission: Any) -> ReplaySource:
    """The replay's telemetry for ``--telemetry choice`` (auto, none, meta, sim or a file).

    ``auto`` takes the dataset's meta, else a DJI sidecar beside the video (``clip.SRT``), else
    nothing. A flight log that cannot be read or aligned gives one line and no telemetry.
    """
    if choice == "meta" and not with_meta:
        raise ValueError(f"{input_path}: no per-frame telemetry (meta with latitude, longitude "
                         "and altitude) to replay; use --telemetry sim")
    if choice in ("meta", "auto") and with_meta:
        return ReplaySource("dataset meta", kind="meta")
    if choice in ("sim", "flight"):
        from sim.flight import Flight

        return ReplaySource("simulated flight of the mission (positions are the simulator's, "
                            "not the footage's)", kind="sim", flight=Flight(mission))
    if choice == "none":
        return ReplaySource("none (alerts carry frame, time and pixel, no position)")
    path: Path | None = Path(choice) if choice != "auto" else _sidecar(input_path)
    if path is None:
        return ReplaySource("none given (alerts carry frame, time and pixel, no position; "
                            "--telemetry FILE reads a flight log)")
    return _log_source(path, input_path, is_video, names, fps, duration_s, offset_s)


def _sidecar(video: Path) -> Path | None:
    for suffix in (".SRT", ".srt"):
        candidate = video.with_suffix(suffix)
        if video.is_file() and candidate.is_file():
            return candidate
    return None


def _log_source(path: Path, input_path: Path, is_video: bool, names: list[str], fps: float,
                duration_s: float | None, offset_s: float | None) -> ReplaySource:
    try:
        log = open_flight_log(path)
    except FlightLogError as exc:
        return ReplaySource(f"none: {exc}")
    lines = [log.summary(), f"home: {_home_text(log)}"] + log.notes
    try:
        if is_video:
            alignment = align_video(log, created=creation_time(input_path),
                                    duration_s=duration_s, offset_s=offset_s)
        else:
            alignment = align_images(log, names, fps, offset_s)
    except AlignmentError as exc:
        return ReplaySource(f"none: {exc}", lines=lines)
    lines.append(f"alignment: {alignment.method}")
    return ReplaySource(f"{log.fmt} {path.name}", lines=lines, kind="log", log=log,
                        alignment=alignment, utc_offset_s=log.utc_offset_s)


def _home_text(log: FlightLog) -> str:
    if log.home is None:
        return "unknown"
    lat, lon, alt = log.home
    alt_text = f"{alt:.1f} m AMSL" if math.isfinite(alt) else "altitude unknown"
    return f"{lat:.7f}, {lon:.7f}, {alt_text} ({log.home_note})"
