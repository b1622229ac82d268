"""Actions a pilot can live with, over real UDP against the simulated vehicle: one visit plan
instead of a reposition per alert, the pilot's mission kept when visits go into it, moving
commands only to bounded positions inside the area, the ROI pause only with a gimbal, and
none while the vehicle lands or returns home."""

import pymap3d
import pytest
from alert_samples import make_alert
from conftest import free_udp_port, wait_until

from sarmission.alerts.store import AlertStore
from sarmission.mavlink.commands import CommandSender, Outbox
from sarmission.mavlink.connection import M, MavlinkLink
from sarmission.mavlink.mission_transfer import WireItem
from sarmission.mavlink.outbox_commands import Reposition
from sarmission.mavlink.telemetry import MESSAGE_TYPES, TelemetryBuffer
from sarmission.mission.actions import ActionPolicy, _Key
from sarmission.mission.config import load_mission
from sarmission.mission.visits import MoveGate
from sim.vehicle import MissionItem, SimVehicle

HOME = (-35.3640, 149.1652)  # the mission area's origin; the area: 40-200 m N, +-100 m E
REL = M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT


def at(north: float, east: float) -> tuple[float, float]:
    lat, lon, _ = pymap3d.ned2geodetic(north, east, 0.0, *HOME, 0.0)
    return float(lat), float(lon)


class Clock:
    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


class Rig:
    """The simulated vehicle, our link, outbox, store and an action policy with a fake clock."""

    def __init__(self, tmp_path, policy: list[str], aircraft=None, gimbal=False, **actions):
        overrides = {
            "flight.takeoff": False,
            "area.home_lat": HOME[0],
            "area.home_lon": HOME[1],
            "actions.policy": policy,
            "actions.statustext_repeats": 1,
        }
        overrides.update({f"actions.{k}": v for k, v in actions.items()})
        self.mission = load_mission(overrides=overrides)
        port = free_udp_port()
        self.vehicle = SimVehicle(f"udpin:127.0.0.1:{port}", self.mission).start()
        self.link = MavlinkLink(f"udpout:127.0.0.1:{port}")
        # the vehicle's armed state and flight mode come from its HEARTBEAT, as in a live run
        self.telemetry = TelemetryBuffer()
        self.link.subscribe_autopilot(self.telemetry.handle_message, MESSAGE_TYPES)
        # a generous ACK wait: on a loaded machine a re-send after a slow ACK reaches the
        # vehicle as a second command and the counts below would be off
        self.outbox = Outbox(CommandSender(self.link, retries=2, ack_timeout_s=5.0))
        self.store = AlertStore(tmp_path / "alerts.db")
        self.lines: list[str] = []
        self.clock = Clock()
        assert self.link.wait_autopilot(5.0)
        assert wait_until(lambda: self.telemetry.flight_state is not None, 5.0)
        self.policy = ActionPolicy(
            self.mission.actions,
            self.outbox,
            self.store,
            survey_altitude_m=50.0,
            console=self.lines.append,
            clock=self.clock,
            move_gate=MoveGate.from_mission(self.mission),
            aircraft_position=lambda: aircraft,
            gimbal_present=lambda: gimbal,
            takeover=self.telemetry.takeover_refusal,
        )

    def alert(
        self,
        target_id: int,
        north: float,
        east: float,
        error_m: float = 3.0,
        confidence: float | None = None,
    ):
        alert = make_alert(
            target_id, position=at(north, east), error_m=error_m, confidence=confidence
        )
        self.store.add(alert)
        self.policy.announce(alert)
        return alert

    def settle(self) -> None:
        """Tick like the controller does until nothing is queued."""
        assert wait_until(lambda: self.policy.tick() or not self.policy.pending(), 15.0), (
            self.policy.pending(),
            self.lines,
        )

    def commands(self, command: int) -> list:
        return [c for c in self.vehicle.commands if c.command == command]

    def close(self) -> None:
        self.outbox.close()
        self.link.close()
        self.vehicle.stop()
        self.store.close()


@pytest.fixture
def rig_factory(tmp_path):
    rigs = []

    def make(*args, **kwargs) -> Rig:
        rigs.append(Rig(tmp_path, *args, **kwargs))
        return rigs[-1]

    yield make
    for rig in rigs:
        rig.close()


def test_sixteen_alerts_in_ten_seconds_make_one_reposition_then_the_nearest(rig_factory):
    rig = rig_factory(["loiter"], aircraft=at(40.0, 0.0))
    first_visit_at = rig.clock.t + 10.0 / 16  # the first tick, after the first alert
    for k in range(16):  # 16 people 8 m apart in a line northwards, within 10 s
        rig.alert(k + 1, 60.0 + 8.0 * k, 0.0)
        rig.clock.t += 10.0 / 16
        rig.policy.tick()
    rig.settle()
    (first,) = rig.commands(M.MAV_CMD_DO_REPOSITION)  # the first alert leaves at once
    assert first.params[4:6] == pytest.approx([round(v * 1e7) for v in at(60.0, 0.0)], abs=1)
    assert sorted(rig.policy.planner.visited) == [1]
    rig.clock.t = first_visit_at + 59.0
    rig.settle()
    assert len(rig.commands(M.MAV_CMD_DO_REPOSITION)) == 1  # the interval is not over
    rig.clock.t = first_visit_at + 60.0
    rig.settle()
    first, second = rig.commands(M.MAV_CMD_DO_REPOSITION)
    # nearest to the aircraft: target 2 at 68 m N, covering 3-5 within 30 m of it
    assert second.params[4:6] == pytest.approx([round(v * 1e7) for v in at(68.0, 0.0)], abs=1)
    assert sorted(rig.policy.planner.visited) == [1, 2, 3, 4, 5]
    delivered = [a for a in rig.store.list() if "mavlink_loiter" in a.delivered]
    assert sorted(a.target_id for a in delivered) == [1, 2, 3, 4, 5]
    assert any("visit plan: loiter to target" in line for line in rig.lines)


def test_a_queued_visit_the_operator_overrules_is_withdrawn(rig_factory):
    """Queued behind the first visit, one alert is dismissed by the operator and another's
    confidence is rated below ``min_confidence`` by the operator's decisions on others: when
    the next visit is due neither is flown to; the third is."""
    rig = rig_factory(["loiter"], aircraft=at(40.0, 0.0), min_confidence=0.4)
    rig.alert(1, 60.0, 0.0)  # flown to at once
    rig.policy.tick()
    rig.alert(2, 120.0, 0.0)  # dismissed later
    rated = make_alert(3, tier="candidate", position=at(150.0, 0.0), error_m=3.0)
    rig.store.add(rated)
    rig.policy.announce(rig.store.promote(rated.alert_id, "held 3 s", None, 0.0))
    assert rig.store.get(rated.alert_id).confidence == pytest.approx(0.5)
    rig.alert(4, 180.0, 0.0)  # stays
    rig.settle()
    assert sorted(rig.policy.planner.pending) == [2, 3, 4]
    rig.store.decide(rig.store.list()[1].alert_id, "dismissed", "ana")
    for k in range(3):  # other rated alerts, all dismissed: the mission's level drops
        other = make_alert(10 + k, tier="candidate")
        rig.store.add(other)
        rig.store.promote(other.alert_id, "held 3 s", None, 0.0)
        rig.store.decide(other.alert_id, "dismissed", "ana")
    assert rig.store.get(rated.alert_id).confidence < 0.4
    rig.clock.t += 60.0
    rig.settle()
    first, second = rig.commands(M.MAV_CMD_DO_REPOSITION)
    assert second.params[4:6] == pytest.approx([round(v * 1e7) for v in at(180.0, 0.0)], abs=1)
    assert not rig.policy.planner.pending
    withdrawn = [line for line in rig.lines if "visit withdrawn" in line]
    assert len(withdrawn) == 2 and "dismissed by ana" in withdrawn[0]
    assert "below the 40 % " in withdrawn[1]
    assert "visits withdrawn (dismissed or rated down since): 2" in rig.policy.summary()


def test_a_visit_withheld_as_too_unlikely_goes_once_rated_up(rig_factory):
    """``min_confidence`` 0.6: two targets rated 50 % likely are not flown to. The operator
    confirms other alerts of the mission, which rates both up, then dismisses one of the two:
    only the other is queued (at the next check) and flown to."""
    rig = rig_factory(["loiter"], aircraft=at(40.0, 0.0), min_confidence=0.6)
    held = []
    for target_id, north in ((1, 120.0), (2, 200.0)):
        alert = make_alert(target_id, tier="candidate", position=at(north, 0.0), error_m=3.0)
        rig.store.add(alert)
        rig.policy.announce(rig.store.promote(alert.alert_id, "held 3 s", None, 0.0))
        held.append(alert.alert_id)
    rig.settle()
    assert not rig.commands(M.MAV_CMD_DO_REPOSITION) and not rig.policy.planner.pending
    assert rig.policy.withheld == 2
    for k in range(3):  # other rated alerts, all people: the mission's level rises
        other = make_alert(10 + k, tier="candidate")
        rig.store.add(other)
        rig.store.promote(other.alert_id, "held 3 s", None, 0.0)
        rig.store.decide(other.alert_id, "confirmed", "ana")
    assert rig.store.get(held[0]).confidence > 0.6
    assert rig.store.decide(held[1], "dismissed", "ana").confidence > 0.6
    rig.clock.t += 0.5  # the store is read at most every RATED_UP_CHECK_S
    rig.policy.tick()
    assert not rig.policy.planner.pending
    rig.clock.t += 1.0
    rig.settle()
    (visit,) = rig.commands(M.MAV_CMD_DO_REPOSITION)
    assert visit.params[4:6] == pytest.approx([round(v * 1e7) for v in at(120.0, 0.0)], abs=1)
    queued = [line for line in rig.lines if "visit queued: rated up to" in line]
    assert len(queued) == 1 and "target 1 " in queued[0]
    rig.clock.t += 120.0
    rig.settle()
    assert len(rig.commands(M.MAV_CMD_DO_REPOSITION)) == 1  # the dismissed one never goes


def survey_items() -> list[MissionItem]:
    """The pilot's mission on the vehicle: home, speed, a 4-corner box, DO_JUMP back to 2."""
    wire = [
        WireItem(
            M.MAV_FRAME_GLOBAL,
            M.MAV_CMD_NAV_WAYPOINT,
            x=round(HOME[0] * 1e7),
            y=round(HOME[1] * 1e7),
        ),
        WireItem(2, M.MAV_CMD_DO_CHANGE_SPEED, (1.0, 5.0, -1.0, 0.0)),
    ]
    for n, e in ((200, -100), (200, 100), (40, 100), (40, -100)):
        lat, lon = at(n, e)
        wire.append(
            WireItem(REL, M.MAV_CMD_NAV_WAYPOINT, x=round(lat * 1e7), y=round(lon * 1e7), z=60.0)
        )
    wire.append(WireItem(2, M.MAV_CMD_DO_JUMP, (2.0, -1.0, 0.0, 0.0)))
    return [
        MissionItem(seq, w.frame, w.command, 0, w.autocontinue, *w.params, w.x, w.y, w.z)
        for seq, w in enumerate(wire)
    ]


def test_mission_policy_keeps_the_pilots_mission_and_inserts_the_visits(rig_factory):
    rig = rig_factory(["alert", "mission"], aircraft=at(40.0, 0.0), visit_loiter_s=20.0)
    pilot = survey_items()
    rig.vehicle.missions[0] = list(pilot)
    rig.vehicle.mission_current = 4  # flying to the third corner
    rig.alert(1, 150.0, 50.0)
    rig.alert(2, 100.0, -50.0)
    rig.settle()
    after = rig.vehicle.missions[0]
    loiters = [it for it in after if it.command == M.MAV_CMD_NAV_LOITER_TIME]
    assert [(it.seq, it.param1) for it in loiters] == [(4, 20.0), (5, 20.0)]
    # nearest first from the aircraft at 40 m N: target 2 (100 N, -50 E), then target 1
    assert [(it.x, it.y) for it in loiters] == [
        tuple(round(v * 1e7) for v in at(100.0, -50.0)),
        tuple(round(v * 1e7) for v in at(150.0, 50.0)),
    ]
    kept = [it for it in after if it.command != M.MAV_CMD_NAV_LOITER_TIME]
    assert [(it.command, it.x, it.y, it.z) for it in kept[1:-1]] == [
        (it.command, it.x, it.y, it.z) for it in pilot[1:-1]
    ]
    assert kept[-1].command == M.MAV_CMD_DO_JUMP and kept[-1].param1 == 2.0  # loop unchanged
    assert rig.vehicle.mission_current == 4  # the first visit is what the vehicle flies now
    assert rig.policy.acknowledged == 1
    assert all("mavlink_mission" in a.delivered for a in rig.store.list())


@pytest.mark.parametrize(
    ("north", "east", "error_m", "why"),
    [
        (100.0, 0.0, 40.0, "position error 40 m exceeds 25 m"),
        (100.0, 400.0, 3.0, "300 m outside the mission area (allowed: 200 m)"),
    ],
)
def test_moving_commands_only_to_bounded_positions_in_the_area(
    rig_factory, north, east, error_m, why
):
    rig = rig_factory(["alert", "loiter", "roi"])
    rig.alert(1, north, east, error_m=error_m)
    rig.clock.t += 120.0
    rig.settle()
    assert rig.commands(M.MAV_CMD_DO_REPOSITION) == []
    assert rig.commands(M.MAV_CMD_DO_SET_ROI_LOCATION) == []
    assert (
        f"  -> target 1 (T1-{rig.store.list()[0].short_id[-2:]}): loiter withheld: {why}"
        in rig.lines
    )
    assert rig.policy.withheld == 2  # loiter and roi


def test_the_aircraft_goes_only_to_targets_likely_enough(rig_factory):
    """``min_confidence`` 0.5: an alert 5 % likely a person is told but not flown to; the next,
    80 % likely, is visited."""
    rig = rig_factory(["alert", "loiter"], aircraft=at(40.0, 0.0), min_confidence=0.5)
    rig.alert(1, 100.0, 0.0, confidence=0.05)
    rig.clock.t += 1.0
    rig.alert(2, 150.0, 0.0, confidence=0.8)
    rig.clock.t += 120.0
    rig.settle()
    (visit,) = rig.commands(M.MAV_CMD_DO_REPOSITION)
    assert visit.params[4:6] == pytest.approx([round(v * 1e7) for v in at(150.0, 0.0)], abs=1)
    short = {a.target_id: a.short_id for a in rig.store.list()}
    assert (
        f"  -> target 1 ({short[1]}): loiter withheld: 5 % likely a person, below the 50 % "
        "that moves the aircraft" in rig.lines
    )
    assert rig.policy.withheld == 1


@pytest.mark.parametrize("gimbal", [False, True])
def test_the_roi_pauses_the_search_only_with_a_gimbal(rig_factory, gimbal):
    rig = rig_factory(["roi"], gimbal=gimbal)
    rig.alert(1, 100.0, 0.0)
    rig.settle()
    assert len(rig.commands(M.MAV_CMD_DO_SET_ROI_LOCATION)) == 1
    assert rig.policy.search_paused() is gimbal


def test_a_refined_position_moves_a_queued_visit_or_withdraws_it(rig_factory):
    """Target 1's visit leaves at once; target 2 waits for the interval. Its position, refined
    20 m east, is where the vehicle is sent; target 3's, refined to a 40 m error, is withdrawn
    from the plan; a visit already flown is not sent again."""
    rig = rig_factory(["loiter"], aircraft=at(40.0, 0.0))
    first = rig.alert(1, 60.0, 0.0)
    rig.policy.tick()
    second = rig.alert(2, 150.0, -50.0)
    third = rig.alert(3, 150.0, 60.0)
    rig.settle()
    second.position = at(150.0, -30.0)
    assert rig.policy.refine(second)
    third.error_m = 40.0
    assert rig.policy.refine(third)
    first.position = at(70.0, 0.0)
    assert not rig.policy.refine(first)  # visited already: nothing goes out again
    assert sorted(rig.policy.planner.pending) == [2]
    assert any("target 3" in line and "visit withdrawn: position error 40 m" in line
               for line in rig.lines)  # fmt: skip
    rig.clock.t += 61.0
    rig.settle()
    flown = rig.commands(M.MAV_CMD_DO_REPOSITION)
    assert len(flown) == 2
    assert flown[1].params[4:6] == pytest.approx([round(v * 1e7) for v in at(150.0, -30.0)], abs=1)


COPTER_RTL, COPTER_LAND = 6, 9


def set_mode(rig: Rig, custom_mode: int, name: str) -> None:
    """The vehicle switches mode (as the pilot or a failsafe does); wait for its HEARTBEAT."""
    rig.vehicle.autopilot.custom_mode = custom_mode
    assert wait_until(lambda: rig.telemetry.flight_state.mode == name, 5.0)


def test_no_loiter_or_roi_while_the_vehicle_lands_the_alert_still_goes_out(rig_factory):
    """A confirmed alert while the pilot lands: no DO_REPOSITION (it would switch to GUIDED and
    cancel the landing), no ROI; the STATUSTEXT goes out, and the console says why."""
    rig = rig_factory(["alert", "loiter", "roi"], aircraft=at(40.0, 0.0))
    set_mode(rig, COPTER_LAND, "LAND")
    rig.alert(1, 100.0, 0.0)
    rig.clock.t += 1.0
    rig.policy.tick()
    rig.settle()
    assert not rig.commands(M.MAV_CMD_DO_REPOSITION)
    assert not rig.commands(M.MAV_CMD_DO_SET_ROI_LOCATION)
    assert wait_until(lambda: len(rig.vehicle.statustexts) == 1, 5.0)
    withheld = [line for line in rig.lines if "withheld: vehicle in LAND" in line]
    assert len(withheld) == 2, rig.lines  # loiter and roi, one line each
    assert rig.policy.planner.pending == {}


def test_a_visit_queued_before_rtl_is_withdrawn_when_due(rig_factory):
    """In AUTO the first visit leaves; the second, queued behind the visit interval, is due
    after the pilot switched to RTL: it is withdrawn, not flown."""
    rig = rig_factory(["loiter"], aircraft=at(40.0, 0.0))
    rig.alert(1, 60.0, 0.0)
    rig.clock.t += 1.0
    rig.settle()
    assert len(rig.commands(M.MAV_CMD_DO_REPOSITION)) == 1
    rig.alert(2, 150.0, 0.0)
    set_mode(rig, COPTER_RTL, "RTL")
    rig.clock.t += 120.0
    rig.settle()
    assert len(rig.commands(M.MAV_CMD_DO_REPOSITION)) == 1
    assert any("visit withdrawn: vehicle in RTL" in line for line in rig.lines), rig.lines


def test_a_command_queued_in_auto_is_withheld_if_the_vehicle_returns_before_it_goes(
    rig_factory,
):
    """The outbox asks the policy right before sending (a command queued while the link was
    down meets the vehicle as it is then)."""
    rig = rig_factory(["loiter"], aircraft=at(40.0, 0.0))
    set_mode(rig, COPTER_RTL, "RTL")
    alert = make_alert(7, position=at(60.0, 0.0), error_m=3.0)
    rig.store.add(alert)
    key = _Key(alert.alert_id, "mavlink_loiter", 7, alert.short_id)
    rig.outbox.submit(Reposition(*at(60.0, 0.0), 50.0), key=key)
    rig.settle()
    assert not rig.commands(M.MAV_CMD_DO_REPOSITION)
    assert any("loiter withheld: vehicle in RTL" in line for line in rig.lines), rig.lines
    assert rig.policy.withheld == 1 and rig.policy.refused == 0
