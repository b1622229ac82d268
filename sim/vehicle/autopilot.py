"""The simulated autopilot's own state: home, gimbal, flight mode and ArduPilot's start.

Shared by the stream scheduler (what it may report) and the command handler (what it may do).
"""

from __future__ import annotations

from dataclasses import dataclass

COPTER_MODE_AUTO = 3
COPTER_MODE_GUIDED = 4


@dataclass
class AutopilotState:
    """Home ``(lat, lon, alt AMSL)``, whether a gimbal is fitted, the Copter ``custom_mode``,
    and the sim times of the GPS fix and of home (None: from the first message)."""

    home: tuple[float, float, float]
    has_gimbal: bool
    gps_fix_after_s: float | None = None
    home_after_s: float | None = None
    custom_mode: int = COPTER_MODE_AUTO

    def has_gps_fix(self, t: float) -> bool:
        """Whether the simulated GPS has its fix at sim time ``t``."""
        return self.gps_fix_after_s is None or t >= self.gps_fix_after_s

    def has_home(self, t: float) -> bool:
        """Whether the autopilot has set home (and its EKF origin) at sim time ``t``."""
        return self.home_after_s is None or t >= self.home_after_s
