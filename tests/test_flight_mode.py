"""Whether the vehicle may be taken over, from its HEARTBEAT: armed, in a mode known to be safe
to take over (AUTO, GUIDED, LOITER, POSHOLD; PX4 mission or hold), and heard lately."""

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.mavlink.flight_mode import HEARTBEAT_MAX_AGE_S, FlightState, takeover_refusal
from sarmission.mavlink.telemetry import TelemetryBuffer

ARMED = M.MAV_MODE_FLAG_SAFETY_ARMED | M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
ARDUPILOT, PX4 = M.MAV_AUTOPILOT_ARDUPILOTMEGA, M.MAV_AUTOPILOT_PX4


def heartbeat(custom_mode: int, base_mode: int = ARMED, autopilot: int = ARDUPILOT):
    mav = M.MAVLink(None, srcSystem=1, srcComponent=1)
    msg = mav.heartbeat_encode(M.MAV_TYPE_QUADROTOR, autopilot, base_mode, custom_mode, 4)
    msg.pack(mav)  # sets the source ids
    return msg


def px4_mode(main: int, sub: int = 0) -> int:
    return (main << 16) | (sub << 24)


@pytest.mark.parametrize(
    ("custom_mode", "autopilot", "refused"),
    [
        (3, ARDUPILOT, ""),  # AUTO
        (4, ARDUPILOT, ""),  # GUIDED
        (5, ARDUPILOT, ""),  # LOITER
        (16, ARDUPILOT, ""),  # POSHOLD
        (6, ARDUPILOT, "vehicle in RTL"),
        (9, ARDUPILOT, "vehicle in LAND"),
        (21, ARDUPILOT, "vehicle in SMART_RTL"),
        (17, ARDUPILOT, "vehicle in BRAKE"),
        (27, ARDUPILOT, "vehicle in AUTO_RTL"),
        (0, ARDUPILOT, "vehicle in STABILIZE"),  # the pilot has the sticks
        (99, ARDUPILOT, "vehicle in Mode(99)"),
        (px4_mode(4, 4), PX4, ""),  # AUTO_MISSION
        (px4_mode(4, 3), PX4, ""),  # AUTO_LOITER (hold)
        (px4_mode(4, 5), PX4, "vehicle in RTL"),
        (px4_mode(4, 6), PX4, "vehicle in LAND"),
        (px4_mode(3), PX4, "vehicle in POSCTL"),
    ],
)
def test_modes_that_may_be_taken_over(custom_mode, autopilot, refused):
    state = FlightState.from_heartbeat(heartbeat(custom_mode, autopilot=autopilot), 10.0)
    why = takeover_refusal(state, 10.5)
    assert why.startswith(refused) and bool(why) == bool(refused), why


def test_disarmed_unknown_and_stale_are_refused():
    disarmed = FlightState.from_heartbeat(heartbeat(3, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), 0.0)
    assert takeover_refusal(disarmed, 0.1) == "vehicle disarmed (AUTO)"
    assert takeover_refusal(None, 0.0).startswith("flight mode unknown")
    auto = FlightState.from_heartbeat(heartbeat(3), 0.0)
    assert takeover_refusal(auto, HEARTBEAT_MAX_AGE_S) == ""
    assert takeover_refusal(auto, HEARTBEAT_MAX_AGE_S + 0.5).startswith("flight mode unknown")


def test_the_telemetry_buffer_tracks_the_autopilots_heartbeat():
    buf = TelemetryBuffer()
    assert buf.takeover_refusal(0.0).startswith("flight mode unknown")
    buf.handle_message(heartbeat(3), arrival=1.0)
    assert buf.takeover_refusal(1.5) == ""
    buf.handle_message(heartbeat(9), arrival=2.0)
    assert buf.flight_state.mode == "LAND" and buf.flight_state.armed
    assert buf.takeover_refusal(2.5).startswith("vehicle in LAND")
    buf.reset("another autopilot")
    assert buf.takeover_refusal(2.5).startswith("flight mode unknown")
