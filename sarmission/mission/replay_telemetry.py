"""Telemetry for offline replay, pushed into a :class:`TelemetryBuffer` in the frames' clock.

Two sources:

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
from typing import Any

from sarmission.data.coco_video import FrameTelemetry
from sarmission.geo.wgs84 import ned_to_geodetic
from sarmission.mavlink.telemetry import TelemetryBuffer


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
