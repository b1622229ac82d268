"""A MAVLink vehicle (pymavlink, MAVLink 2) flying the synthetic flight, for tests and demos.

It behaves like an ArduPilot Copter autopilot (system 1, component 1, MAV_TYPE_QUADROTOR,
MAV_AUTOPILOT_ARDUPILOTMEGA) as seen from a companion computer:

- Streams HEARTBEAT (1 Hz wall clock), GLOBAL_POSITION_INT (10 Hz), GPS_RAW_INT (5 Hz: 3D fix,
  10 satellites, ``h_acc`` the simulated GNSS noise), ATTITUDE (20 Hz),
  GIMBAL_DEVICE_ATTITUDE_STATUS (5 Hz, only with a gimbal), SYSTEM_TIME (1 Hz) and
  HOME_POSITION (0.5 Hz); rates in simulated time. ``stream_on_request=True`` sends only
  HEARTBEAT until MAV_CMD_SET_MESSAGE_INTERVAL asks for a message (ArduPilot behaviour).
  (:mod:`sim.vehicle.streams`)
- ArduPilot's start, optionally (both off by default): until ``gps_fix_after_s`` (sim time)
  GLOBAL_POSITION_INT reads lat/lon 0 and GPS_RAW_INT fix_type 0 with no satellites; until
  ``home_after_s`` no HOME_POSITION is sent, GET_HOME_POSITION fails, DO_REPOSITION fails (no
  EKF origin) and arming is refused with a reason. Copter 4.7 SITL (observed): GPS fix ~9 s after
  boot, EKF origin and HOME_POSITION ~10 s later. (:mod:`sim.vehicle.autopilot`)
- COMMAND_LONG / COMMAND_INT get a COMMAND_ACK (:mod:`sim.vehicle.commands`).
- A packet whose MAVLink sequence number equals the previous one from the same system and
  component is a duplicate (a radio or router sending it twice): dropped and counted in
  :attr:`SimVehicle.duplicates_dropped`.
- Mission protocol as server (:mod:`sim.vehicle.mission_server`).
- Every STATUSTEXT received is logged and kept in :attr:`SimVehicle.statustexts`
  (:mod:`sim.vehicle.statustexts`).
- Malformed input is dropped; a failing handler is logged and the loop carries on.

Time: ``sim_time() = (monotonic() - start) * speedup`` seconds; ``time_boot_ms`` of every message
is the sample's capture time in that clock. A frame source renders the same flight with
:meth:`SimVehicle.truth_state` / :meth:`SimVehicle.camera_pose`. The flight is anything with the
:class:`sim.flight_model.FlightModel` protocol.
"""

from sim.vehicle.autopilot import COPTER_MODE_AUTO, COPTER_MODE_GUIDED
from sim.vehicle.commands import ARM_NO_HOME, CommandRecord
from sim.vehicle.mission_server import UPLOAD_MAX_RETRIES, UPLOAD_RETRY_S, MissionItem
from sim.vehicle.run import run_vehicle
from sim.vehicle.statustexts import StatusText
from sim.vehicle.streams import STREAMS
from sim.vehicle.vehicle import SimVehicle

__all__ = [
    "ARM_NO_HOME",
    "COPTER_MODE_AUTO",
    "COPTER_MODE_GUIDED",
    "STREAMS",
    "UPLOAD_MAX_RETRIES",
    "UPLOAD_RETRY_S",
    "CommandRecord",
    "MissionItem",
    "SimVehicle",
    "StatusText",
    "run_vehicle",
]
