"""The adopted autopilot's armed state and flight mode, and whether the vehicle may be taken over.

A positional action (DO_REPOSITION with the change-mode flag, an ROI, a mission insertion)
overrides what the vehicle is doing. That is wanted while it surveys (AUTO) or holds position,
and dangerous while it lands or returns home: the pilot's or a failsafe's RTL/LAND would be
cancelled and the vehicle flown back out. So the autopilot's HEARTBEAT is read (``base_mode``
MAV_MODE_FLAG_SAFETY_ARMED, ``custom_mode`` decoded as pymavlink does:
:func:`pymavlink.mavutil.mode_string_v10`, ArduPilot by vehicle type, PX4 by its main and sub
mode) and a takeover is allowed only in the modes of :data:`TAKEOVER_MODES`, armed, with a
HEARTBEAT at most :data:`HEARTBEAT_MAX_AGE_S` old. Everything else (disarmed; RTL, SMART_RTL,
AUTO_RTL, LAND, BRAKE; manual modes, where the pilot has the sticks; a mode not known; no
current HEARTBEAT) is refused.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as M

#: A HEARTBEAT older than this says nothing about the current mode (seconds; sent at 1 Hz).
HEARTBEAT_MAX_AGE_S = 3.0

#: Flight modes in which the vehicle may be sent elsewhere, per autopilot (mode names as
#: :func:`pymavlink.mavutil.mode_string_v10` gives them).
TAKEOVER_MODES: dict[int, frozenset[str]] = {
    M.MAV_AUTOPILOT_ARDUPILOTMEGA: frozenset({"AUTO", "GUIDED", "LOITER", "POSHOLD"}),
    M.MAV_AUTOPILOT_PX4: frozenset({"MISSION", "LOITER"}),
}


@dataclass(frozen=True)
class FlightState:
    """What one HEARTBEAT said: ``armed``, the ``mode`` name and the ``autopilot`` kind,
    received at local time ``arrival``."""

    armed: bool
    mode: str
    autopilot: int
    arrival: float

    @classmethod
    def from_heartbeat(cls, msg: Any, arrival: float) -> FlightState:
        """The state a HEARTBEAT reports."""
        armed = bool(int(msg.base_mode) & M.MAV_MODE_FLAG_SAFETY_ARMED)
        try:
            mode = str(mavutil.mode_string_v10(msg))
        except Exception:  # an odd vehicle type or mode pymavlink cannot map: unknown
            mode = f"Mode({int(msg.custom_mode)})"
        return cls(armed, mode, int(msg.autopilot), arrival)


def takeover_refusal(state: FlightState | None, now: float) -> str:
    """Why the vehicle may not be sent anywhere now ("" when it may)."""
    if state is None:
        return "flight mode unknown (no HEARTBEAT from the autopilot)"
    age = now - state.arrival
    if age > HEARTBEAT_MAX_AGE_S:
        return f"flight mode unknown (no HEARTBEAT for {age:.1f} s)"
    if not state.armed:
        return f"vehicle disarmed ({state.mode})"
    if state.mode not in TAKEOVER_MODES.get(state.autopilot, frozenset()):
        return f"vehicle in {state.mode}, not a mode that may be taken over"
    return ""
