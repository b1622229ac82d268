"""A flight that follows an autopilot's log, so that the simulator renders what that aircraft's
camera saw: the ArduPilot SITL's own truth (DataFlash ``SIM``: the simulated vehicle's exact
position and attitude, not the estimate the autopilot logs and sends) at every logged instant.

:class:`LogFlight` has the part of :class:`sim.flight.Flight` that rendering uses (``mission``,
``state_at``, ``camera_pose_at``, ``survey_duration``); times are the log's own clock (seconds
of ``TimeUS``). Position and attitude are interpolated linearly between ``SIM`` samples (yaw
unwrapped). The camera is the mission's fixed mount in the body frame (``mount_pitch_deg``).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
from pymavlink import mavutil

from sarmission.geo.camera import CameraPose
from sarmission.mission.config import MissionConfig
from sim.flight import Flight, VehicleState
from sim.truth_frames import geodetic_to_ned


class LogFlight(Flight):
    """The SITL truth of a DataFlash log (see the module docstring). A :class:`Flight` to the
    renderer, but its path is the log's: none of the planned survey is built.

    ``home``: ``(lat, lon, alt AMSL)`` of the NED origin (default: the first ``SIM`` sample at
    the ground); the returned :attr:`mission` is ``mission`` with that home.
    """

    def __init__(
        self,
        path: str | Path,
        mission: MissionConfig,  # noqa: D107
        home: tuple[float, float, float] | None = None,
    ) -> None:
        # Flight.__init__ is not called: it would plan a survey this flight does not fly.
        reader = mavutil.mavlink_connection(str(path))
        rows = []
        while (msg := reader.recv_match(type="SIM")) is not None:
            rows.append((msg.TimeUS / 1e6, msg.Lat, msg.Lng, msg.Alt, msg.Roll, msg.Pitch, msg.Yaw))
        if len(rows) < 2:
            raise ValueError(f"{path}: no SIM messages (not an ArduPilot SITL log)")
        data = np.array(rows, dtype=float)
        self.times = data[:, 0]
        if home is None:
            home = (float(data[0, 1]), float(data[0, 2]), float(data[0, 3]))
        self.home = home
        n, e, d = geodetic_to_ned(data[:, 1], data[:, 2], data[:, 3], *home)
        self.position_ned = np.column_stack([n, e, d])
        self.rpy = np.radians(data[:, 4:7])
        self.rpy[:, 2] = np.unwrap(self.rpy[:, 2])
        self.mission = dataclasses.replace(
            mission,
            area=dataclasses.replace(
                mission.area, home_lat=home[0], home_lon=home[1], home_alt_m=home[2]
            ),
        )
        self.survey_duration = float(self.times[-1])
        self._mount = math.radians(mission.camera.mount_pitch_deg)

    def state_at(self, t: float) -> VehicleState:
        """The simulated vehicle's true state at log time ``t`` (clamped to the log)."""
        t = float(np.clip(t, self.times[0], self.times[-1]))
        j = int(np.clip(np.searchsorted(self.times, t), 1, len(self.times) - 1))
        i = j - 1
        f = (t - self.times[i]) / (self.times[j] - self.times[i])
        pos = self.position_ned[i] * (1 - f) + self.position_ned[j] * f
        vel = (self.position_ned[j] - self.position_ned[i]) / (self.times[j] - self.times[i])
        roll, pitch, yaw = self.rpy[i] * (1 - f) + self.rpy[j] * f
        yaw = (yaw + math.pi) % (2 * math.pi) - math.pi
        return VehicleState(
            t=t,
            position_ned=pos,
            velocity_ned=vel,
            acceleration_ned=np.zeros(3),
            roll=float(roll),
            pitch=float(pitch),
            yaw=float(yaw),
            gimbal_roll=0.0,
            gimbal_pitch=self._mount,
            gimbal_yaw=0.0,
            gimbal_frame="body",
            wind_ned=np.zeros(3),
        )

    def camera_pose_at(self, t: float) -> CameraPose:
        """Camera pose at log time ``t``."""
        return self.state_at(t).camera_pose()
