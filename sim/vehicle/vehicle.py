"""SimVehicle: the simulated autopilot composed of its link, streams, commands and missions.

It owns the background thread: read what arrives, drop duplicates and malformed input, hand each
message to the part that handles its type, and let the streams and the mission server do what
has fallen due.
"""

from __future__ import annotations

import logging
import select
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from sarmission.geo.camera import CameraPose
from sarmission.mission.config import MissionConfig, load_mission
from sim.flight import Flight, VehicleState
from sim.flight_model import FlightModel
from sim.telemetry import TelemetryModel
from sim.vehicle.autopilot import AutopilotState
from sim.vehicle.commands import CommandHandler, CommandRecord
from sim.vehicle.link import VehicleLink
from sim.vehicle.mission_server import MissionItem, MissionServer
from sim.vehicle.statustexts import StatusText, StatusTextLog
from sim.vehicle.streams import StreamScheduler

log = logging.getLogger(__name__)

#: Wait for input at most this long per loop, so streams go out on time.
POLL_S = 0.005
#: Messages read per loop at most before the streams get their turn.
READ_BATCH = 200


class SimVehicle:
    """MAVLink vehicle in a background thread. Use as a context manager or start()/stop().

    ``listen_url``: pymavlink URL (``udpin:127.0.0.1:14550`` waits for a client and answers the
    last sender; ``udpout:127.0.0.1:14540`` sends to a client that listens, e.g. MAVSDK with
    ``udpin://0.0.0.0:14540``). ``mission``: a :class:`MissionConfig` or a TOML path.
    ``flight``: a ready :class:`~sim.flight_model.FlightModel` to fly instead of the mission's
    planned one (e.g. :class:`sim.meta_flight.MetaFlight`); ``mission`` defaults to its mission.
    A flight whose ``steerable`` is False gets DO_REPOSITION and DO_SET_ROI_* answered with
    MAV_RESULT_DENIED. ``gps_fix_after_s`` / ``home_after_s``: ArduPilot's start (see
    :mod:`sim.vehicle`); None: a fix and a home from the first message. ``gimbal_report``:
    the gimbal's yaw relative to the heading ("vehicle") or to north ("earth").
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
        flight: FlightModel | None = None,
        gps_fix_after_s: float | None = None,
        home_after_s: float | None = None,
        gimbal_report: str = "vehicle",
    ) -> None:
        if speedup <= 0:
            raise ValueError("speedup must be positive")
        if mission is None and flight is not None:
            mission = flight.mission
        if not isinstance(mission, MissionConfig):
            mission = load_mission(mission)
        self.mission = mission
        self.seed = seed
        self.stream_on_request = stream_on_request
        self.flight: FlightModel = Flight(mission, seed=seed) if flight is None else flight
        self.telemetry = TelemetryModel(
            self.flight, mission, seed=seed, gimbal_report=gimbal_report
        )
        self.link = VehicleLink(listen_url, system_id, component_id, float(speedup))
        self.autopilot = AutopilotState(
            mission.area.home, mission.camera.gimbal, gps_fix_after_s, home_after_s
        )
        self.streams = StreamScheduler(
            self.link,
            self.telemetry,
            self.autopilot,
            mission.telemetry.gnss_noise_m,
            seed,
            stream_on_request,
        )
        self.mission_server = MissionServer(self.link, legacy_mission_request)
        self.command_handler = CommandHandler(
            self.link, self.flight, self.autopilot, self.streams, self.mission_server
        )
        self.statustext_log = StatusTextLog(self.link.sim_time)
        self.bad_packets = 0
        self.duplicates_dropped = 0
        self._last_seq: dict[tuple[int, int], int] = {}
        self._handlers: dict[str, Callable[[Any], None]] = {
            "STATUSTEXT": self.statustext_log.on_statustext,
            "HEARTBEAT": self._on_heartbeat,
            **self.command_handler.handlers(),
            **self.mission_server.handlers(),
        }
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    # -- the parts' state, as attributes of the vehicle --------------------------------------------
    @property
    def url(self) -> str:
        return self.link.url

    @property
    def speedup(self) -> float:
        return self.link.speedup

    @property
    def system_id(self) -> int:
        return self.link.system_id

    @property
    def component_id(self) -> int:
        return self.link.component_id

    @property
    def home(self) -> tuple[float, float, float]:
        return self.autopilot.home

    @property
    def has_gimbal(self) -> bool:
        return self.autopilot.has_gimbal

    @property
    def gps_fix_after_s(self) -> float | None:
        return self.autopilot.gps_fix_after_s

    @property
    def home_after_s(self) -> float | None:
        return self.autopilot.home_after_s

    @property
    def custom_mode(self) -> int:
        """The Copter flight mode the heartbeat reports."""
        return self.autopilot.custom_mode

    @property
    def legacy_mission_request(self) -> bool:
        return self.mission_server.legacy_mission_request

    @property
    def statustexts(self) -> list[StatusText]:
        """Every STATUSTEXT received."""
        return self.statustext_log.statustexts

    @property
    def commands(self) -> list[CommandRecord]:
        """Every command received, with the result sent."""
        return self.command_handler.commands

    @property
    def missions(self) -> dict[int, list[MissionItem]]:
        """Stored items by mission type (0 mission, 1 fence, 2 rally)."""
        return self.mission_server.missions

    @property
    def mission_current(self) -> int:
        """The mission item "flown to" (MISSION_CURRENT); the simulated flight does not follow
        the stored mission, this only answers the protocol as ArduPilot does."""
        return self.mission_server.mission_current

    @mission_current.setter
    def mission_current(self, seq: int) -> None:
        self.mission_server.mission_current = seq

    @property
    def sent_counts(self) -> dict[str, int]:
        """Messages sent, by name."""
        return self.link.sent_counts

    # -- clock and truth ---------------------------------------------------------------------------
    def sim_time(self) -> float:
        """Seconds of simulated flight since start() (0 before)."""
        return self.link.sim_time()

    def truth_state(self, t: float | None = None) -> VehicleState:
        """Exact vehicle state at sim time ``t`` (default: now)."""
        return self.flight.state_at(self.sim_time() if t is None else t)

    def camera_pose(self, t: float | None = None) -> CameraPose:
        """Exact camera pose at sim time ``t`` (default: now)."""
        return self.flight.camera_pose_at(self.sim_time() if t is None else t)

    def has_gps_fix(self, t: float | None = None) -> bool:
        """Whether the simulated GPS has its fix at sim time ``t`` (default: now)."""
        return self.autopilot.has_gps_fix(self.sim_time() if t is None else t)

    def has_home(self, t: float | None = None) -> bool:
        """Whether the autopilot has set home (and its EKF origin) at sim time ``t``."""
        return self.autopilot.has_home(self.sim_time() if t is None else t)

    # -- lifecycle ---------------------------------------------------------------------------------
    def start(self) -> SimVehicle:
        """Open the link and start flying (returns self)."""
        if self._thread is not None:
            return self
        self.link.open()
        self._last_seq.clear()
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
        self.link.close()

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
        return int(self.link.conn.port.getsockname()[1])

    # -- main loop ---------------------------------------------------------------------------------
    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self._tick()
            except Exception:  # never let one bad step end the vehicle
                log.exception("vehicle loop error")
                time.sleep(0.01)

    def _tick(self) -> None:
        conn = self.link.conn
        try:
            readable, _, _ = select.select([conn.port], [], [], POLL_S)
        except (OSError, ValueError):
            readable = []
            time.sleep(POLL_S)
        if readable or conn.mav.buf_len() > 0:
            self._read(conn)
        self.streams.send_due()
        self.mission_server.check_upload_timeout()

    def _read(self, conn: Any) -> None:
        for _ in range(READ_BATCH):
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

    def _handle(self, msg: Any) -> None:
        mtype = msg.get_type()
        if mtype == "BAD_DATA":
            self.bad_packets += 1
            return
        target = getattr(msg, "target_system", None)
        if target not in (None, 0, self.system_id):
            return
        handler = self._handlers.get(mtype)
        if handler is not None:
            handler(msg)

    def _on_heartbeat(self, msg: Any) -> None:
        log.debug(
            "heartbeat from %d/%d type %d", msg.get_srcSystem(), msg.get_srcComponent(), msg.type
        )
