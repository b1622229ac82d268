"""A MAVLink vehicle (pymavlink, MAVLink 2) flying the synthetic flight, for tests and demos.

It behaves like an ArduPilot Copter autopilot (system 1, component 1, MAV_TYPE_QUADROTOR,
MAV_AUTOPILOT_ARDUPILOTMEGA) as seen from a companion computer:

- Streams HEARTBEAT (1 Hz wall clock), GLOBAL_POSITION_INT (10 Hz), GPS_RAW_INT (5 Hz: 3D fix,
  10 satellites, ``h_acc`` the simulated GNSS noise), ATTITUDE (20 Hz),
  GIMBAL_DEVICE_ATTITUDE_STATUS (5 Hz, only with a gimbal), SYSTEM_TIME (1 Hz) and
  HOME_POSITION (0.5 Hz); rates in simulated time. ``stream_on_request=True`` sends only
  HEARTBEAT until MAV_CMD_SET_MESSAGE_INTERVAL asks for a message (ArduPilot behaviour).
- ArduPilot's start, optionally (both off by default): until ``gps_fix_after_s`` (sim time)
  GLOBAL_POSITION_INT reads lat/lon 0 and GPS_RAW_INT fix_type 0 with no satellites; until
  ``home_after_s`` no HOME_POSITION is sent, GET_HOME_POSITION fails, DO_REPOSITION fails (no
  EKF origin) and arming is refused with a reason. Copter 4.7 SITL (observed): GPS fix ~9 s after
  boot, EKF origin and HOME_POSITION ~10 s later.
- COMMAND_LONG / COMMAND_INT get a COMMAND_ACK: SET_MESSAGE_INTERVAL, REQUEST_MESSAGE,
  GET_HOME_POSITION, REQUEST_AUTOPILOT_CAPABILITIES, DO_REPOSITION (flies there and holds),
  DO_SET_ROI_LOCATION / DO_SET_ROI_NONE (points the gimbal; these three are MAV_RESULT_DENIED for
  a flight that cannot be steered, such as replayed footage), COMPONENT_ARM_DISARM; anything else
  is MAV_RESULT_UNSUPPORTED. Like ArduPilot, a refused arming is followed by STATUSTEXTs of
  severity CRITICAL giving the reason ("Arm: ..."); other refusals come without one.
- A packet whose MAVLink sequence number equals the previous one from the same system and
  component is a duplicate (a radio or router sending it twice): dropped and counted in
  :attr:`SimVehicle.duplicates_dropped`.
- Mission protocol as server: upload (MISSION_COUNT -> MISSION_REQUEST_INT, or MISSION_REQUEST
  with ``legacy_mission_request=True`` like ArduPilot -> MISSION_ITEM_INT -> MISSION_ACK) with
  re-requests on timeout, download (MISSION_REQUEST_LIST -> MISSION_COUNT -> MISSION_REQUEST_INT
  -> MISSION_ITEM_INT -> MISSION_ACK), MISSION_CLEAR_ALL.
- Every STATUSTEXT received is logged and kept in :attr:`SimVehicle.statustexts`.
- Malformed input is dropped; a failing handler is logged and the loop carries on.

Time: ``sim_time() = (monotonic() - start) * speedup`` seconds; ``time_boot_ms`` of every message
is the sample's capture time in that clock. A frame source renders the same flight with
:meth:`SimVehicle.truth_state` / :meth:`SimVehicle.camera_pose`.
"""

from __future__ import annotations

import logging
import math
import select
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sarmission.geo.camera import CameraPose
from sarmission.geo.wgs84 import geodetic_to_ned
from sarmission.mavlink.connection import mavlink2_connection
from sarmission.mission.config import MissionConfig, load_mission
from sim.flight import Flight, VehicleState
from sim.telemetry import AttitudeSample, GimbalSample, PositionSample, TelemetryModel

log = logging.getLogger(__name__)

M = mavlink2
COPTER_MODE_AUTO = 3
COPTER_MODE_GUIDED = 4

#: Message id -> (stream name, default rate Hz in sim time).
STREAMS: dict[int, tuple[str, float]] = {
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: ("position", 10.0),
    M.MAVLINK_MSG_ID_GPS_RAW_INT: ("gps", 5.0),
    M.MAVLINK_MSG_ID_ATTITUDE: ("attitude", 20.0),
    M.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS: ("gimbal", 5.0),
    M.MAVLINK_MSG_ID_SYSTEM_TIME: ("system_time", 1.0),
    M.MAVLINK_MSG_ID_HOME_POSITION: ("home", 0.5),
}

UPLOAD_RETRY_S = 0.5
UPLOAD_MAX_RETRIES = 6
GPS_FIX_3D = 3
GPS_SATELLITES = 10
GPS_HDOP = 121  # eph (HDOP x 100) as Copter SITL reports it
#: ArduPilot's arming refusal while it has no home (Copter 4.7 SITL, observed).
ARM_NO_HOME = "Arm: AHRS: waiting for home"


@dataclass
class StatusText:
    """A STATUSTEXT received (chunks of one ``id`` joined), with the sim time it arrived."""

    sim_time: float
    severity: int
    text: str
    src_system: int
    src_component: int


@dataclass
class MissionItem:
    """One stored MISSION_ITEM_INT (lat/lon as degE7 integers in ``x``/``y``)."""

    seq: int
    frame: int
    command: int
    current: int
    autocontinue: int
    param1: float
    param2: float
    param3: float
    param4: float
    x: int
    y: int
    z: float
    mission_type: int = 0


@dataclass
class _Upload:
    peer: tuple[int, int]
    count: int
    mission_type: int
    items: list[MissionItem | None]
    next_seq: int = 0
    last_request: float = 0.0
    retries: int = 0


@dataclass
class _Stream:
    interval_s: float  # 0 = off
    next_t: float = 0.0


@dataclass
class CommandRecord:
    """A command received: its id, whether it came as COMMAND_INT, params and the result sent."""

    sim_time: float
    command: int
    is_int: bool
    params: tuple[float, ...]
    result: int


class SimVehicle:
    """MAVLink vehicle in a background thread. Use as a context manager or start()/stop().

    ``listen_url``: pymavlink URL (``udpin:127.0.0.1:14550`` waits for a client and answers the
    last sender; ``udpout:127.0.0.1:14540`` sends to a client that listens, e.g. MAVSDK with
    ``udpin://0.0.0.0:14540``). ``mission``: a :class:`MissionConfig` or a TOML path.
    ``flight``: a ready flight to fly instead of the mission's planned one (anything with
    :class:`Flight`'s ``mission``, ``state_at``, ``camera_pose_at``, ``reposition``, ``set_roi``
    and ``survey_duration``, e.g. :class:`sim.meta_flight.MetaFlight`); ``mission`` defaults to
    its mission. A flight whose ``steerable`` is False gets DO_REPOSITION and DO_SET_ROI_*
    answered with MAV_RESULT_DENIED. ``gps_fix_after_s`` / ``home_after_s``: ArduPilot's start
    (see the module docstring); None: a fix and a home from the first message.
    """

    def __init__(
        self,
        listen_url: str,
        mission: MissionConfig | str | Path | None = None,
        speedup: float = 1.0,
        seed: int = 0,
        stream_on_request: bool = False,
        legacy_mission_request: bool = False,
        system_id: int = 1,
        component_id: int = 1,
        flight: Any = None,
        gps_fix_after_s: float | None = None,
        home_after_s: float | None = None,
    ) -> None:
        if speedup <= 0:
            raise ValueError("speedup must be positive")
        if mission is None and flight is not None:
            mission = flight.mission
        if not isinstance(mission, MissionConfig):
            mission = load_mission(mission)
        self.mission = mission
        self.url = listen_url
        self.speedup = float(speedup)
        self.seed = seed
        self.stream_on_request = stream_on_request
        self.legacy_mission_request = legacy_mission_request
        self.system_id = system_id
        self.component_id = component_id
        self.gps_fix_after_s = gps_fix_after_s
        self.home_after_s = home_after_s
        self.flight = Flight(mission, seed=seed) if flight is None else flight
        self.telemetry = TelemetryModel(self.flight, mission, seed=seed)
        self.home = mission.area.home
        self.has_gimbal = mission.camera.gimbal
        self.statustexts: list[StatusText] = []
        self.commands: list[CommandRecord] = []
        self.missions: dict[int, list[MissionItem]] = {0: [], 1: [], 2: []}
        self.custom_mode = COPTER_MODE_AUTO
        #: The mission item "flown to" (MISSION_CURRENT); the simulated flight does not follow
        #: the stored mission, this only answers the protocol as ArduPilot does.
        self.mission_current = 0
        self.sent_counts: dict[str, int] = {}
        self.bad_packets = 0
        self.duplicates_dropped = 0
        self._last_seq: dict[tuple[int, int], int] = {}
        self._reasons: list[str] = []  # STATUSTEXTs to send after the ACK being prepared
        self._chunks: dict[tuple[int, int, int], list[str]] = {}
        self._upload: _Upload | None = None
        self._streams: dict[int, _Stream] = {}
        for msg_id, (name, rate) in STREAMS.items():
            off = stream_on_request or (name == "gimbal" and not self.has_gimbal)
            self._streams[msg_id] = _Stream(0.0 if off else 1.0 / rate)
        self._conn: Any = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._started = threading.Event()
        self._mono0 = 0.0
        self._unix0 = 0.0
        self._next_heartbeat = 0.0
        self._lock = threading.Lock()

    # -- clock and truth ---------------------------------------------------------------------------
    def sim_time(self) -> float:
        """Seconds of simulated flight since start() (0 before)."""
        if not self._started.is_set():
            return 0.0
        return (time.monotonic() - self._mono0) * self.speedup

    def truth_state(self, t: float | None = None) -> VehicleState:
        """Exact vehicle state at sim time ``t`` (default: now)."""
        return self.flight.state_at(self.sim_time() if t is None else t)

    def camera_pose(self, t: float | None = None) -> CameraPose:
        """Exact camera pose at sim time ``t`` (default: now)."""
        return self.flight.camera_pose_at(self.sim_time() if t is None else t)

    # -- lifecycle ---------------------------------------------------------------------------------
    def start(self) -> SimVehicle:
        """Open the link and start flying (returns self)."""
        if self._thread is not None:
            return self
        self._conn = mavlink2_connection(self.url, self.system_id, self.component_id)
        self._last_seq.clear()
        self._mono0 = time.monotonic()
        self._unix0 = time.time()
        self._started.set()
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="sim-vehicle", daemon=True)
        self._thread.start()
        log.info(
            "vehicle on %s, mission %s, speedup %.1f", self.url, self.mission.name, self.speedup
        )
        return self

    def stop(self) -> None:
        """Stop the thread and close the link."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        if self._conn is not None:
            try:
                self._conn.close()
            except OSError:
                pass
            self._conn = None

    def __enter__(self) -> SimVehicle:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def is_alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    @property
    def local_port(self) -> int:
        """The UDP port the vehicle's socket is bound to."""
        return int(self._conn.port.getsockname()[1])

    # -- main loop ---------------------------------------------------------------------------------
    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self._tick()
            except Exception:  # never let one bad step end the vehicle
                log.exception("vehicle loop error")
                time.sleep(0.01)

    def _tick(self) -> None:
        conn = self._conn
        wait = 0.005
        try:
            readable, _, _ = select.select([conn.port], [], [], wait)
        except (OSError, ValueError):
            readable = []
            time.sleep(wait)
        if readable or conn.mav.buf_len() > 0:
            for _ in range(200):
                try:
                    msg = conn.recv_msg()
                except Exception:
                    self.bad_packets += 1
                    log.debug("dropped undecodable input", exc_info=True)
                    continue
                if msg is None:
                    break
                if self._duplicate(msg):
                    continue
                try:
                    self._handle(msg)
                except Exception:
                    log.exception("error handling %s", msg.get_type())
        self._send_due()
        self._check_upload_timeout()

    def _duplicate(self, msg: Any) -> bool:
        """Whether ``msg`` repeats the previous packet's sequence number from its source (a
        duplicate, as MAVLink receivers treat it); counted in ``duplicates_dropped``."""
        if msg.get_type() == "BAD_DATA":
            return False
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        seq = msg.get_seq()
        if self._last_seq.get(src) == seq:
            self.duplicates_dropped += 1
            return True
        self._last_seq[src] = seq
        return False

    def has_gps_fix(self, t: float | None = None) -> bool:
        """Whether the simulated GPS has its fix at sim time ``t`` (default: now)."""
        t = self.sim_time() if t is None else t
        return self.gps_fix_after_s is None or t >= self.gps_fix_after_s

    def has_home(self, t: float | None = None) -> bool:
        """Whether the autopilot has set home (and its EKF origin) at sim time ``t``."""
        t = self.sim_time() if t is None else t
        return self.home_after_s is None or t >= self.home_after_s

    def _send(self, kind: str, fn: Any, *args: Any, **kwargs: Any) -> None:
        if self._conn is None:
            return
        try:
            fn(*args, **kwargs)
            self.sent_counts[kind] = self.sent_counts.get(kind, 0) + 1
        except OSError as exc:  # e.g. ICMP port unreachable from a client that went away
            log.debug("send %s failed: %s", kind, exc)

    def _send_due(self) -> None:
        mono = time.monotonic()
        if mono >= self._next_heartbeat:
            self._next_heartbeat = mono + 1.0
            self._send_heartbeat()
        now = self.sim_time()
        lat = self.telemetry.latency_s
        for msg_id, stream in self._streams.items():
            if stream.interval_s <= 0:
                continue
            if stream.next_t < now - 2.0:  # fell far behind (stall): skip ahead
                stream.next_t = now - lat
            while stream.next_t + lat <= now:
                self._send_stream(msg_id, stream.next_t)
                stream.next_t += stream.interval_s

    def _send_heartbeat(self) -> None:
        base = (
            M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
            | M.MAV_MODE_FLAG_SAFETY_ARMED
            | M.MAV_MODE_FLAG_STABILIZE_ENABLED
            | M.MAV_MODE_FLAG_GUIDED_ENABLED
        )
        self._send(
            "HEARTBEAT",
            self._conn.mav.heartbeat_send,
            M.MAV_TYPE_QUADROTOR,
            M.MAV_AUTOPILOT_ARDUPILOTMEGA,
            base,
            self.custom_mode,
            M.MAV_STATE_ACTIVE,
        )

    def _send_stream(self, msg_id: int, t: float) -> None:
        mav = self._conn.mav
        ms = int(round(t * 1000.0))
        if msg_id == M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT:
            p: PositionSample = self.telemetry.position(t)
            v = p.velocity_ned if self.has_gps_fix(t) else (0.0, 0.0, 0.0)
            fix = self.has_gps_fix(t)
            self._send(
                "GLOBAL_POSITION_INT",
                mav.global_position_int_send,
                ms,
                int(round(p.lat_deg * 1e7)) if fix else 0,
                int(round(p.lon_deg * 1e7)) if fix else 0,
                int(round(p.alt_m * 1000)) if fix else 0,
                int(round(p.relative_alt_m * 1000)) if fix else 0,
                _i16(v[0] * 100),
                _i16(v[1] * 100),
                _i16(v[2] * 100),
                int(round(p.heading_deg * 100)) % 36000,
            )
        elif msg_id == M.MAVLINK_MSG_ID_GPS_RAW_INT:
            self._send_gps_raw(t)
        elif msg_id == M.MAVLINK_MSG_ID_ATTITUDE:
            a: AttitudeSample = self.telemetry.attitude(t)
            self._send(
                "ATTITUDE",
                mav.attitude_send,
                ms,
                a.roll,
                a.pitch,
                a.yaw,
                a.rollspeed,
                a.pitchspeed,
                a.yawspeed,
            )
        elif msg_id == M.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS:
            g: GimbalSample | None = self.telemetry.gimbal(t)
            if g is None:
                return
            nan = float("nan")
            self._send(
                "GIMBAL_DEVICE_ATTITUDE_STATUS",
                mav.gimbal_device_attitude_status_send,
                0,
                0,
                ms,
                g.flags,
                list(g.q),
                nan,
                nan,
                nan,
                0,
                g.delta_yaw,
                nan,
                1,
            )
        elif msg_id == M.MAVLINK_MSG_ID_SYSTEM_TIME:
            self._send("SYSTEM_TIME", mav.system_time_send, int((self._unix0 + t) * 1e6), ms)
        elif msg_id == M.MAVLINK_MSG_ID_HOME_POSITION:
            self._send_home()

    def _send_gps_raw(self, t: float) -> None:
        """GPS_RAW_INT at sim time ``t``: the GNSS position with a 3D fix, or, before
        ``gps_fix_after_s``, no fix at all (fix_type 0, lat/lon 0, no satellites), as ArduPilot
        reports its GPS while it searches."""
        unknown = 0xFFFF
        if not self.has_gps_fix(t):
            self._send("GPS_RAW_INT", self._conn.mav.gps_raw_int_send, int(t * 1e6), 0, 0, 0,
                       0, unknown, unknown, 0, unknown, 0, 0, 0, 0, 0, 0, 0)
            return
        p: PositionSample = self.telemetry.position(t)
        v = p.velocity_ned
        speed = math.hypot(v[0], v[1])
        cog = int(round(math.degrees(math.atan2(v[1], v[0])) * 100)) % 36000
        h_acc_mm = max(1, int(round(self.mission.telemetry.gnss_noise_m * 1000)))
        self._send(
            "GPS_RAW_INT",
            self._conn.mav.gps_raw_int_send,
            int(t * 1e6),
            GPS_FIX_3D,
            int(round(p.lat_deg * 1e7)),
            int(round(p.lon_deg * 1e7)),
            int(round(p.alt_m * 1000)),
            GPS_HDOP,
            GPS_HDOP + 80,
            min(int(round(speed * 100)), 0xFFFE),
            cog,
            GPS_SATELLITES,
            int(round(p.alt_m * 1000)),
            h_acc_mm,
            int(round(1.5 * h_acc_mm)),
            max(1, int(round(0.1 * h_acc_mm))),
            0,
            0,
        )

    def _send_home(self) -> None:
        if not self.has_home():  # ArduPilot sends nothing until its home is set
            return
        lat, lon, alt = self.home
        self._send(
            "HOME_POSITION",
            self._conn.mav.home_position_send,
            int(round(lat * 1e7)),
            int(round(lon * 1e7)),
            int(round(alt * 1000)),
            0.0,
            0.0,
            0.0,
            [1.0, 0.0, 0.0, 0.0],
            0.0,
            0.0,
            0.0,
            int((self._unix0 + self.sim_time()) * 1e6),
        )

    def _send_autopilot_version(self) -> None:
        caps = (
            M.MAV_PROTOCOL_CAPABILITY_MISSION_INT
            | M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
            | M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
            | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
        )
        # flight_sw_version 4.7.0 official: 0x04070000 | FIRMWARE_VERSION_TYPE_OFFICIAL (255)
        self._send(
            "AUTOPILOT_VERSION",
            self._conn.mav.autopilot_version_send,
            caps,
            0x040700FF,
            0,
            0,
            0,
            [0] * 8,
            [0] * 8,
            [0] * 8,
            0,
            0,
            4242 + self.seed,
        )

    # -- incoming ----------------------------------------------------------------------------------
    def _handle(self, msg: Any) -> None:
        mtype = msg.get_type()
        if mtype == "BAD_DATA":
            self.bad_packets += 1
            return
        target = getattr(msg, "target_system", None)
        if target not in (None, 0, self.system_id):
            return
        handler = getattr(self, "_on_" + mtype.lower(), None)
        if handler is not None:
            handler(msg)

    def _on_statustext(self, msg: Any) -> None:
        text = msg.text if isinstance(msg.text, str) else msg.text.decode("utf-8", "replace")
        text = text.rstrip("\x00")
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        msg_id = getattr(msg, "id", 0)
        if msg_id:
            key = (src[0], src[1], msg_id)
            parts = self._chunks.setdefault(key, [])
            parts.append(text)
            if len(text) >= 50:  # a full chunk: more follow
                return
            text = "".join(self._chunks.pop(key))
        entry = StatusText(self.sim_time(), int(msg.severity), text, src[0], src[1])
        with self._lock:
            self.statustexts.append(entry)
        log.warning("STATUSTEXT from %d/%d severity %d: %s", src[0], src[1], entry.severity, text)

    def _ack(self, msg: Any, command: int, result: int) -> None:
        self._send(
            "COMMAND_ACK",
            self._conn.mav.command_ack_send,
            command,
            result,
            0,
            0,
            msg.get_srcSystem(),
            msg.get_srcComponent(),
        )

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
        result = self._execute(command, p, frame, is_int)
        with self._lock:
            self.commands.append(CommandRecord(self.sim_time(), command, is_int, p, result))
        log.info("command %d (%s) -> result %d", command, "INT" if is_int else "LONG", result)
        self._ack(msg, command, result)
        for text in self._reasons:  # ArduPilot's reasons follow its ACK
            self._send("STATUSTEXT", self._conn.mav.statustext_send, M.MAV_SEVERITY_CRITICAL,
                       text.encode("ascii", "replace")[:50])
        self._reasons = []

    def _location_ned(self, p: tuple[float, ...], frame: int | None, is_int: bool) -> np.ndarray:
        """Target location of a COMMAND_INT (x, y degE7) or COMMAND_LONG (param5/6 deg) in NED."""
        lat = p[4] / 1e7 if is_int else p[4]
        lon = p[5] / 1e7 if is_int else p[5]
        alt = p[6]
        here = self.flight.state_at(self.sim_time()).position_ned
        if alt is None or not math.isfinite(alt):
            down = here[2]
        elif frame in (M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_INT):
            down = self.home[2] - alt
        else:  # relative to home (GLOBAL_RELATIVE_ALT[_INT]) or unspecified
            down = -alt
        if not (math.isfinite(lat) and math.isfinite(lon)) or (lat == 0 and lon == 0):
            return np.array([here[0], here[1], down])
        n, e, _ = geodetic_to_ned(lat, lon, self.home[2], *self.home)
        return np.array([float(n), float(e), down])

    def _execute(self, command: int, p: tuple[float, ...], frame: int | None, is_int: bool) -> int:
        now = self.sim_time()
        if command == M.MAV_CMD_SET_MESSAGE_INTERVAL:
            msg_id, interval_us = int(p[0]), p[1]
            if msg_id not in STREAMS:
                return M.MAV_RESULT_DENIED
            name, rate = STREAMS[msg_id]
            if name == "gimbal" and not self.has_gimbal:
                return M.MAV_RESULT_DENIED
            stream = self._streams[msg_id]
            if interval_us == -1:
                stream.interval_s = 0.0
            elif interval_us >= 0:
                was_off = stream.interval_s <= 0
                stream.interval_s = 1.0 / rate if interval_us == 0 else interval_us / 1e6
                if was_off:
                    stream.next_t = now
            else:
                return M.MAV_RESULT_DENIED
            log.info("stream %s interval %.3f s", name, stream.interval_s)
            return M.MAV_RESULT_ACCEPTED
        if command == M.MAV_CMD_REQUEST_MESSAGE:
            msg_id = int(p[0])
            if msg_id == M.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
                self._send_autopilot_version()
            elif msg_id == M.MAVLINK_MSG_ID_HOME_POSITION:
                self._send_home()
            elif msg_id == M.MAVLINK_MSG_ID_MISSION_CURRENT:
                self._send("MISSION_CURRENT", self._conn.mav.mission_current_send,
                           self.mission_current, len(self.missions[0]))
            elif msg_id in STREAMS and not (STREAMS[msg_id][0] == "gimbal" and not self.has_gimbal):
                self._send_stream(msg_id, now)
            else:
                return M.MAV_RESULT_DENIED
            return M.MAV_RESULT_ACCEPTED
        if command == M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            self._send_autopilot_version()
            return M.MAV_RESULT_ACCEPTED
        if command == M.MAV_CMD_GET_HOME_POSITION:
            if not self.has_home(now):
                return M.MAV_RESULT_FAILED
            self._send_home()
            return M.MAV_RESULT_ACCEPTED
        if command == M.MAV_CMD_COMPONENT_ARM_DISARM:
            if p[0] == 1 and not self.has_home(now):
                self._reasons.append(ARM_NO_HOME)
                return M.MAV_RESULT_FAILED
            return M.MAV_RESULT_ACCEPTED if p[0] == 1 else M.MAV_RESULT_DENIED
        if command in (M.MAV_CMD_DO_REPOSITION, M.MAV_CMD_DO_SET_ROI_LOCATION,
                       M.MAV_CMD_DO_SET_ROI_NONE) and not getattr(self.flight, "steerable", True):
            log.info("command %d denied: this flight cannot be steered (replayed footage)",
                     command)
            return M.MAV_RESULT_DENIED
        if command == M.MAV_CMD_DO_REPOSITION:
            if not self.has_home(now):  # ArduPilot: no EKF origin yet, FAILED and no text
                return M.MAV_RESULT_FAILED
            target = self._location_ned(p, frame, is_int)
            speed = p[0] if p[0] is not None and math.isfinite(p[0]) and p[0] > 0 else None
            eta = self.flight.reposition(now, target, speed)
            if int(p[1]) & 1:
                self.custom_mode = COPTER_MODE_GUIDED
            log.info("reposition to NED %s, arrival at t=%.1f s", np.round(target, 1), eta)
            return M.MAV_RESULT_ACCEPTED
        if command == M.MAV_CMD_DO_SET_ROI_LOCATION:
            target = self._location_ned(p, frame, is_int)
            self.flight.set_roi(now, target)
            log.info("ROI at NED %s", np.round(target, 1))
            return M.MAV_RESULT_ACCEPTED
        if command == M.MAV_CMD_DO_SET_ROI_NONE:
            self.flight.set_roi(now, None)
            return M.MAV_RESULT_ACCEPTED
        if command == M.MAV_CMD_DO_SET_MISSION_CURRENT:
            seq = int(p[0])
            if not 0 <= seq < len(self.missions[0]):
                return M.MAV_RESULT_DENIED
            self.mission_current = seq
            return M.MAV_RESULT_ACCEPTED
        return M.MAV_RESULT_UNSUPPORTED

    # -- mission protocol --------------------------------------------------------------------------
    def _mission_ack(self, peer: tuple[int, int], result: int, mission_type: int) -> None:
        self._send(
            "MISSION_ACK", self._conn.mav.mission_ack_send, peer[0], peer[1], result, mission_type
        )

    def _request_item(self) -> None:
        up = self._upload
        if up is None:
            return
        up.last_request = time.monotonic()
        if self.legacy_mission_request:
            self._send(
                "MISSION_REQUEST",
                self._conn.mav.mission_request_send,
                up.peer[0],
                up.peer[1],
                up.next_seq,
                up.mission_type,
            )
        else:
            self._send(
                "MISSION_REQUEST_INT",
                self._conn.mav.mission_request_int_send,
                up.peer[0],
                up.peer[1],
                up.next_seq,
                up.mission_type,
            )

    def _on_mission_count(self, msg: Any) -> None:
        peer = (msg.get_srcSystem(), msg.get_srcComponent())
        mtype = getattr(msg, "mission_type", 0)
        if mtype not in self.missions:
            self._mission_ack(peer, M.MAV_MISSION_UNSUPPORTED, mtype)
            return
        if msg.count == 0:
            self.missions[mtype] = []
            self._upload = None
            self._mission_ack(peer, M.MAV_MISSION_ACCEPTED, mtype)
            return
        if msg.count > 1000:
            self._mission_ack(peer, M.MAV_MISSION_NO_SPACE, mtype)
            return
        self._upload = _Upload(peer, msg.count, mtype, [None] * msg.count)
        log.info("mission upload of %d items from %d/%d", msg.count, *peer)
        self._request_item()

    def _on_mission_item_int(self, msg: Any) -> None:
        self._receive_item(msg, int(msg.x), int(msg.y))

    def _on_mission_item(self, msg: Any) -> None:
        self._receive_item(msg, int(round(msg.x * 1e7)), int(round(msg.y * 1e7)))

    def _receive_item(self, msg: Any, x: int, y: int) -> None:
        up = self._upload
        peer = (msg.get_srcSystem(), msg.get_srcComponent())
        if up is None or peer != up.peer:
            return
        if msg.seq != up.next_seq:  # duplicate or out of order: ask again for the one we need
            self._request_item()
            return
        up.items[msg.seq] = MissionItem(
            msg.seq,
            msg.frame,
            msg.command,
            msg.current,
            msg.autocontinue,
            msg.param1,
            msg.param2,
            msg.param3,
            msg.param4,
            x,
            y,
            float(msg.z),
            up.mission_type,
        )
        up.next_seq += 1
        up.retries = 0
        if up.next_seq < up.count:
            self._request_item()
            return
        self.missions[up.mission_type] = [i for i in up.items if i is not None]
        self._upload = None
        log.info("mission upload complete: %d items", up.count)
        self._mission_ack(peer, M.MAV_MISSION_ACCEPTED, up.mission_type)

    def _check_upload_timeout(self) -> None:
        up = self._upload
        if up is None or time.monotonic() - up.last_request < UPLOAD_RETRY_S:
            return
        if up.retries >= UPLOAD_MAX_RETRIES:
            log.warning("mission upload timed out waiting for item %d", up.next_seq)
            self._mission_ack(up.peer, M.MAV_MISSION_OPERATION_CANCELLED, up.mission_type)
            self._upload = None
            return
        up.retries += 1
        self._request_item()

    def _on_mission_request_list(self, msg: Any) -> None:
        mtype = getattr(msg, "mission_type", 0)
        peer = (msg.get_srcSystem(), msg.get_srcComponent())
        if mtype not in self.missions:
            self._mission_ack(peer, M.MAV_MISSION_UNSUPPORTED, mtype)
            return
        self._send(
            "MISSION_COUNT",
            self._conn.mav.mission_count_send,
            peer[0],
            peer[1],
            len(self.missions[mtype]),
            mtype,
        )

    def _send_item(self, msg: Any, as_int: bool) -> None:
        mtype = getattr(msg, "mission_type", 0)
        peer = (msg.get_srcSystem(), msg.get_srcComponent())
        items = self.missions.get(mtype)
        if items is None or not 0 <= msg.seq < len(items):
            self._mission_ack(peer, M.MAV_MISSION_INVALID_SEQUENCE, mtype)
            return
        it = items[msg.seq]
        if as_int:
            self._send(
                "MISSION_ITEM_INT",
                self._conn.mav.mission_item_int_send,
                peer[0],
                peer[1],
                it.seq,
                it.frame,
                it.command,
                it.current,
                it.autocontinue,
                it.param1,
                it.param2,
                it.param3,
                it.param4,
                it.x,
                it.y,
                it.z,
                mtype,
            )
        else:
            self._send(
                "MISSION_ITEM",
                self._conn.mav.mission_item_send,
                peer[0],
                peer[1],
                it.seq,
                it.frame,
                it.command,
                it.current,
                it.autocontinue,
                it.param1,
                it.param2,
                it.param3,
                it.param4,
                it.x / 1e7,
                it.y / 1e7,
                it.z,
                mtype,
            )

    def _on_mission_request_int(self, msg: Any) -> None:
        self._send_item(msg, True)

    def _on_mission_request(self, msg: Any) -> None:
        self._send_item(msg, False)

    def _on_mission_clear_all(self, msg: Any) -> None:
        mtype = getattr(msg, "mission_type", 0)
        if mtype in self.missions:
            self.missions[mtype] = []
        self._mission_ack(
            (msg.get_srcSystem(), msg.get_srcComponent()), M.MAV_MISSION_ACCEPTED, mtype
        )

    def _on_mission_ack(self, msg: Any) -> None:
        log.debug(
            "mission ack %d from %d/%d", msg.type, msg.get_srcSystem(), msg.get_srcComponent()
        )

    def _on_heartbeat(self, msg: Any) -> None:
        log.debug(
            "heartbeat from %d/%d type %d", msg.get_srcSystem(), msg.get_srcComponent(), msg.type
        )


def _i16(v: float) -> int:
    return int(max(-32768, min(32767, round(v))))


def run_vehicle(
    listen: str, mission_path: str | None, speedup: float, seed: int, duration: float | None
) -> int:
    """Run a vehicle until Ctrl-C or ``duration`` seconds of wall time; print what it does."""
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s")
    vehicle = SimVehicle(listen, mission_path, speedup=speedup, seed=seed)
    print(
        f"vehicle: mission '{vehicle.mission.name}' on {listen}, speedup {speedup:g}, seed {seed};"
        f" survey takes {vehicle.flight.survey_duration:.0f} s of sim time",
        flush=True,
    )
    deadline = None if duration is None else time.monotonic() + duration
    last_print = 0.0
    try:
        with vehicle:
            while deadline is None or time.monotonic() < deadline:
                time.sleep(0.2)
                if time.monotonic() - last_print >= 5.0:
                    last_print = time.monotonic()
                    s = vehicle.truth_state()
                    n, e, d = s.position_ned
                    print(
                        f"t={s.t:7.1f}s  NED=({n:7.1f}, {e:7.1f}, {d:6.1f})  "
                        f"yaw={math.degrees(s.yaw):6.1f}  sent={sum(vehicle.sent_counts.values())}"
                        f"  statustexts={len(vehicle.statustexts)}",
                        flush=True,
                    )
    except KeyboardInterrupt:
        print("vehicle: stopped", flush=True)
    return 0
