"""What the simulated vehicle and its telemetry need of a flight, as a protocol.

:class:`sim.flight.Flight` (a planned survey), :class:`sim.log_flight.LogFlight` (a SITL log) and
:class:`sim.meta_flight.MetaFlight` (replayed footage) all fly for the vehicle through this.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from sarmission.geo.camera import CameraPose
from sarmission.mission.config import MissionConfig
from sim.flight import VehicleState


class FlightModel(Protocol):
    """A flight the vehicle streams and steers: exact state by sim time, runtime changes.

    ``steerable`` False means the flight cannot obey DO_REPOSITION or an ROI (replayed
    footage); the vehicle then denies those commands.
    """

    @property
    def mission(self) -> MissionConfig: ...

    @property
    def survey_duration(self) -> float: ...

    @property
    def steerable(self) -> bool: ...

    def state_at(self, t: float) -> VehicleState: ...

    def camera_pose_at(self, t: float) -> CameraPose: ...

    def reposition(
        self, t: float, target_ned: np.ndarray, speed_m_s: float | None = None
    ) -> float: ...

    def set_roi(self, t: float, target_ned: np.ndarray | None) -> None: ...
