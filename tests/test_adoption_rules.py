"""Which sender the link takes for the autopilot, rule by rule (no sockets): HEARTBEAT kinds that
are not a flight controller, the link timeout at its boundary, pinned ids, gimbals of the adopted
system only. The rules are MAVLink's: MAV_AUTOPILOT_INVALID marks a non-autopilot, MAV_TYPE_GCS
a ground station, components 154 and 171-175 are gimbals."""

import pytest
from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.mavlink.adoption import Adoption, is_autopilot_heartbeat, source_kind


class _Sink:
    def __init__(self) -> None:
        self.data = b""

    def write(self, data: bytes) -> None:
        self.data += data


def heartbeat(
    system: int,
    component: int,
    mav_type: int = M.MAV_TYPE_QUADROTOR,
    autopilot: int = M.MAV_AUTOPILOT_ARDUPILOTMEGA,
):
    """A HEARTBEAT as received from ``system``/``component`` (encoded, then parsed)."""
    sink = _Sink()
    M.MAVLink(sink, srcSystem=system, srcComponent=component).heartbeat_send(
        mav_type, autopilot, 0, 0, M.MAV_STATE_ACTIVE
    )
    parser = M.MAVLink(None)
    (msg,) = parser.parse_buffer(sink.data)
    return msg


@pytest.mark.parametrize(
    ("msg", "is_autopilot"),
    [
        (heartbeat(1, 1), True),
        (heartbeat(1, 1, M.MAV_TYPE_FIXED_WING, M.MAV_AUTOPILOT_PX4), True),
        (heartbeat(1, 1, autopilot=M.MAV_AUTOPILOT_INVALID), False),
        (heartbeat(255, 190, M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_ARDUPILOTMEGA), False),
        (heartbeat(1, 191, M.MAV_TYPE_ONBOARD_CONTROLLER), False),
        (heartbeat(1, 154, M.MAV_TYPE_QUADROTOR), False),  # a gimbal claiming a vehicle type
        (heartbeat(1, 171), False),
        (heartbeat(1, 1, M.MAV_TYPE_GIMBAL), False),
    ],
)
def test_which_heartbeats_claim_a_flight_controller(msg, is_autopilot):
    assert is_autopilot_heartbeat(msg) is is_autopilot


def test_a_rival_is_adopted_only_after_more_than_the_link_timeout():
    """Of the same system (another component): after the link timeout."""
    adoption = Adoption(link_timeout_s=3.0)
    first = adoption.heartbeat((1, 1), 10.0)
    assert first is not None and first.new == (1, 1) and first.old is None
    adoption.heard((1, 1), 12.0)  # any message keeps it alive
    assert adoption.heartbeat((1, 2), 14.0) is None  # silent 2 s
    assert adoption.heartbeat((1, 2), 15.0) is None  # silent exactly the timeout: still alive
    assert adoption.adopted == (1, 1) and adoption.rivals(15.0) == [(1, 2)]
    change = adoption.heartbeat((1, 2), 15.5)  # silent 3.5 s
    assert change is not None and change.new == (1, 2) and change.old == (1, 1)
    assert change.silent_s == pytest.approx(3.5)
    assert adoption.adopted == (1, 2) and adoption.adoptions == 2


def test_another_system_is_not_adopted_after_a_fade_and_the_former_is_taken_back():
    """A 3 s fade does not hand the link to another vehicle (system 2): only a minute of
    silence does; the former autopilot heard again is taken back at once."""
    adoption = Adoption(link_timeout_s=3.0)
    adoption.heartbeat((1, 1), 10.0)
    for t in (14.0, 20.0, 40.0, 70.0):  # silent 4..60 s
        assert adoption.heartbeat((2, 1), t) is None, t
    assert adoption.heartbeat((1, 1), 70.5) is None  # back: still the adopted one
    assert adoption.adopted == (1, 1) and adoption.adoptions == 1
    change = adoption.heartbeat((2, 1), 131.0)  # silent 60.5 s: gone
    assert change is not None and change.new == (2, 1) and change.old == (1, 1)
    back = adoption.heartbeat((1, 1), 131.5)  # the former is heard again
    assert back is not None and back.new == (1, 1) and back.old == (2, 1)
    assert adoption.adopted == (1, 1) and adoption.adoptions == 3


@pytest.mark.parametrize(
    ("pin", "src", "adopted"),
    [
        ((1, None), (1, 1), True),
        ((1, None), (2, 1), False),
        ((None, 1), (7, 1), True),
        ((None, 1), (1, 2), False),
        ((1, 1), (1, 1), True),
        ((1, 1), (1, 2), False),
        ((1, 1), (2, 1), False),
    ],
)
def test_pinned_system_and_component_are_enforced(pin, src, adopted):
    adoption = Adoption(3.0, target_system=pin[0], target_component=pin[1])
    assert (adoption.heartbeat(src, 1.0) is not None) is adopted
    assert adoption.adopted == (src if adopted else None)


def test_gimbal_messages_only_from_the_adopted_systems_gimbals():
    assert source_kind((1, 1), (1, 1)) == "autopilot"
    assert source_kind((1, M.MAV_COMP_ID_GIMBAL), (1, 1)) == "gimbal"
    assert source_kind((1, M.MAV_COMP_ID_GIMBAL2), (1, 1)) == "gimbal"
    assert source_kind((2, M.MAV_COMP_ID_GIMBAL), (1, 1)) == "foreign"
    assert source_kind((1, 2), (1, 1)) == "foreign"
    assert source_kind((1, 1), None) == "foreign"
