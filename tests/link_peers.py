"""Raw MAVLink peers for link tests: any system/component id, signed or not, on 127.0.0.1 UDP.

:class:`RawPeer` plays an autopilot (or a spoofer claiming to be one): HEARTBEATs at 5 Hz, and
optionally answers MAV_CMD_SET_MESSAGE_INTERVAL with ACCEPTED while sending only the streams in
``honour`` (ArduPilot accepts a gimbal stream it has no mount for, then sends nothing).
"""

from __future__ import annotations

import threading
import time
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.mavlink.connection import mavlink2_connection


class RawPeer:
    """A pymavlink peer sending to ``udpout:127.0.0.1:port`` from ``system``/``component``."""

    def __init__(
        self,
        port: int,
        system: int,
        component: int = 1,
        *,
        mav_type: int = M.MAV_TYPE_QUADROTOR,
        autopilot: int = M.MAV_AUTOPILOT_ARDUPILOTMEGA,
        key: bytes | None = None,
        heartbeat: bool = True,
        ack_intervals: bool = False,
        honour: set[int] | None = None,
    ) -> None:
        self.conn = mavlink2_connection(f"udpout:127.0.0.1:{port}", system, component)
        if key is not None:
            self.conn.setup_signing(key, sign_outgoing=True)
        self.mav_type = mav_type
        self.autopilot = autopilot
        self.ack_intervals = ack_intervals
        self.honour = set(honour or ())
        self.heartbeat = threading.Event()
        if heartbeat:
            self.heartbeat.set()
        self.heartbeats_sent = 0
        self.received: list[Any] = []
        #: SET_MESSAGE_INTERVAL requests received: (message id, interval us).
        self.interval_requests: list[tuple[int, float]] = []
        self.streams: dict[int, float] = {}  # accepted: message id -> interval s
        self._next_stream: dict[int, float] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    @property
    def link_id(self) -> int:
        """The signing link id this peer's packets carry."""
        return int(self.conn.mav.signing.link_id)

    def send(self, msg: Any) -> None:
        """Send an encoded message (``peer.conn.mav.xxx_encode(...)``) from the peer's ids."""
        with self._lock:
            self.conn.mav.send(msg)

    def requests_for(self, msg_id: int) -> int:
        """How many SET_MESSAGE_INTERVAL requests for ``msg_id`` arrived."""
        return sum(1 for i, _ in list(self.interval_requests) if i == msg_id)

    def start_stream(self, msg_id: int, period_s: float) -> None:
        """Send ``msg_id`` every ``period_s`` (if in ``honour``) without being asked."""
        with self._lock:
            self.streams[msg_id] = period_s

    def forget_streams(self) -> None:
        """Stop every stream, as an autopilot does when it reboots."""
        with self._lock:
            self.streams.clear()

    def _run(self) -> None:
        next_hb = 0.0
        while not self._stop.is_set():
            now = time.monotonic()
            if self.heartbeat.is_set() and now >= next_hb:
                next_hb = now + 0.2
                self.send(
                    self.conn.mav.heartbeat_encode(
                        self.mav_type, self.autopilot, 0, 0, M.MAV_STATE_ACTIVE
                    )
                )
                self.heartbeats_sent += 1
            self._send_streams(now)
            msg = self.conn.recv_match(blocking=True, timeout=0.01)
            if msg is not None and msg.get_type() != "BAD_DATA":
                self.received.append(msg)
                if msg.get_type() in ("COMMAND_LONG", "COMMAND_INT"):
                    self._on_command(msg)

    def _on_command(self, msg: Any) -> None:
        if msg.command != M.MAV_CMD_SET_MESSAGE_INTERVAL:
            return
        msg_id = int(msg.param1)
        self.interval_requests.append((msg_id, msg.param2))
        if not self.ack_intervals:
            return
        with self._lock:
            if msg.param2 > 0:
                self.streams[msg_id] = msg.param2 / 1e6
            else:
                self.streams.pop(msg_id, None)
        self.send(
            self.conn.mav.command_ack_encode(
                M.MAV_CMD_SET_MESSAGE_INTERVAL,
                M.MAV_RESULT_ACCEPTED,
                0,
                0,
                msg.get_srcSystem(),
                msg.get_srcComponent(),
            )
        )

    def _send_streams(self, now: float) -> None:
        with self._lock:
            due = [
                i
                for i, period in self.streams.items()
                if i in self.honour and now >= self._next_stream.get(i, 0.0)
            ]
            for i in due:
                self._next_stream[i] = now + self.streams[i]
        boot_ms = int(now * 1000) & 0xFFFFFFFF
        for msg_id in due:
            if msg_id == M.MAVLINK_MSG_ID_ATTITUDE:
                self.send(self.conn.mav.attitude_encode(boot_ms, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0))
            elif msg_id == M.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS:
                self.send(
                    self.conn.mav.gimbal_device_attitude_status_encode(
                        0, 0, boot_ms, 0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, 0
                    )
                )

    def close(self) -> None:
        """Stop sending (the peer falls silent) and close its socket."""
        self._stop.set()
        self._thread.join(2.0)
        self.conn.close()

    def __enter__(self) -> RawPeer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
