"""ArduPilot Copter SITL for tests: the real autopilot process and a pilot at its ground station.

:class:`Sitl` runs the ``arducopter`` binary (software in the loop: the real flight code flying a
simulated quadcopter) in a scratch directory of its own, in a process group of its own so that
:meth:`Sitl.stop` leaves nothing behind. Its SERIAL0 sends MAVLink to ``link_port`` (the companion
computer: our :class:`~sarmission.mavlink.connection.MavlinkLink`, ``udpin:``) and its SERIAL1 to
``gcs_port`` (the ground station: :class:`Pilot`); ArduPilot routes between the two as between a
companion port and a telemetry radio. Both ports come from the OS. SITL's own ports (RC input
UDP ``5501 + 10 I``, SERIAL2 TCP ``5763 + 10 I``) follow its ``--instance I``; instances are
chosen below the OS's ephemeral port range, starting from one derived from the process id and
probed free, so concurrent test processes and their OS-chosen ports do not collide.

:class:`Pilot` is a plain pymavlink connection on the ground-station port acting as the pilot:
it asks for streams, waits for a GPS fix and HOME_POSITION, arms in GUIDED (retrying while the
autopilot's pre-arm checks refuse), takes off, uploads and reads back a survey mission, switches
modes and keeps every STATUSTEXT it sees. It shares no code with the project under test.

Speed-up: ``--speedup S`` runs the simulation S times faster than the wall clock; the autopilot's
``time_boot_ms`` and stream rates are in simulated time (4 Hz asked = 4 S Hz on the wire), its
HEARTBEAT goes out once per simulated second.
"""

from __future__ import annotations

import math
import os
import queue
import shutil
import signal
import socket
import subprocess
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from conftest import free_udp_port
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as M

#: Pilot (ground station) MAVLink ids: system 255, MAV_COMP_ID_MISSIONPLANNER.
GCS_SYSTEM = 255
GCS_COMPONENT = M.MAV_COMP_ID_MISSIONPLANNER
#: ArduCopter custom modes (``mavutil.mode_mapping_acm``).
COPTER_MODES = {"STABILIZE": 0, "AUTO": 3, "GUIDED": 4, "LOITER": 5, "RTL": 6, "LAND": 9}
#: Instances tried: their SITL ports stay below 32768, where Linux starts handing out ports.
INSTANCE_RANGE = (100, 2600)
_claimed: set[int] = set()
_claimed_lock = threading.Lock()
#: Process ids of every SITL started by this process (the stray-process check reads it).
STARTED_PIDS: list[int] = []
#: util-linux ``setpriv``, which execs SITL with a parent-death signal (None where missing).
SETPRIV = shutil.which("setpriv")


def wait_for(cond: Callable[[], Any], timeout: float, step: float = 0.05) -> Any:
    """Poll ``cond`` until it returns something true (returned) or ``timeout`` passed (its last
    value returned). Deadlines bound a hung test; they do not measure speed."""
    deadline = time.monotonic() + timeout
    while True:
        value = cond()
        if value or time.monotonic() >= deadline:
            return value
        time.sleep(step)


def _port_free(port: int, kind: int) -> bool:
    with socket.socket(socket.AF_INET, kind) as s:
        try:
            s.bind(("0.0.0.0", port))
        except OSError:
            return False
    return True


def sitl_ports(instance: int) -> tuple[list[int], list[int]]:
    """``(tcp, udp)`` ports that SITL instance ``instance`` may bind itself: TCP ``5760-5763 +
    10 I`` (SERIAL0 5760, SERIAL1 5762, SERIAL2 5763; the first two are UDP clients here, listed
    anyway) and RC input UDP ``5501 + 10 I``."""
    base = 10 * instance
    return [5760 + base + k for k in range(4)], [5501 + base]


def pick_instance() -> int:
    """An instance number not used by this process whose SITL ports are free right now,
    starting from one derived from the process id (different test processes start apart)."""
    lo, hi = INSTANCE_RANGE
    start = lo + (os.getpid() * 37) % (hi - lo)
    with _claimed_lock:
        for k in range(hi - lo):
            instance = lo + (start - lo + k) % (hi - lo)
            if instance in _claimed:
                continue
            tcp, udp = sitl_ports(instance)
            if all(_port_free(p, socket.SOCK_STREAM) for p in tcp) and all(
                _port_free(p, socket.SOCK_DGRAM) for p in udp
            ):
                _claimed.add(instance)
                return instance
    raise RuntimeError("no free SITL instance")


def process_group_alive(pgid: int) -> bool:
    """Whether any process (not yet reaped) is left in process group ``pgid``."""
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class Sitl:
    """One ArduPilot Copter SITL process (see the module docstring).

    ``binary``: the ``arducopter`` executable; ``copter.parm`` beside it holds the SITL airframe
    defaults. ``workdir``: scratch directory (eeprom.bin, logs). ``extra_params``: parameter
    defaults written to a file of their own after ``copter.parm`` (e.g. ``SIM_GPS1_ENABLE 0``).
    ``home``: ``(lat, lon, alt, heading)`` where the simulated vehicle starts.
    """

    def __init__(
        self,
        binary: Path,
        workdir: Path,
        *,
        speedup: float = 10.0,
        home: tuple[float, float, float, float] = (43.0, 10.0, 0.0, 0.0),
        extra_params: dict[str, float] | None = None,
    ) -> None:
        self.binary = Path(binary)
        self.defaults = self.binary.parent / "copter.parm"
        if not self.defaults.is_file():
            raise FileNotFoundError(f"SITL defaults {self.defaults} missing beside the binary")
        self.workdir = Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.speedup = speedup
        self.home = home
        self.extra_params = dict(extra_params or {})
        self.instance = pick_instance()
        self.link_port = free_udp_port()
        self.gcs_port = free_udp_port()
        self.proc: subprocess.Popen[bytes] | None = None
        self.starts = 0
        self._log: Any = None

    @property
    def link_url(self) -> str:
        """Connection string for the companion computer's link (our MavlinkLink)."""
        return f"udpin:127.0.0.1:{self.link_port}"

    @property
    def gcs_url(self) -> str:
        """Connection string for the ground station (the :class:`Pilot`)."""
        return f"udpin:127.0.0.1:{self.gcs_port}"

    @property
    def pid(self) -> int | None:
        return None if self.proc is None else self.proc.pid

    @property
    def log_path(self) -> Path:
        return self.workdir / "sitl.log"

    def start(
        self,
        *,
        wipe: bool = True,
        home: tuple[float, float, float, float] | None = None,
        speedup: float | None = None,
    ) -> Sitl:
        """Start the process (``wipe``: fresh eeprom, i.e. default parameters and no mission;
        without it the autopilot boots as after a power cycle; ``home``, ``speedup``: change
        them from now on). Same instance and ports every time, so a restart is the same
        autopilot on the same links."""
        if self.proc is not None and self.proc.poll() is None:
            raise RuntimeError("SITL already running")
        if home is not None:
            self.home = home
        if speedup is not None:
            self.speedup = speedup
        defaults = str(self.defaults)
        if self.extra_params:
            extra = self.workdir / "extra.parm"
            extra.write_text("".join(f"{k} {v}\n" for k, v in self.extra_params.items()))
            defaults += f",{extra}"
        args = [
            str(self.binary),
            "--model",
            "+",
            "--speedup",
            f"{self.speedup:g}",
            "--defaults",
            defaults,
            "-I",
            str(self.instance),
            "--home",
            ",".join(f"{v:.7f}" for v in self.home),
            "--serial0",
            f"udpclient:127.0.0.1:{self.link_port}",
            "--serial1",
            f"udpclient:127.0.0.1:{self.gcs_port}",
        ]
        if wipe:
            args.append("--wipe")
        if SETPRIV:  # SITL dies with the thread that starts it (the main one), teardown or not
            args = [SETPRIV, "--pdeathsig", "KILL", *args]
        self._log = open(self.log_path, "ab")  # closed in stop()
        self.proc = subprocess.Popen(
            args,
            cwd=self.workdir,
            stdin=subprocess.DEVNULL,
            stdout=self._log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        STARTED_PIDS.append(self.proc.pid)
        self.starts += 1
        return self

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def pause(self) -> None:
        """SIGSTOP: the autopilot freezes mid-flight (a hung or disconnected autopilot)."""
        self._signal(signal.SIGSTOP)

    def resume(self) -> None:
        """SIGCONT after :meth:`pause`."""
        self._signal(signal.SIGCONT)

    def _signal(self, sig: int) -> None:
        if self.proc is None:
            raise RuntimeError("SITL not started")
        os.killpg(self.proc.pid, sig)

    def stop(self) -> None:
        """SIGKILL the whole process group and reap it (idempotent)."""
        if self.proc is not None:
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            self.proc.wait(timeout=10)
        if self._log is not None:
            self._log.close()
            self._log = None

    def restart(
        self, *, home: tuple[float, float, float, float] | None = None, speedup: float | None = None
    ) -> Sitl:
        """Kill and boot again on the same instance and ports, keeping the eeprom (a power
        cycle: parameters and the stored mission survive, ``time_boot_ms`` starts at 0)."""
        self.stop()
        return self.start(wipe=False, home=home, speedup=speedup)

    def log_tail(self, n: int = 20) -> str:
        """The last ``n`` lines SITL printed (for failure messages)."""
        try:
            lines = self.log_path.read_text(errors="replace").splitlines()
        except OSError:
            return ""
        return "\n".join(lines[-n:])


@dataclass(frozen=True)
class Statustext:
    """One STATUSTEXT seen by the pilot, with the ids of its sender."""

    severity: int
    text: str
    src_system: int
    src_component: int
    arrival: float
    text_id: int = 0
    chunk_seq: int = 0


@dataclass(frozen=True)
class Waypoint:
    """A mission item as the pilot uploads it and reads it back (degrees, metres, params 1-4)."""

    command: int
    lat: float = 0.0
    lon: float = 0.0
    alt: float = 0.0
    params: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    frame: int = M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT


def box_survey(
    lat0: float, lon0: float, alt: float, side_m: float = 300.0, speed_m_s: float = 5.0
) -> list[Waypoint]:
    """A looping box survey north-east of ``(lat0, lon0)``: home placeholder (item 0, which
    ArduPilot overwrites with home), DO_CHANGE_SPEED, four corners, DO_JUMP back forever."""
    dn = 1.0 / 111_111.0
    de = dn / math.cos(math.radians(lat0))
    items = [
        Waypoint(M.MAV_CMD_NAV_WAYPOINT, lat0, lon0, 0.0),
        Waypoint(M.MAV_CMD_DO_CHANGE_SPEED, params=(1.0, speed_m_s, -1.0, 0.0)),
    ]
    for n, e in ((side_m, 0.0), (side_m, side_m), (0.0, side_m), (0.0, 0.0)):
        items.append(Waypoint(M.MAV_CMD_NAV_WAYPOINT, lat0 + n * dn, lon0 + e * de, alt))
    items.append(Waypoint(M.MAV_CMD_DO_JUMP, params=(2.0, -1.0, 0.0, 0.0)))
    return items


@dataclass
class _Waiter:
    types: frozenset[str]
    predicate: Callable[[Any], bool] | None
    queue: queue.Queue[Any] = field(default_factory=queue.Queue)


class Pilot:
    """The ground station: a raw pymavlink connection on SITL's SERIAL1 (see module docstring).

    A reader thread keeps the newest message of each type from the autopilot and every
    STATUSTEXT; requests register a waiter before sending so that no reply is missed.
    """

    def __init__(self, url: str, ack_timeout_s: float = 2.0) -> None:
        self.url = url
        self.ack_timeout_s = ack_timeout_s
        self.conn = mavutil.mavlink_connection(
            url, source_system=GCS_SYSTEM, source_component=GCS_COMPONENT
        )
        self.conn.mav = M.MAVLink(self.conn, srcSystem=GCS_SYSTEM, srcComponent=GCS_COMPONENT)
        self.conn.mav.robust_parsing = True
        self.autopilot: tuple[int, int] | None = None
        self.heartbeat_sources: set[tuple[int, int, int]] = set()  # (sys, comp, MAV_TYPE)
        self.statustexts: list[Statustext] = []
        self._latest: dict[str, tuple[Any, float]] = {}
        self._waiters: list[_Waiter] = []
        self._lock = threading.Lock()
        self._send_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read_loop, name="sitl-pilot", daemon=True)
        self._thread.start()

    # -- reading ---------------------------------------------------------------------------
    def _read_loop(self) -> None:
        while not self._stop.is_set():
            try:
                msg = self.conn.recv_match(blocking=True, timeout=0.1)
            except OSError:
                time.sleep(0.05)
                continue
            if msg is None or msg.get_type() == "BAD_DATA":
                continue
            self._on_message(msg, time.monotonic())

    def _on_message(self, msg: Any, arrival: float) -> None:
        mtype = msg.get_type()
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        with self._lock:
            if mtype == "HEARTBEAT":
                self.heartbeat_sources.add((*src, int(msg.type)))
                if (
                    self.autopilot is None
                    and msg.autopilot != M.MAV_AUTOPILOT_INVALID
                    and msg.type != M.MAV_TYPE_GCS
                ):
                    self.autopilot = src
            if mtype == "STATUSTEXT":
                self.statustexts.append(
                    Statustext(
                        int(msg.severity),
                        _text(msg.text),
                        *src,
                        arrival,
                        int(getattr(msg, "id", 0)),
                        int(getattr(msg, "chunk_seq", 0)),
                    )
                )
            if src == self.autopilot:
                self._latest[mtype] = (msg, arrival)
            waiters = [w for w in self._waiters if mtype in w.types]
        for w in waiters:
            if w.predicate is None or w.predicate(msg):
                w.queue.put(msg)

    def latest(self, mtype: str) -> Any | None:
        """The newest message of ``mtype`` from the autopilot (None: none yet)."""
        with self._lock:
            entry = self._latest.get(mtype)
        return None if entry is None else entry[0]

    def latest_arrival(self, mtype: str) -> float | None:
        """``time.monotonic()`` when the newest ``mtype`` from the autopilot arrived."""
        with self._lock:
            entry = self._latest.get(mtype)
        return None if entry is None else entry[1]

    def forget(self, *mtypes: str) -> None:
        """Drop the newest messages of ``mtypes`` (e.g. before waiting for fresh ones)."""
        with self._lock:
            for mtype in mtypes:
                self._latest.pop(mtype, None)

    def wait_message(
        self,
        types: Iterable[str],
        predicate: Callable[[Any], bool] | None = None,
        timeout: float = 10.0,
        send: Callable[[], None] | None = None,
    ) -> Any | None:
        """The next message of ``types`` matching ``predicate`` after calling ``send`` (if
        given), or None after ``timeout`` seconds."""
        waiter = _Waiter(frozenset(types), predicate)
        with self._lock:
            self._waiters.append(waiter)
        try:
            if send is not None:
                send()
            try:
                return waiter.queue.get(timeout=timeout)
            except queue.Empty:
                return None
        finally:
            with self._lock:
                self._waiters.remove(waiter)

    def statustexts_from(self, system: int, component: int) -> list[Statustext]:
        """STATUSTEXT seen from sender ``system``/``component``."""
        with self._lock:
            return [
                s
                for s in self.statustexts
                if (s.src_system, s.src_component) == (system, component)
            ]

    def autopilot_texts(self, since: float = -math.inf) -> list[str]:
        """Texts of the autopilot's STATUSTEXT that arrived after ``since``."""
        with self._lock:
            return [
                s.text
                for s in self.statustexts
                if (s.src_system, s.src_component) == self.autopilot and s.arrival > since
            ]

    # -- sending ---------------------------------------------------------------------------
    @property
    def target(self) -> tuple[int, int]:
        return self.autopilot or (1, 1)

    def send(self, msg: Any) -> None:
        with self._send_lock:
            self.conn.mav.send(msg)

    def wait_heartbeat(self, timeout: float = 30.0) -> tuple[int, int]:
        """The autopilot's ``(system, component)`` once its HEARTBEAT arrived."""
        found = wait_for(lambda: self.autopilot, timeout)
        if not found:
            raise TimeoutError(f"no autopilot HEARTBEAT on {self.url} within {timeout:.0f} s")
        return found

    def command_long(
        self, command: int, *params: float, timeout: float | None = None
    ) -> Any | None:
        """COMMAND_LONG; returns the autopilot's COMMAND_ACK for it (None: no answer)."""
        p = [float(v) for v in params] + [0.0] * (7 - len(params))
        msg = self.conn.mav.command_long_encode(*self.target, command, 0, *p[:7])
        return self._command(command, msg, timeout)

    def command_int(
        self,
        command: int,
        frame: int,
        params: Sequence[float],
        lat: float,
        lon: float,
        alt: float,
        timeout: float | None = None,
    ) -> Any | None:
        """COMMAND_INT at ``lat``/``lon`` (degrees) and ``alt``; returns its COMMAND_ACK."""
        p = [float(v) for v in params] + [0.0] * (4 - len(params))
        msg = self.conn.mav.command_int_encode(
            *self.target,
            frame,
            command,
            0,
            0,
            *p[:4],
            round(lat * 1e7),
            round(lon * 1e7),
            float(alt),
        )
        return self._command(command, msg, timeout)

    def _command(self, command: int, msg: Any, timeout: float | None) -> Any | None:
        return self.wait_message(
            ["COMMAND_ACK"],
            lambda m: m.command == command and m.target_system in (0, GCS_SYSTEM),
            self.ack_timeout_s if timeout is None else timeout,
            send=lambda: self.send(msg),
        )

    def request_streams(self, rate_hz: float = 2.0) -> None:
        """All data streams at ``rate_hz`` (simulated time) and HOME_POSITION at 1 Hz: what a
        ground station asks for on connecting."""
        self.send(
            self.conn.mav.request_data_stream_encode(
                *self.target, M.MAV_DATA_STREAM_ALL, max(1, round(rate_hz)), 1
            )
        )
        self.command_long(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_HOME_POSITION, 1e6)

    def set_param(self, name: str, value: float, timeout: float = 5.0) -> float:
        """PARAM_SET; returns the value the autopilot reports back in PARAM_VALUE."""
        msg = self.conn.mav.param_set_encode(
            *self.target, name.encode("ascii"), float(value), M.MAV_PARAM_TYPE_REAL32
        )
        reply = self.wait_message(
            ["PARAM_VALUE"],
            lambda m: _text(m.param_id) == name,
            timeout,
            send=lambda: self.send(msg),
        )
        if reply is None:
            raise TimeoutError(f"no PARAM_VALUE for {name}")
        return float(reply.param_value)

    # -- vehicle state ---------------------------------------------------------------------
    def position(self) -> Any | None:
        """The newest GLOBAL_POSITION_INT."""
        return self.latest("GLOBAL_POSITION_INT")

    def mode(self) -> int | None:
        """The autopilot's custom mode from its newest HEARTBEAT."""
        hb = self.latest("HEARTBEAT")
        return None if hb is None else int(hb.custom_mode)

    @property
    def armed(self) -> bool:
        hb = self.latest("HEARTBEAT")
        return hb is not None and bool(hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)

    def wait_gps_fix(self, timeout: float = 60.0) -> Any:
        """The first GLOBAL_POSITION_INT with a position (ArduPilot sends 0, 0 before)."""
        found = wait_for(
            lambda: (p := self.position()) is not None and (p.lat or p.lon) and p, timeout
        )
        if not found:
            raise TimeoutError("no GPS position from the autopilot")
        return found

    def wait_home(self, timeout: float = 60.0) -> Any:
        """The autopilot's HOME_POSITION (it has none before its GPS fix)."""
        found = wait_for(lambda: self.latest("HOME_POSITION"), timeout)
        if not found:
            raise TimeoutError("no HOME_POSITION from the autopilot")
        return found

    def set_mode(self, name: str, timeout: float = 10.0) -> None:
        """MAV_CMD_DO_SET_MODE to ``name``, until the HEARTBEAT reports it."""
        custom = COPTER_MODES[name]
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.command_long(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, custom)
            if wait_for(lambda: self.mode() == custom, 1.0):
                return
        raise TimeoutError(f"mode {name} not reached; autopilot said: {self.autopilot_texts()}")

    def arm(self, timeout: float = 120.0) -> None:
        """GUIDED and arm, retried while the pre-arm checks refuse (COMMAND_ACK 4 and a
        STATUSTEXT reason, for tens of simulated seconds after boot)."""
        deadline = time.monotonic() + timeout
        started = time.monotonic()
        while time.monotonic() < deadline:
            self.set_mode("GUIDED", timeout=max(1.0, deadline - time.monotonic()))
            ack = self.command_long(M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
            if (
                ack is not None
                and ack.result == M.MAV_RESULT_ACCEPTED
                and wait_for(lambda: self.armed, 5.0)
            ):
                return
            time.sleep(0.5)
        raise TimeoutError(f"not armable; autopilot said: {self.autopilot_texts(started)[-5:]}")

    def takeoff(self, alt: float, timeout: float = 120.0) -> None:
        """MAV_CMD_NAV_TAKEOFF to ``alt`` m above home (armed, GUIDED), until 95 % reached."""
        ack = self.command_long(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, alt)
        if ack is None or ack.result != M.MAV_RESULT_ACCEPTED:
            raise RuntimeError(f"takeoff refused: {ack}; {self.autopilot_texts()[-3:]}")
        if not wait_for(
            lambda: (p := self.position()) is not None and p.relative_alt / 1000.0 > 0.95 * alt,
            timeout,
        ):
            raise TimeoutError(f"altitude {alt} m not reached: {self.position()}")

    def fly_up(self, alt: float, timeout: float = 180.0) -> None:
        """Arm and take off to ``alt`` (see :meth:`arm`, :meth:`takeoff`)."""
        self.arm(timeout)
        self.takeoff(alt, timeout)

    # -- missions --------------------------------------------------------------------------
    def upload_mission(self, items: Sequence[Waypoint], timeout: float = 20.0) -> int:
        """MISSION_COUNT, then the item each MISSION_REQUEST(_INT) asks for, until MISSION_ACK;
        returns its result (0: accepted)."""
        mav = self.conn.mav
        ts, tc = self.target
        deadline = time.monotonic() + timeout
        last: Any = mav.mission_count_encode(ts, tc, len(items), M.MAV_MISSION_TYPE_MISSION)
        self_waiter = _Waiter(
            frozenset({"MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"}),
            lambda m: m.target_system == GCS_SYSTEM,
        )
        with self._lock:
            self._waiters.append(self_waiter)
        try:
            self.send(last)
            while time.monotonic() < deadline:
                try:
                    reply = self_waiter.queue.get(timeout=self.ack_timeout_s)
                except queue.Empty:
                    self.send(last)
                    continue
                if reply.get_type() == "MISSION_ACK":
                    return int(reply.type)
                it = items[reply.seq]
                last = mav.mission_item_int_encode(
                    ts,
                    tc,
                    reply.seq,
                    it.frame,
                    it.command,
                    0,
                    1,
                    *it.params,
                    round(it.lat * 1e7),
                    round(it.lon * 1e7),
                    float(it.alt),
                    M.MAV_MISSION_TYPE_MISSION,
                )
                self.send(last)
        finally:
            with self._lock:
                self._waiters.remove(self_waiter)
        raise TimeoutError("mission upload: no MISSION_ACK")

    def read_mission(self, timeout: float = 20.0) -> list[Any]:
        """MISSION_REQUEST_LIST, then MISSION_REQUEST_INT for each item; returns the
        MISSION_ITEM_INT messages in order (item 0 is home)."""
        mav = self.conn.mav
        ts, tc = self.target
        count = None
        for _ in range(5):
            count = self.wait_message(
                ["MISSION_COUNT"],
                lambda m: m.target_system == GCS_SYSTEM,
                self.ack_timeout_s,
                send=lambda: self.send(
                    mav.mission_request_list_encode(ts, tc, M.MAV_MISSION_TYPE_MISSION)
                ),
            )
            if count is not None:
                break
        if count is None:
            raise TimeoutError("no MISSION_COUNT")
        items = []
        deadline = time.monotonic() + timeout
        for seq in range(count.count):
            item = None
            while item is None and time.monotonic() < deadline:
                item = self.wait_message(
                    ["MISSION_ITEM_INT"],
                    lambda m, seq=seq: m.seq == seq and m.target_system == GCS_SYSTEM,
                    self.ack_timeout_s,
                    send=lambda seq=seq: self.send(
                        mav.mission_request_int_encode(ts, tc, seq, M.MAV_MISSION_TYPE_MISSION)
                    ),
                )
            if item is None:
                raise TimeoutError(f"mission item {seq} not received")
            items.append(item)
        self.send(
            mav.mission_ack_encode(ts, tc, M.MAV_MISSION_ACCEPTED, M.MAV_MISSION_TYPE_MISSION)
        )
        return items

    def close(self) -> None:
        """Stop the reader and close the socket (idempotent)."""
        if self._stop.is_set():
            return
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.conn.close()


def _text(value: Any) -> str:
    if isinstance(value, bytes):
        value = value.decode("ascii", "replace")
    return str(value).rstrip("\0")


def distance_m(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Horizontal distance between two points (equirectangular: fine over kilometres)."""
    dn = math.radians(lat2 - lat1) * 6_371_000.0
    de = math.radians(lon2 - lon1) * 6_371_000.0 * math.cos(math.radians((lat1 + lat2) / 2))
    return math.hypot(dn, de)
