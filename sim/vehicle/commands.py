"""The simulated vehicle's command handler: COMMAND_LONG / COMMAND_INT in, COMMAND_ACK out.

SET_MESSAGE_INTERVAL, REQUEST_MESSAGE, GET_HOME_POSITION, REQUEST_AUTOPILOT_CAPABILITIES,
DO_REPOSITION (flies there and holds), DO_SET_ROI_LOCATION / DO_SET_ROI_NONE (point the gimbal;
these three are MAV_RESULT_DENIED for a flight that cannot be steered, such as replayed footage),
COMPONENT_ARM_DISARM and DO_SET_MISSION_CURRENT; anything else is MAV_RESULT_UNSUPPORTED. Like
ArduPilot, a refused arming is followed by STATUSTEXTs of severity CRITICAL giving the reason.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sim.flight_model import FlightModel
from sim.truth_frames import geodetic_to_ned
from sim.vehicle.autopilot import COPTER_MODE_GUIDED, AutopilotState
from sim.vehicle.link import VehicleLink
from sim.vehicle.mission_server import MissionServer
from sim.vehicle.streams import StreamScheduler

log = logging.getLogger(__name__)

M = mavlink2

#: ArduPilot's arming refusal while it has no home (Copter 4.7 SITL, observed).
ARM_NO_HOME = "Arm: AHRS: waiting for home"
#: Commands that move the vehicle or its camera: denied for a flight that cannot be steered.
STEERING = (M.MAV_CMD_DO_REPOSITION, M.MAV_CMD_DO_SET_ROI_LOCATION, M.MAV_CMD_DO_SET_ROI_NONE)


@dataclass
class CommandRecord:
    """A command received: its id, whether it came as COMMAND_INT, params and the result sent."""

    sim_time: float
    command: int
    is_int: bool
    params: tuple[float, ...]
    result: int


@dataclass(frozen=True)
class _Received:
    """One command being carried out at sim time ``now``; ``frame`` only for COMMAND_INT."""

    params: tuple[float, ...]
    frame: int | None
    is_int: bool
    now: float


class CommandHandler:
    """Carries out commands on the flight, the streams and the mission server and ACKs them;
    every command and its result is kept in :attr:`commands`."""

    def __init__(
        self,
        link: VehicleLink,
        flight: FlightModel,
        autopilot: AutopilotState,
        streams: StreamScheduler,
        mission_server: MissionServer,
    ) -> None:
        self.link = link
        self.flight = flight
        self.autopilot = autopilot
        self.streams = streams
        self.mission_server = mission_server
        self.commands: list[CommandRecord] = []
        self._reasons: list[str] = []  # STATUSTEXTs to send after the ACK being prepared
        self._lock = threading.Lock()
        self._handlers: dict[int, Callable[[_Received], int]] = {
            M.MAV_CMD_SET_MESSAGE_INTERVAL: self._set_message_interval,
            M.MAV_CMD_REQUEST_MESSAGE: self._request_message,
            M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: self._request_capabilities,
            M.MAV_CMD_GET_HOME_POSITION: self._get_home_position,
            M.MAV_CMD_COMPONENT_ARM_DISARM: self._arm_disarm,
            M.MAV_CMD_DO_REPOSITION: self._reposition,
            M.MAV_CMD_DO_SET_ROI_LOCATION: self._set_roi_location,
            M.MAV_CMD_DO_SET_ROI_NONE: self._set_roi_none,
            M.MAV_CMD_DO_SET_MISSION_CURRENT: self._set_mission_current,
        }

    def handlers(self) -> dict[str, Callable[[Any], None]]:
        """Message type -> handler, for the two command messages."""
        return {"COMMAND_LONG": self._on_command_long, "COMMAND_INT": self._on_command_int}

    # -- messages ----------------------------------------------------------------------------------
    def _on_command_long(self, msg: Any) -> None:
        params = (
            msg.param1,
            msg.param2,
            msg.param3,
            msg.param4,
            msg.param5,
            msg.param6,
            msg.param7,
        )
        self._command(msg, msg.command, params, None, False)

    def _on_command_int(self, msg: Any) -> None:
        params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.x, msg.y, msg.z)
        self._command(msg, msg.command, params, msg.frame, True)

    def _command(
        self, msg: Any, command: int, p: tuple[float, ...], frame: int | None, is_int: bool
    ) -> None:
        self._reasons = []
        result = self._execute(command, _Received(p, frame, is_int, self.link.sim_time()))
        with self._lock:
            self.commands.append(CommandRecord(self.link.sim_time(), command, is_int, p, result))
        log.info("command %d (%s) -> result %d", command, "INT" if is_int else "LONG", result)
        self.link.send(
            "COMMAND_ACK",
            self.link.mav.command_ack_send,
            command,
            result,
            0,
            0,
            msg.get_srcSystem(),
            msg.get_srcComponent(),
        )
        for text in self._reasons:  # ArduPilot's reasons follow its ACK
            self.link.send(
                "STATUSTEXT",
                self.link.mav.statustext_send,
                M.MAV_SEVERITY_CRITICAL,
                text.encode("ascii", "replace")[:50],
            )
        self._reasons = []

    def _execute(self, command: int, cmd: _Received) -> int:
        handler = self._handlers.get(command)
        if handler is None:
            return M.MAV_RESULT_UNSUPPORTED
        if command in STEERING and not self.flight.steerable:
            log.info("command %d denied: this flight cannot be steered (replayed footage)", command)
            return M.MAV_RESULT_DENIED
        return handler(cmd)

    # -- commands ----------------------------------------------------------------------------------
    def _set_message_interval(self, cmd: _Received) -> int:
        ok = self.streams.set_interval(int(cmd.params[0]), cmd.params[1], cmd.now)
        return M.MAV_RESULT_ACCEPTED if ok else M.MAV_RESULT_DENIED

    def _request_message(self, cmd: _Received) -> int:
        msg_id = int(cmd.params[0])
        if msg_id == M.MAVLINK_MSG_ID_MISSION_CURRENT:
            self.mission_server.send_current()
            return M.MAV_RESULT_ACCEPTED
        ok = self.streams.request(msg_id, cmd.now)
        return M.MAV_RESULT_ACCEPTED if ok else M.MAV_RESULT_DENIED

    def _request_capabilities(self, cmd: _Received) -> int:
        self.streams.send_autopilot_version()
        return M.MAV_RESULT_ACCEPTED

    def _get_home_position(self, cmd: _Received) -> int:
        if not self.autopilot.has_home(cmd.now):
            return M.MAV_RESULT_FAILED
        self.streams.send_home()
        return M.MAV_RESULT_ACCEPTED

    def _arm_disarm(self, cmd: _Received) -> int:
        arm = cmd.params[0] == 1
        if arm and not self.autopilot.has_home(cmd.now):
            self._reasons.append(ARM_NO_HOME)
            return M.MAV_RESULT_FAILED
        return M.MAV_RESULT_ACCEPTED if arm else M.MAV_RESULT_DENIED

    def _reposition(self, cmd: _Received) -> int:
        if not self.autopilot.has_home(cmd.now):  # ArduPilot: no EKF origin yet, FAILED, no text
            return M.MAV_RESULT_FAILED
        p = cmd.params
        target = self._location_ned(cmd)
        speed = p[0] if p[0] is not None and math.isfinite(p[0]) and p[0] > 0 else None
        eta = self.flight.reposition(cmd.now, target, speed)
        if int(p[1]) & 1:
            self.autopilot.custom_mode = COPTER_MODE_GUIDED
        log.info("reposition to NED %s, arrival at t=%.1f s", np.round(target, 1), eta)
        return M.MAV_RESULT_ACCEPTED

    def _set_roi_location(self, cmd: _Received) -> int:
        target = self._location_ned(cmd)
        self.flight.set_roi(cmd.now, target)
        log.info("ROI at NED %s", np.round(target, 1))
        return M.MAV_RESULT_ACCEPTED

    def _set_roi_none(self, cmd: _Received) -> int:
        self.flight.set_roi(cmd.now, None)
        return M.MAV_RESULT_ACCEPTED

    def _set_mission_current(self, cmd: _Received) -> int:
        ok = self.mission_server.set_current(int(cmd.params[0]))
        return M.MAV_RESULT_ACCEPTED if ok else M.MAV_RESULT_DENIED

    def _location_ned(self, cmd: _Received) -> np.ndarray:
        """Target location of a COMMAND_INT (x, y degE7) or COMMAND_LONG (param5/6 deg) in NED."""
        p = cmd.params
        lat = p[4] / 1e7 if cmd.is_int else p[4]
        lon = p[5] / 1e7 if cmd.is_int else p[5]
        alt = p[6]
        home = self.autopilot.home
        here = self.flight.state_at(self.link.sim_time()).position_ned
        if alt is None or not math.isfinite(alt):
            down = here[2]
        elif cmd.frame in (M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_INT):
            down = home[2] - alt
        else:  # relative to home (GLOBAL_RELATIVE_ALT[_INT]) or unspecified
            down = -alt
        if not (math.isfinite(lat) and math.isfinite(lon)) or (lat == 0 and lon == 0):
            return np.array([here[0], here[1], down])
        n, e, _ = geodetic_to_ned(lat, lon, home[2], *home)
        return np.array([float(n), float(e), down])
