"""The simulated vehicle's telemetry streams: what it sends, when, and on request.

HEARTBEAT goes out at 1 Hz wall clock; the other streams at their rates in sim time, each sample
stamped with its capture time and sent ``latency_s`` later. MAV_CMD_SET_MESSAGE_INTERVAL and
MAV_CMD_REQUEST_MESSAGE reach the streams through :meth:`StreamScheduler.set_interval` and
:meth:`StreamScheduler.request`.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sim.telemetry import AttitudeSample, GimbalSample, PositionSample, TelemetryModel
from sim.vehicle.autopilot import AutopilotState
from sim.vehicle.link import VehicleLink

log = logging.getLogger(__name__)

M = mavlink2

#: Message id -> (stream name, default rate Hz in sim time).
STREAMS: dict[int, tuple[str, float]] = {
    M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: ("position", 10.0),
    M.MAVLINK_MSG_ID_GPS_RAW_INT: ("gps", 5.0),
    M.MAVLINK_MSG_ID_ATTITUDE: ("attitude", 20.0),
    M.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS: ("gimbal", 5.0),
    M.MAVLINK_MSG_ID_SYSTEM_TIME: ("system_time", 1.0),
    M.MAVLINK_MSG_ID_HOME_POSITION: ("home", 0.5),
}

GPS_FIX_3D = 3
GPS_SATELLITES = 10
GPS_HDOP = 121  # eph (HDOP x 100) as Copter SITL reports it
#: Samples this far behind (a stall) are skipped rather than sent in a burst.
STALL_SKIP_S = 2.0


@dataclass
class _Stream:
    interval_s: float  # 0 = off
    next_t: float = 0.0


def _i16(v: float) -> int:
    return int(max(-32768, min(32767, round(v))))


class StreamScheduler:
    """Sends the vehicle's streams through ``link`` from ``telemetry`` as they fall due.

    ``stream_on_request``: every stream starts off until SET_MESSAGE_INTERVAL asks for it
    (ArduPilot's behaviour towards a companion computer); the gimbal stream is off without a
    gimbal. ``gnss_noise_m`` sets GPS_RAW_INT's reported accuracy; ``seed`` its UID.
    """

    def __init__(
        self,
        link: VehicleLink,
        telemetry: TelemetryModel,
        autopilot: AutopilotState,
        gnss_noise_m: float,
        seed: int,
        stream_on_request: bool,
    ) -> None:
        self.link = link
        self.telemetry = telemetry
        self.autopilot = autopilot
        self.gnss_noise_m = gnss_noise_m
        self.seed = seed
        self._next_heartbeat = 0.0
        self._streams: dict[int, _Stream] = {}
        for msg_id, (name, rate) in STREAMS.items():
            off = stream_on_request or (name == "gimbal" and not autopilot.has_gimbal)
            self._streams[msg_id] = _Stream(0.0 if off else 1.0 / rate)

    def _available(self, msg_id: int) -> bool:
        return msg_id in STREAMS and not (
            STREAMS[msg_id][0] == "gimbal" and not self.autopilot.has_gimbal
        )

    # -- requests ----------------------------------------------------------------------------------
    def set_interval(self, msg_id: int, interval_us: float, now: float) -> bool:
        """SET_MESSAGE_INTERVAL: -1 stops the stream, 0 restores its default rate, else the
        interval in microseconds. False for a message this vehicle does not stream."""
        if not self._available(msg_id) or not (interval_us == -1 or interval_us >= 0):
            return False
        name, rate = STREAMS[msg_id]
        stream = self._streams[msg_id]
        if interval_us == -1:
            stream.interval_s = 0.0
        else:
            was_off = stream.interval_s <= 0
            stream.interval_s = 1.0 / rate if interval_us == 0 else interval_us / 1e6
            if was_off:
                stream.next_t = now
        log.info("stream %s interval %.3f s", name, stream.interval_s)
        return True

    def request(self, msg_id: int, now: float) -> bool:
        """REQUEST_MESSAGE: send ``msg_id`` once now; False for one it cannot send."""
        if msg_id == M.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            self.send_autopilot_version()
        elif msg_id == M.MAVLINK_MSG_ID_HOME_POSITION:
            self.send_home()
        elif self._available(msg_id):
            self._send_stream(msg_id, now)
        else:
            return False
        return True

    # -- schedule ----------------------------------------------------------------------------------
    def send_due(self) -> None:
        """Send the heartbeat and every stream sample whose time (plus latency) has come."""
        mono = time.monotonic()
        if mono >= self._next_heartbeat:
            self._next_heartbeat = mono + 1.0
            self._send_heartbeat()
        now = self.link.sim_time()
        lat = self.telemetry.latency_s
        for msg_id, stream in self._streams.items():
            if stream.interval_s <= 0:
                continue
            if stream.next_t < now - STALL_SKIP_S:  # fell far behind (stall): skip ahead
                stream.next_t = now - lat
            while stream.next_t + lat <= now:
                self._send_stream(msg_id, stream.next_t)
                stream.next_t += stream.interval_s

    # -- messages ----------------------------------------------------------------------------------
    def _send_heartbeat(self) -> None:
        base = (
            M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
            | M.MAV_MODE_FLAG_SAFETY_ARMED
            | M.MAV_MODE_FLAG_STABILIZE_ENABLED
            | M.MAV_MODE_FLAG_GUIDED_ENABLED
        )
        self.link.send(
            "HEARTBEAT",
            self.link.mav.heartbeat_send,
            M.MAV_TYPE_QUADROTOR,
            M.MAV_AUTOPILOT_ARDUPILOTMEGA,
            base,
            self.autopilot.custom_mode,
            M.MAV_STATE_ACTIVE,
        )

    def _send_stream(self, msg_id: int, t: float) -> None:
        if msg_id == M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT:
            self._send_position(t)
        elif msg_id == M.MAVLINK_MSG_ID_GPS_RAW_INT:
            self._send_gps_raw(t)
        elif msg_id == M.MAVLINK_MSG_ID_ATTITUDE:
            self._send_attitude(t)
        elif msg_id == M.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS:
            self._send_gimbal(t)
        elif msg_id == M.MAVLINK_MSG_ID_SYSTEM_TIME:
            self.link.send(
                "SYSTEM_TIME",
                self.link.mav.system_time_send,
                self.link.unix_us(t),
                int(round(t * 1000.0)),
            )
        elif msg_id == M.MAVLINK_MSG_ID_HOME_POSITION:
            self.send_home()

    def _send_position(self, t: float) -> None:
        p: PositionSample = self.telemetry.position(t)
        fix = self.autopilot.has_gps_fix(t)
        v = p.velocity_ned if fix else (0.0, 0.0, 0.0)
        self.link.send(
            "GLOBAL_POSITION_INT",
            self.link.mav.global_position_int_send,
            int(round(t * 1000.0)),
            int(round(p.lat_deg * 1e7)) if fix else 0,
            int(round(p.lon_deg * 1e7)) if fix else 0,
            int(round(p.alt_m * 1000)) if fix else 0,
            int(round(p.relative_alt_m * 1000)) if fix else 0,
            _i16(v[0] * 100),
            _i16(v[1] * 100),
            _i16(v[2] * 100),
            int(round(p.heading_deg * 100)) % 36000,
        )

    def _send_attitude(self, t: float) -> None:
        a: AttitudeSample = self.telemetry.attitude(t)
        self.link.send(
            "ATTITUDE",
            self.link.mav.attitude_send,
            int(round(t * 1000.0)),
            a.roll,
            a.pitch,
            a.yaw,
            a.rollspeed,
            a.pitchspeed,
            a.yawspeed,
        )

    def _send_gimbal(self, t: float) -> None:
        g: GimbalSample | None = self.telemetry.gimbal(t)
        if g is None:
            return
        nan = float("nan")
        self.link.send(
            "GIMBAL_DEVICE_ATTITUDE_STATUS",
            self.link.mav.gimbal_device_attitude_status_send,
            0,
            0,
            int(round(t * 1000.0)),
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

    def _send_gps_raw(self, t: float) -> None:
        """GPS_RAW_INT at sim time ``t``: the GNSS position with a 3D fix, or, before
        ``gps_fix_after_s``, no fix at all (fix_type 0, lat/lon 0, no satellites), as ArduPilot
        reports its GPS while it searches."""
        unknown = 0xFFFF
        if not self.autopilot.has_gps_fix(t):
            self.link.send(
                "GPS_RAW_INT",
                self.link.mav.gps_raw_int_send,
                int(t * 1e6),
                0,
                0,
                0,
                0,
                unknown,
                unknown,
                0,
                unknown,
                0,
                0,
                0,
                0,
                0,
                0,
                0,
            )
            return
        p: PositionSample = self.telemetry.position(t)
        v = p.velocity_ned
        speed = math.hypot(v[0], v[1])
        cog = int(round(math.degrees(math.atan2(v[1], v[0])) * 100)) % 36000
        h_acc_mm = max(1, int(round(self.gnss_noise_m * 1000)))
        self.link.send(
            "GPS_RAW_INT",
            self.link.mav.gps_raw_int_send,
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

    def send_home(self) -> None:
        """HOME_POSITION now; nothing until the autopilot has a home, as ArduPilot."""
        now = self.link.sim_time()
        if not self.autopilot.has_home(now):
            return
        lat, lon, alt = self.autopilot.home
        self.link.send(
            "HOME_POSITION",
            self.link.mav.home_position_send,
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
            self.link.unix_us(self.link.sim_time()),
        )

    def send_autopilot_version(self) -> None:
        """AUTOPILOT_VERSION: Copter 4.7.0 official with MISSION_INT, COMMAND_INT, MAVLink 2."""
        caps = (
            M.MAV_PROTOCOL_CAPABILITY_MISSION_INT
            | M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
            | M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
            | M.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
        )
        # flight_sw_version 4.7.0 official: 0x04070000 | FIRMWARE_VERSION_TYPE_OFFICIAL (255)
        self.link.send(
            "AUTOPILOT_VERSION",
            self.link.mav.autopilot_version_send,
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
