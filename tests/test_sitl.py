"""The project's MAVLink side against the real autopilot: ArduPilot Copter SITL over real UDP.

Skipped unless ``$SARMISSION_SITL`` names the ``arducopter`` binary (``.ci/run`` sets it when
``../shared/sitl/arducopter`` exists). One SITL process serves the whole module, at
:data:`SPEEDUP` times real time, and goes through the life of a flight in file order: power-on
without GPS (``boot``), GPS fix and home, the pilot's take-off and survey in AUTO (``airborne``),
and finally a frozen then rebooted autopilot (``restarted``). The pilot is a plain pymavlink
ground station on SITL's second serial port (:mod:`sitl_harness`); our side is the project's own
MavlinkLink, TelemetryBuffer, CommandSender, Outbox, ActionPolicy and LiveSession. Fixtures
that drive the vehicle through a phase record what our side saw; the tests judge the records.
Nothing here measures speed: every wait is a condition with a generous deadline.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scripted_detector import ScriptedDetector
from sitl_harness import (
    STARTED_PIDS,
    Pilot,
    Sitl,
    Waypoint,
    box_survey,
    distance_m,
    process_group_alive,
)
from sitl_harness import wait_for as harness_wait_for

from sarmission.alerts.model import Alert
from sarmission.alerts.store import AlertStore
from sarmission.data.frames import Frame
from sarmission.geo.geolocate import PlatformPose
from sarmission.mavlink.commands import CommandResult, CommandSender, Outbox
from sarmission.mavlink.connection import M, MavlinkLink
from sarmission.mavlink.telemetry import StaleTelemetry
from sarmission.mission.actions import ActionPolicy, ascii_statustext
from sarmission.mission.config import ActionsConfig, MissionConfig, load_mission
from sarmission.mission.live import LiveSession
from sarmission.mission.visits import MoveGate

#: Simulation speed-up: ArduPilot's boot, GPS fix, arming and flight go this much faster. The
#: autopilot's clock (``time_boot_ms``) then runs this much faster than ours, which no real
#: autopilot does; the reboot (``restarted``) is therefore at real time, where recognising a new
#: boot timeline (a steady offset to our clock) is what the telemetry buffer has to do.
SPEEDUP = 10
#: Where the simulated vehicle powers on (lat, lon, alt, heading) and where it reboots: 445 m
#: further north, so that anything left over from before the reboot is far off the new state.
HOME = (43.0, 10.0, 0.0, 0.0)
MOVED_HOME = (43.004, 10.0, 0.0, 0.0)
#: Survey altitude above home (m).
ALT = 30.0
#: Deadline for anything the autopilot has to do (boot, fix, arm, fly a few hundred metres).
DEADLINE_S = 90.0
#: Our link's source ids: the vehicle's system, MAV_COMP_ID_ONBOARD_COMPUTER.
OUR_IDS = (1, M.MAV_COMP_ID_ONBOARD_COMPUTER)

_DN = 1.0 / 111_111.0


def offset(lat: float, lon: float, north_m: float, east_m: float) -> tuple[float, float]:
    """The point ``north_m``/``east_m`` metres from ``lat``/``lon``."""
    return lat + north_m * _DN, lon + east_m * _DN / math.cos(math.radians(lat))


def wait_for(cond: Callable[[], Any], timeout: float = DEADLINE_S) -> Any:
    """:func:`sitl_harness.wait_for` with :data:`DEADLINE_S` by default."""
    return harness_wait_for(cond, timeout)


def mission_config(policy: list[str]) -> MissionConfig:
    """The mission as flown here: SITL's home, the survey box inside the area, a hard-mounted
    nadir camera (SITL has no gimbal), a small image, the survey altitude, a candidate
    confirmed at its lock."""
    return load_mission(
        overrides={
            "name": "sitl",
            "area.home_lat": HOME[0],
            "area.home_lon": HOME[1],
            "area.rectangle_m": [-200.0, -200.0, 400.0, 400.0],
            "camera.width": 640,
            "camera.height": 360,
            "camera.gimbal": False,
            "camera.mount_pitch_deg": -90.0,
            "flight.altitude_m": ALT,
            "actions.policy": policy,
            # confirmed at the lock: these tests are about the autopilot, not the evidence
            "confirm.min_seen_s": 0.0,
            "confirm.min_sightings": 1,
        }
    )


class StampedFrames:
    """A camera stand-in: grey frames stamped with ``time.monotonic()`` when read, one every
    ``period_s``, ``count`` of them (None: until closed)."""

    def __init__(self, count: int | None, period_s: float = 0.05) -> None:
        self.count = count
        self.period_s = period_s
        self.skipped = 0
        self.read_count = 0
        self._image = np.full((360, 640, 3), 90, np.uint8)
        self._closed = threading.Event()

    def read(self) -> Frame | None:
        if self._closed.wait(self.period_s) or (
            self.count is not None and self.read_count >= self.count
        ):
            return None
        self.read_count += 1
        return Frame(self.read_count - 1, time.monotonic(), self._image)

    def close(self) -> None:
        self._closed.set()


def open_session(
    sitl: Sitl,
    db: Path,
    policy: list[str],
    detector: Any = None,
    source: StampedFrames | None = None,
) -> tuple[LiveSession, list[str]]:
    """A LiveSession on our SITL port; returns it and the list its console writes to."""
    lines: list[str] = []
    session = LiveSession(
        mission_config(policy),
        detector or ScriptedDetector([]),
        source or StampedFrames(0),
        sitl.link_url,
        str(db),
        console=lines.append,
        connect_timeout_s=DEADLINE_S,
    )
    return session, lines


def alert_at(lat: float, lon: float, target_id: int = 1) -> Alert:
    """A stored-alert stand-in at ``lat``/``lon`` for the action policy."""
    return Alert(
        mission_id="sitl",
        target_id=target_id,
        class_name="swimmer",
        score=0.9,
        lock_time=time.time(),
        frame_index=0,
        position=(lat, lon),
        error_m=3.0,
    )


# -- the shared vehicle -------------------------------------------------------------------------
@dataclass
class Vehicle:
    """The module's SITL process and the pilot at its ground station."""

    sitl: Sitl
    pilot: Pilot
    workdir: Path
    survey: list[Waypoint] = field(default_factory=list)

    def home_latlon(self) -> tuple[float, float]:
        home = self.pilot.latest("HOME_POSITION")
        assert home is not None, "the autopilot has not reported its home"
        return home.latitude / 1e7, home.longitude / 1e7

    def position(self) -> tuple[float, float, float]:
        """The autopilot's newest position as the pilot sees it: lat, lon, metres above home."""
        p = self.pilot.position()
        assert p is not None
        return p.lat / 1e7, p.lon / 1e7, p.relative_alt / 1000.0

    def distance_to(self, lat: float, lon: float) -> float:
        here = self.position()
        return distance_m(here[0], here[1], lat, lon)


@pytest.fixture(scope="module")
def no_stray_sitl() -> Iterator[None]:
    """After the module: every SITL process group it started is gone."""
    first = len(STARTED_PIDS)
    yield
    left = [pid for pid in STARTED_PIDS[first:] if process_group_alive(pid)]
    assert not left, f"SITL process groups still alive after the tests: {left}"


@pytest.fixture(scope="module")
def vehicle(
    sitl_binary: Path, tmp_path_factory: pytest.TempPathFactory, no_stray_sitl: None
) -> Iterator[Vehicle]:
    """SITL powered on with its simulated GPS switched off (``SIM_GPS1_ENABLE 0``), so that
    the time before a fix lasts as long as the ``boot`` fixture needs; the pilot connected."""
    workdir = tmp_path_factory.mktemp("sitl")
    sitl = Sitl(
        sitl_binary,
        workdir / "sitl",
        speedup=SPEEDUP,
        home=HOME,
        extra_params={"SIM_GPS1_ENABLE": 0},
    )
    pilot = Pilot(sitl.gcs_url)
    sitl.start()
    try:
        if not wait_for(lambda: pilot.autopilot):
            raise RuntimeError(f"no HEARTBEAT from SITL; it said:\n{sitl.log_tail()}")
        pilot.request_streams()
        yield Vehicle(sitl, pilot, workdir)
    finally:
        pilot.close()
        sitl.stop()


@dataclass
class Sample:
    """One GLOBAL_POSITION_INT or HOME_POSITION our link received, and the buffer's state right
    after it took the message."""

    mtype: str
    arrival: float
    lat: float
    lon: float
    rel_alt: float
    buffer_home: tuple[float, float, float] | None
    pose: PlatformPose | None


def record_samples(session: LiveSession, into: list[Sample]) -> None:
    """Subscribe after the session's buffer, so each sample sees the buffer with the message in."""
    buf = session.telemetry
    assert session.link is not None

    def on_message(msg: Any, arrival: float) -> None:
        if msg.get_type() == "HOME_POSITION":
            lat, lon, rel = msg.latitude / 1e7, msg.longitude / 1e7, 0.0
        else:
            lat, lon, rel = msg.lat / 1e7, msg.lon / 1e7, msg.relative_alt / 1000.0
        into.append(Sample(msg.get_type(), arrival, lat, lon, rel, buf.home, buf.pose_at(arrival)))

    session.link.subscribe(on_message, ["GLOBAL_POSITION_INT", "HOME_POSITION"])


@dataclass
class BootRecord:
    """What our LiveSession saw and got back while the autopilot came up (``boot``)."""

    samples: list[Sample] = field(default_factory=list)
    gps_enabled_at: float = math.inf
    lookup_without_gps: PlatformPose | StaleTelemetry | None = None
    home_without_gps: tuple[float, float, float] | None = None
    reposition_without_gps: CommandResult | None = None
    policy_refused: int = 0
    policy_delivered: int = 0
    policy_pending: int = 0
    policy_withheld: int = 0
    console: list[str] = field(default_factory=list)
    home_message: Any = None
    pose_after: PlatformPose | StaleTelemetry | None = None
    buffer_home_after: tuple[float, float, float] | None = None
    pilot_position_after: Any = None


@pytest.fixture(scope="module")
def boot(vehicle: Vehicle) -> BootRecord:
    """From power-on to home, through a LiveSession (its own stream requests, buffer, outbox and
    action policy with ``loiter``): without GPS, look at the buffer and have a target's loiter
    and a DO_REPOSITION of our own answered; then switch the simulated GPS on and wait for the
    fix, HOME_POSITION and a pose. Every position and home message is recorded with the
    buffer's state right after it."""
    pilot = vehicle.pilot
    if pilot.latest("HOME_POSITION") is not None or pilot.armed:
        raise RuntimeError("boot must run first on the shared SITL (keep the file's order)")
    rec = BootRecord()
    session, rec.console = open_session(vehicle.sitl, vehicle.workdir / "boot.db", ["loiter"])
    try:
        assert session.link is not None
        record_samples(session, rec.samples)
        zero = lambda: [s for s in rec.samples if s.lat == 0 and s.lon == 0]  # noqa: E731
        if not wait_for(lambda: len(zero()) >= 20 and session.telemetry.newest_time("attitude")):
            raise RuntimeError(f"no telemetry from SITL: {vehicle.sitl.log_tail()}")
        rec.home_without_gps = session.telemetry.home
        rec.lookup_without_gps = session.telemetry.lookup(time.monotonic())

        target = offset(HOME[0], HOME[1], 100.0, 0.0)
        rec.reposition_without_gps = CommandSender(session.link).reposition(*target, ALT)
        alert = alert_at(*target)
        session.store.add(alert)
        session.actions.announce(alert)
        actions = session.actions  # ticked as the controller does each frame: the visit leaves
        wait_for(
            lambda: actions.tick() or (actions.pending() == 0 and not actions.planner.pending), 30.0
        )
        rec.policy_refused = session.actions.refused
        rec.policy_delivered = session.actions.delivered
        rec.policy_pending = session.actions.pending()
        rec.policy_withheld = session.actions.withheld

        rec.gps_enabled_at = time.monotonic()
        pilot.set_param("SIM_GPS1_ENABLE", 1)
        rec.home_message = pilot.wait_home(DEADLINE_S)
        wait_for(
            lambda: (
                session.telemetry.pose_at(time.monotonic()) is not None
                and session.telemetry.home is not None
            )
        )
        now = time.monotonic()
        rec.pose_after = session.telemetry.lookup(now)
        rec.buffer_home_after = session.telemetry.home
        rec.pilot_position_after = pilot.position()
    finally:
        session.close(drain_s=0.0)
    return rec


@pytest.fixture(scope="module")
def with_home(boot: BootRecord, vehicle: Vehicle) -> Vehicle:
    """The vehicle on the ground, disarmed, with a GPS fix and home."""
    return vehicle


@pytest.fixture(scope="module")
def airborne(with_home: Vehicle) -> Vehicle:
    """The pilot's flight: GUIDED, arm, take off to :data:`ALT`, upload a looping 300 m box
    survey from home and switch to AUTO."""
    v = with_home
    v.pilot.fly_up(ALT, DEADLINE_S)
    v.survey = box_survey(*v.home_latlon(), ALT)
    result = v.pilot.upload_mission(v.survey)
    if result != M.MAV_MISSION_ACCEPTED:
        raise RuntimeError(f"survey upload refused: {result}")
    v.pilot.set_mode("AUTO")
    return v


@pytest.fixture
def link(vehicle: Vehicle) -> Iterator[MavlinkLink]:
    """Our MavlinkLink on SITL's companion port, the autopilot found."""
    with MavlinkLink(vehicle.sitl.link_url) as our_link:
        assert our_link.wait_autopilot(DEADLINE_S), "no autopilot HEARTBEAT on our port"
        yield our_link


Item = tuple[int, int, int, float, tuple[float, float, float, float]]


def mission_items(pilot: Pilot) -> list[Item]:
    """The autopilot's mission as the pilot reads it back: (command, lat degE7, lon degE7, alt,
    params 1-4) per item, item 0 (home) included."""
    return [
        (m.command, m.x, m.y, round(m.z, 2), (m.param1, m.param2, m.param3, m.param4))
        for m in pilot.read_mission()
    ]


def survey_items(survey: list[Waypoint]) -> list[Item]:
    """The pilot's uploaded survey in the form :func:`mission_items` reads it back, without the
    home placeholder (ArduPilot writes its home there)."""
    return [
        (w.command, round(w.lat * 1e7), round(w.lon * 1e7), round(w.alt, 2), w.params)
        for w in survey[1:]
    ]


def survey_lost(after: list[Item], survey: list[Waypoint]) -> str:
    """Why the pilot's survey is not kept in the read-back ``after`` ('' when it is): each of its
    items, in order (others may lie between), and each DO_JUMP still landing on the item the
    pilot's landed on (its target number may change around inserted items)."""
    jump = M.MAV_CMD_DO_JUMP
    where: dict[int, int] = {}  # the pilot's seq -> seq in the read-back
    k = 1
    for seq, item in enumerate(survey_items(survey), start=1):

        def same(got: Item, item: Item = item) -> bool:
            if item[0] == jump:
                return got[0] == jump and got[4][1:] == item[4][1:]
            return got == item

        while k < len(after) and not same(after[k]):
            k += 1
        if k == len(after):
            return f"the pilot's item {seq} {item} is missing (or out of order)"
        where[seq] = k
        k += 1
    for seq, w in enumerate(survey):
        if w.command == jump:
            target, got = int(w.params[0]), int(after[where[seq]][4][0])
            if where.get(target) != got:
                return (
                    f"the pilot's DO_JUMP {seq} -> {target} now jumps to {got}, not to "
                    f"{where.get(target)}"
                )
    return ""


# -- before the GPS fix ---------------------------------------------------------------------------
def test_no_pose_and_no_home_while_autopilot_reports_no_position(
    sitl_binary: Path, boot: BootRecord
) -> None:
    """ArduPilot without a GPS fix streams GLOBAL_POSITION_INT at 0, 0 and has no home: the
    buffer must give no pose and no home then, whatever else (attitude) it has."""
    zero = [
        s for s in boot.samples if s.mtype == "GLOBAL_POSITION_INT" and s.lat == 0 and s.lon == 0
    ]
    assert len(zero) >= 20
    assert all(s.pose is None and s.buffer_home is None for s in zero)
    assert boot.home_without_gps is None
    assert isinstance(boot.lookup_without_gps, StaleTelemetry), boot.lookup_without_gps


def test_no_pose_between_gps_fix_and_home_position(sitl_binary: Path, boot: BootRecord) -> None:
    """ArduPilot reports its GPS position about 10 simulated seconds before HOME_POSITION.
    Without home the height above ground means nothing: no home, no pose (so no fix)."""
    window = [
        s
        for s in boot.samples
        if s.mtype == "GLOBAL_POSITION_INT" and s.lat != 0 and s.buffer_home is None
    ]
    assert window, "ArduPilot sent no position before its home (the window this test needs)"
    with_pose = [s for s in window if s.pose is not None]
    assert not with_pose, (
        f"{len(with_pose)} of {len(window)} positions before HOME_POSITION "
        f"gave a pose, e.g. {with_pose[0].pose}"
    )


def test_pose_and_home_match_the_autopilot_after_fix_and_home(
    sitl_binary: Path, boot: BootRecord
) -> None:
    """Once the fix and HOME_POSITION are in, the buffer's home is the autopilot's and its pose
    is where the autopilot says it is (on the ground, so the two links agree closely)."""
    home = boot.home_message
    assert boot.buffer_home_after == pytest.approx(
        (home.latitude / 1e7, home.longitude / 1e7, home.altitude / 1000.0), abs=1e-6
    )
    pose, pilot_pos = boot.pose_after, boot.pilot_position_after
    assert isinstance(pose, PlatformPose), f"no pose after fix and home: {pose}"
    assert distance_m(pose.lat, pose.lon, pilot_pos.lat / 1e7, pilot_pos.lon / 1e7) < 1.0
    assert pose.rel_alt_m == pytest.approx(pilot_pos.relative_alt / 1000.0, abs=0.5)
    assert distance_m(pose.lat, pose.lon, HOME[0], HOME[1]) < 5.0


def test_reposition_refused_before_the_autopilot_has_a_position_and_loiter_withheld(
    sitl_binary: Path, boot: BootRecord
) -> None:
    """Without a position ArduPilot refuses DO_REPOSITION with MAV_RESULT_FAILED: our sender
    reports the refusal after one attempt (no retries on an answer). The action policy never
    sends its loiter to a disarmed vehicle on the ground: withheld, with the reason, not
    delivered, not left queued."""
    result = boot.reposition_without_gps
    assert result is not None and not result.accepted
    assert result.result == M.MAV_RESULT_FAILED and result.attempts == 1
    assert "MAV_RESULT_FAILED" in result.error
    assert (boot.policy_refused, boot.policy_delivered, boot.policy_pending) == (0, 0, 0)
    assert boot.policy_withheld == 1
    assert any("loiter withheld: vehicle disarmed" in line for line in boot.console), boot.console


# -- on the ground, with home ---------------------------------------------------------------------
def test_alert_statustext_is_routed_to_the_ground_station(
    sitl_binary: Path, with_home: Vehicle, link: MavlinkLink
) -> None:
    """An alert STATUSTEXT our link sends to the autopilot reaches the pilot's port, routed by
    ArduPilot, with our system/component ids and severity ALERT (and from no one else)."""
    pilot = with_home.pilot
    text = f"SAR swimmer 43.00100,10.00200 t{time.monotonic_ns() % 100000}"
    assert (link.source_system, link.source_component) == OUR_IDS
    result = CommandSender(link).statustext(text, M.MAV_SEVERITY_ALERT)
    assert result.accepted, result.error
    seen = wait_for(lambda: [s for s in pilot.statustexts if s.text == text])
    assert seen, "our STATUSTEXT did not reach the ground station"
    assert all((s.src_system, s.src_component) == OUR_IDS for s in seen), seen
    assert all(s.severity == M.MAV_SEVERITY_ALERT for s in seen)


def test_long_statustext_reaches_the_ground_station_in_chunks(
    sitl_binary: Path, with_home: Vehicle, link: MavlinkLink
) -> None:
    """A text longer than 50 characters goes as chunks sharing one id (MAVLink 2 STATUSTEXT
    ``id``/``chunk_seq``); ArduPilot passes them on unchanged, so the pilot can join them."""
    pilot = with_home.pilot
    text = (
        "SAR swimmer with life jacket at 43.0012345, 10.0023456 (+-4 m) "
        f"t{time.monotonic_ns() % 100000}"
    )
    assert len(text) > 50
    result = CommandSender(link).statustext(text, M.MAV_SEVERITY_ALERT)
    assert result.accepted and result.attempts == 2
    chunks = wait_for(
        lambda: (
            (
                c := [
                    s
                    for s in pilot.statustexts_from(*OUR_IDS)
                    if s.text_id and text.startswith(s.text[:20])
                ]
            )
            and c
        )
    )
    assert chunks, "no chunked STATUSTEXT from us at the ground station"
    ids = {c.text_id for c in chunks}
    assert len(ids) == 1
    joined = wait_for(
        lambda: (
            "".join(
                s.text
                for s in sorted(
                    (s for s in pilot.statustexts_from(*OUR_IDS) if s.text_id in ids),
                    key=lambda s: s.chunk_seq,
                )
            )
            == text
        ),
        10.0,
    )
    assert joined, [c.text for c in pilot.statustexts_from(*OUR_IDS) if c.text_id in ids]


def test_reposition_on_the_ground_is_accepted_but_does_not_fly(
    sitl_binary: Path, with_home: Vehicle, link: MavlinkLink
) -> None:
    """With a position but disarmed, ArduPilot accepts DO_REPOSITION and switches to GUIDED,
    yet the vehicle stays on the ground: an accepted loiter is not proof of flight."""
    pilot = with_home.pilot
    assert not pilot.armed, "this test needs the vehicle disarmed (keep the file's order)"
    lat, lon, _ = with_home.position()
    result = CommandSender(link).reposition(*offset(lat, lon, 100.0, 0.0), ALT)
    assert result.accepted, result.error
    assert wait_for(lambda: pilot.mode() == 4, 10.0), pilot.mode()
    moved_since = time.monotonic()
    wait_for(lambda: (pilot.latest_arrival("GLOBAL_POSITION_INT") or 0) > moved_since + 1.0, 10.0)
    here = with_home.position()
    assert not pilot.armed
    assert distance_m(lat, lon, here[0], here[1]) < 1.0 and abs(here[2]) < 1.0


# -- in flight ------------------------------------------------------------------------------------
def test_reposition_in_flight_switches_to_guided_and_flies_there(
    sitl_binary: Path, airborne: Vehicle, link: MavlinkLink
) -> None:
    """In AUTO on the survey, DO_REPOSITION as COMMAND_INT is accepted, ArduPilot switches to
    GUIDED and the vehicle flies to the point."""
    pilot = airborne.pilot
    assert pilot.armed and pilot.mode() == 3, "needs the pilot's survey in AUTO"
    lat0, lon0 = airborne.home_latlon()
    target = offset(lat0, lon0, 150.0, -150.0)  # west of the survey box
    before = airborne.distance_to(*target)
    result = CommandSender(link).reposition(*target, ALT)
    assert result.accepted and result.result == M.MAV_RESULT_ACCEPTED, result.error
    assert wait_for(lambda: pilot.mode() == 4, 10.0), pilot.mode()
    assert wait_for(lambda: airborne.distance_to(*target) < 5.0), (
        f"{airborne.distance_to(*target):.0f} m from the point, {before:.0f} m before"
    )
    assert airborne.position()[2] == pytest.approx(ALT, abs=3.0)


def test_roi_in_flight_turns_the_vehicle_to_the_point(
    sitl_binary: Path, airborne: Vehicle, link: MavlinkLink
) -> None:
    """DO_SET_ROI_LOCATION as COMMAND_INT is accepted in flight; with no gimbal ArduPilot turns
    the whole vehicle until it faces the point."""
    pilot = airborne.pilot
    assert pilot.armed
    lat, lon, _ = airborne.position()
    heading = pilot.position().hdg / 100.0
    # a point 100 m away, 120 degrees off the current heading
    bearing = math.radians((heading + 120.0) % 360.0)
    target = offset(lat, lon, 100.0 * math.cos(bearing), 100.0 * math.sin(bearing))

    def heading_error() -> float:
        here = airborne.position()
        dn = (target[0] - here[0]) / _DN
        de = (target[1] - here[1]) / _DN * math.cos(math.radians(here[0]))
        want = math.degrees(math.atan2(de, dn)) % 360.0
        return abs((pilot.position().hdg / 100.0 - want + 180.0) % 360.0 - 180.0)

    start_error = heading_error()
    result = CommandSender(link).set_roi(*target, 0.0)
    assert result.accepted and result.result == M.MAV_RESULT_ACCEPTED, result.error
    assert wait_for(lambda: heading_error() < 10.0), (
        f"heading {heading_error():.0f} deg off the point, {start_error:.0f} deg before"
    )


def test_reposition_keeps_the_pilots_mission(
    sitl_binary: Path, airborne: Vehicle, link: MavlinkLink
) -> None:
    """The pilot's survey, read back after our DO_REPOSITION, is item for item the one the
    pilot uploaded: a reposition flies the vehicle, it does not touch the stored mission."""
    pilot = airborne.pilot
    before = mission_items(pilot)
    assert before[1:] == survey_items(airborne.survey)
    lat, lon, _ = airborne.position()
    result = CommandSender(link).reposition(*offset(lat, lon, -40.0, 30.0), ALT)
    assert result.accepted, result.error
    assert mission_items(pilot) == before


def test_mission_policy_keeps_the_pilots_mission(
    sitl_binary: Path, airborne: Vehicle, link: MavlinkLink, tmp_path: Path
) -> None:
    """Action policy ``mission`` for a target: the autopilot's mission afterwards holds a loiter
    at the target and still the pilot's survey, in order, its loop closing on the same item, and
    the loiter is the item the vehicle flies to now."""
    pilot = airborne.pilot
    assert mission_items(pilot)[1:] == survey_items(airborne.survey)
    lat, lon, _ = airborne.position()
    target = offset(lat, lon, 60.0, 60.0)
    outbox = Outbox(CommandSender(link))
    lines: list[str] = []
    home = airborne.home_latlon()
    area = [(-500.0, -500.0), (-500.0, 800.0), (800.0, 800.0), (800.0, -500.0)]
    gate = MoveGate(area, home, max_error_m=25.0, margin_m=100.0)
    with AlertStore(tmp_path / "alerts.db") as store:
        policy = ActionPolicy(
            ActionsConfig(policy=["mission"]),
            outbox,
            store,
            survey_altitude_m=ALT,
            console=lines.append,
            move_gate=gate,
            aircraft_position=lambda: airborne.position()[:2],
            takeover=lambda: "",
        )
        alert = alert_at(*target)
        store.add(alert)
        try:
            assert policy.announce(alert) == 1
            assert wait_for(
                lambda: policy.tick() or (policy.pending() == 0 and not policy.planner.pending),
                60.0,
            ), "mission action still queued"
        finally:
            outbox.close()
    assert (policy.delivered, policy.refused) == (1, 0), lines
    after = mission_items(pilot)
    loiters = [k for k, it in enumerate(after) if it[0] == M.MAV_CMD_NAV_LOITER_TIME]
    assert (
        loiters
        and distance_m(after[loiters[0]][1] / 1e7, after[loiters[0]][2] / 1e7, *target) < 1.0
    )
    lost = survey_lost(after, airborne.survey)
    assert not lost, f"{lost}; read back {after}"
    current = pilot.wait_message(
        ["MISSION_CURRENT"],
        lambda m: m.seq == loiters[0],
        10.0,
        send=lambda: pilot.send(
            pilot.conn.mav.command_long_encode(
                *pilot.target,
                M.MAV_CMD_REQUEST_MESSAGE,
                0,
                float(M.MAVLINK_MSG_ID_MISSION_CURRENT),
                0,
                0,
                0,
                0,
                0,
                0,
            )
        ),
    )
    assert current is not None, f"the vehicle does not fly to the loiter at {loiters[0]}"


def test_live_session_alert_reaches_the_pilot_with_the_position_below(
    sitl_binary: Path, airborne: Vehicle, tmp_path: Path
) -> None:
    """End to end: a LiveSession locks a target at the image centre (scripted detector), places
    it from SITL's telemetry, and its alert STATUSTEXT reaches the pilot through ArduPilot. The
    camera looks straight down from a hovering vehicle, so the target lies below the vehicle:
    within h * tan(tilt) of it, under 3 m at 30 m for a hover tilt under 5 degrees."""
    pilot = airborne.pilot
    lat0, lon0 = airborne.home_latlon()
    spot = offset(lat0, lon0, 100.0, 100.0)
    ack = pilot.command_int(
        M.MAV_CMD_DO_REPOSITION,
        M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        (-1.0, M.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE, 0.0, math.nan),
        *spot,
        ALT,
    )
    assert ack is not None and ack.result == M.MAV_RESULT_ACCEPTED

    def hovering() -> bool:
        p = pilot.position()
        return (
            airborne.distance_to(*spot) < 1.0
            and math.hypot(p.vx, p.vy) < 20  # cm/s
            and abs(p.relative_alt / 1000.0 - ALT) < 1.0
        )

    assert wait_for(hovering), f"not hovering at the spot: {pilot.position()}"
    box = (315.0, 175.0, 325.0, 185.0)  # the centre of the 640 x 360 image
    n = 12
    source = StampedFrames(n)
    session, lines = open_session(
        airborne.sitl,
        tmp_path / "alerts.db",
        ["alert"],
        ScriptedDetector([[(box, 0.9, 0)]] * n),
        source,
    )
    try:
        assert wait_for(lambda: session.telemetry.pose_at(time.monotonic()) is not None), (
            f"no pose: {session.telemetry.lookup(time.monotonic())}"
        )
        session.run()
        here = airborne.position()
    finally:
        summary = session.close()
    with AlertStore(tmp_path / "alerts.db") as store:
        alerts = store.list()
    assert len(alerts) == 1, (lines, summary)
    alert = alerts[0]
    assert alert.position is not None, alert.position_note
    assert distance_m(*alert.position, here[0], here[1]) < 3.0
    text = ascii_statustext(alert)
    seen = wait_for(lambda: [s for s in pilot.statustexts_from(*OUR_IDS) if s.text == text], 10.0)
    assert seen and all(s.severity == M.MAV_SEVERITY_ALERT for s in seen), (text, lines)


# -- link loss and reboot -----------------------------------------------------------------------
@dataclass
class RestartRecord:
    """What a running LiveSession saw while the autopilot froze and rebooted (``restarted``)."""

    ids_before: tuple[int, int] | None = None
    pose_before: PlatformPose | None = None
    home_before: tuple[float, float, float] | None = None
    went_down: bool = False
    pending_while_down: int = 0
    restarted_at: float = math.inf
    came_back: bool = False
    ids_after: tuple[int, int] | None = None
    samples: list[Sample] = field(default_factory=list)
    interval_acks: list[float] = field(default_factory=list)
    home_message: Any = None
    pose_after: PlatformPose | StaleTelemetry | None = None
    buffer_home_after: tuple[float, float, float] | None = None
    pilot_position_after: Any = None
    alert_id: str = ""
    alert_text: str = ""
    alert_seen: list[Any] = field(default_factory=list)
    alert_delivered: bool = False
    console: list[str] = field(default_factory=list)


@pytest.fixture(scope="module")
def restarted(airborne: Vehicle) -> RestartRecord:
    """A LiveSession runs (blank frames) while the autopilot is frozen (SIGSTOP) until the link
    is lost, an alert is announced (queued), and the autopilot is killed and booted again on the
    same ports at :data:`MOVED_HOME` (eeprom kept, ``time_boot_ms`` from 0), at real time (see
    :data:`SPEEDUP`). Records until the pilot has the new home and the session's buffer a pose."""
    v = airborne
    rec = RestartRecord()
    source = StampedFrames(None)
    session, rec.console = open_session(v.sitl, v.workdir / "restart.db", ["alert"], None, source)
    stop = threading.Event()
    runner = threading.Thread(target=session.run, kwargs={"stop": stop}, daemon=True)
    try:
        link = session.link
        assert link is not None
        record_samples(session, rec.samples)
        link.subscribe(
            lambda m, a: (
                rec.interval_acks.append(a) if m.command == M.MAV_CMD_SET_MESSAGE_INTERVAL else None
            ),
            ["COMMAND_ACK"],
        )
        runner.start()
        wait_for(lambda: session.telemetry.pose_at(time.monotonic()) is not None)
        rec.ids_before = link.autopilot
        rec.pose_before = session.telemetry.pose_at(time.monotonic())
        rec.home_before = session.telemetry.home

        v.sitl.pause()
        rec.went_down = bool(wait_for(lambda: not link.link_ok, 30.0))
        wait_for(lambda: any("link lost" in line for line in rec.console), 10.0)
        lat, lon, _ = v.position()
        alert = alert_at(*offset(lat, lon, -20.0, 20.0), target_id=99)
        session.store.add(alert)
        session.actions.announce(alert)
        rec.alert_id, rec.alert_text = alert.alert_id, ascii_statustext(alert)
        time.sleep(0.5)  # the outbox worker polls it a few times while the link is down
        rec.pending_while_down = session.actions.pending()

        rec.restarted_at = time.monotonic()
        v.sitl.restart(home=MOVED_HOME, speedup=1)
        rec.came_back = bool(wait_for(lambda: link.link_ok, DEADLINE_S))
        rec.ids_after = link.autopilot
        v.pilot.wait_heartbeat()
        v.pilot.forget("HOME_POSITION", "GLOBAL_POSITION_INT")
        v.pilot.request_streams()  # the ground station asks again, as it does after a reboot
        moved = (round(MOVED_HOME[0] * 1e7), round(MOVED_HOME[1] * 1e7))
        rec.home_message = wait_for(
            lambda: (
                (h := v.pilot.latest("HOME_POSITION")) is not None
                and (h.latitude, h.longitude) == moved
                and h
            )
        )
        wait_for(
            lambda: (
                session.telemetry.pose_at(time.monotonic()) is not None
                and session.telemetry.home is not None
                and distance_m(*session.telemetry.home[:2], *MOVED_HOME[:2]) < 1.0
            )
        )
        rec.pose_after = session.telemetry.lookup(time.monotonic())
        rec.buffer_home_after = session.telemetry.home
        rec.pilot_position_after = v.pilot.position()
        wait_for(
            lambda: (
                len(
                    [
                        s
                        for s in rec.samples
                        if s.arrival > rec.restarted_at
                        and s.mtype == "GLOBAL_POSITION_INT"
                        and s.pose is not None
                    ]
                )
                >= 20
            )
        )
        rec.alert_seen = wait_for(
            lambda: [
                s
                for s in v.pilot.statustexts_from(*OUR_IDS)
                if s.text == rec.alert_text and s.arrival > rec.restarted_at
            ],
            30.0,
        )
    finally:
        stop.set()
        source.close()
        runner.join(timeout=10.0)
        session.close(drain_s=0.0)
    with AlertStore(v.workdir / "restart.db") as store:
        stored = store.get(rec.alert_id) if rec.alert_id else None
        rec.alert_delivered = stored is not None and stored.mavlink_sent
    return rec


def test_link_loss_is_reported_when_the_autopilot_freezes(
    sitl_binary: Path, restarted: RestartRecord
) -> None:
    """A frozen autopilot (SIGSTOP: no more HEARTBEAT) makes ``link_ok`` false; the session says
    so on the console; an alert submitted meanwhile stays queued."""
    assert restarted.ids_before == (1, 1)
    assert restarted.went_down
    assert any("link lost" in line for line in restarted.console), restarted.console
    assert restarted.pending_while_down == 1


def test_link_readopts_the_rebooted_autopilot_and_streams_resume(
    sitl_binary: Path, restarted: RestartRecord
) -> None:
    """After the reboot on the same ports the link is up again with the same autopilot; ArduPilot
    forgot our message intervals, so the link asks again (acknowledged after the reboot) and
    positions flow; the alert queued while down reaches the pilot after the reboot."""
    r = restarted
    assert r.came_back and r.ids_after == r.ids_before
    assert any("link back" in line for line in r.console), r.console
    assert [a for a in r.interval_acks if a > r.restarted_at], "no stream request after reboot"
    after = [
        s
        for s in r.samples
        if s.arrival > r.restarted_at and s.mtype == "GLOBAL_POSITION_INT" and s.lat != 0
    ]
    assert after, "no position from the rebooted autopilot on our link"
    assert r.alert_seen and all(s.severity == M.MAV_SEVERITY_ALERT for s in r.alert_seen)
    assert r.alert_delivered, "the alert store does not record the delivery"


def test_pose_after_reboot_is_the_new_state_only(
    sitl_binary: Path, restarted: RestartRecord
) -> None:
    """After the reboot the vehicle sits on the ground 445 m north of where it flew: every pose
    the buffer gives at a post-reboot position message is that message's position (nothing
    from before the reboot mixed in), and the final pose and home are the autopilot's."""
    r = restarted
    assert r.pose_before is not None and r.pose_before.rel_alt_m > ALT / 2
    after = [
        s
        for s in r.samples
        if s.arrival > r.restarted_at
        and s.mtype == "GLOBAL_POSITION_INT"
        and s.lat != 0
        and s.pose is not None
    ]
    assert after, "no pose after the reboot"
    mixed = [
        s
        for s in after
        if distance_m(s.pose.lat, s.pose.lon, s.lat, s.lon) > 2.0
        or abs(s.pose.rel_alt_m - s.rel_alt) > 1.0
    ]
    assert not mixed, [(s.pose, s.lat, s.lon, s.rel_alt) for s in mixed[:3]]
    pose, pilot_pos = r.pose_after, r.pilot_position_after
    assert isinstance(pose, PlatformPose), f"no pose after the reboot: {pose}"
    assert distance_m(pose.lat, pose.lon, pilot_pos.lat / 1e7, pilot_pos.lon / 1e7) < 1.0
    assert distance_m(pose.lat, pose.lon, *MOVED_HOME[:2]) < 5.0
    assert abs(pose.rel_alt_m) < 1.0
    home = r.home_message
    assert r.buffer_home_after == pytest.approx(
        (home.latitude / 1e7, home.longitude / 1e7, home.altitude / 1000.0), abs=1e-6
    )


def test_no_pose_with_the_home_from_before_the_reboot(
    sitl_binary: Path, restarted: RestartRecord
) -> None:
    """A rebooted autopilot has no home until its new GPS fix; a pose computed meanwhile with
    the old home (445 m away here) would place targets against the wrong ground reference."""
    r = restarted
    assert r.home_before is not None
    stale = [
        s
        for s in r.samples
        if s.arrival > r.restarted_at and s.pose is not None and s.buffer_home == r.home_before
    ]
    assert not stale, (
        f"{len(stale)} poses after the reboot with the old home "
        f"{r.home_before}, e.g. at {stale[0].lat:.6f}, {stale[0].lon:.6f}"
    )
