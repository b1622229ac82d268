"""The simulated vehicle's side of the MAVLink mission protocol.

Upload (MISSION_COUNT -> MISSION_REQUEST_INT, or MISSION_REQUEST with ``legacy_mission_request``
like ArduPilot -> MISSION_ITEM_INT -> MISSION_ACK) with re-requests on timeout; download
(MISSION_REQUEST_LIST -> MISSION_COUNT -> MISSION_REQUEST_INT -> MISSION_ITEM_INT -> MISSION_ACK);
MISSION_CLEAR_ALL; the current item for MISSION_CURRENT and DO_SET_MISSION_CURRENT.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from sim.vehicle.link import VehicleLink

log = logging.getLogger(__name__)

M = mavlink2

UPLOAD_RETRY_S = 0.5
UPLOAD_MAX_RETRIES = 6
#: The most items an upload may announce.
MAX_ITEMS = 1000


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


def _peer(msg: Any) -> tuple[int, int]:
    return msg.get_srcSystem(), msg.get_srcComponent()


class MissionServer:
    """Stores the missions (types 0 mission, 1 fence, 2 rally) that clients upload and serves
    them back. The simulated flight does not follow them: :attr:`mission_current` only answers
    the protocol as ArduPilot does."""

    def __init__(self, link: VehicleLink, legacy_mission_request: bool = False) -> None:
        self.link = link
        self.legacy_mission_request = legacy_mission_request
        self.missions: dict[int, list[MissionItem]] = {0: [], 1: [], 2: []}
        #: The mission item "flown to" (MISSION_CURRENT).
        self.mission_current = 0
        self._upload: _Upload | None = None

    def handlers(self) -> dict[str, Callable[[Any], None]]:
        """Message type -> handler, for the messages of the mission protocol."""
        return {
            "MISSION_COUNT": self._on_mission_count,
            "MISSION_ITEM_INT": self._on_mission_item_int,
            "MISSION_ITEM": self._on_mission_item,
            "MISSION_REQUEST_LIST": self._on_mission_request_list,
            "MISSION_REQUEST_INT": self._on_mission_request_int,
            "MISSION_REQUEST": self._on_mission_request,
            "MISSION_CLEAR_ALL": self._on_mission_clear_all,
            "MISSION_ACK": self._on_mission_ack,
        }

    # -- current item ------------------------------------------------------------------------------
    def send_current(self) -> None:
        """MISSION_CURRENT: the current item and the mission's length."""
        self.link.send(
            "MISSION_CURRENT",
            self.link.mav.mission_current_send,
            self.mission_current,
            len(self.missions[0]),
        )

    def set_current(self, seq: int) -> bool:
        """DO_SET_MISSION_CURRENT: False for an item the stored mission does not have."""
        if not 0 <= seq < len(self.missions[0]):
            return False
        self.mission_current = seq
        return True

    # -- upload ------------------------------------------------------------------------------------
    def _ack(self, peer: tuple[int, int], result: int, mission_type: int) -> None:
        self.link.send(
            "MISSION_ACK", self.link.mav.mission_ack_send, peer[0], peer[1], result, mission_type
        )

    def _request_item(self) -> None:
        up = self._upload
        if up is None:
            return
        up.last_request = time.monotonic()
        if self.legacy_mission_request:
            self.link.send(
                "MISSION_REQUEST",
                self.link.mav.mission_request_send,
                up.peer[0],
                up.peer[1],
                up.next_seq,
                up.mission_type,
            )
        else:
            self.link.send(
                "MISSION_REQUEST_INT",
                self.link.mav.mission_request_int_send,
                up.peer[0],
                up.peer[1],
                up.next_seq,
                up.mission_type,
            )

    def _on_mission_count(self, msg: Any) -> None:
        peer = _peer(msg)
        mtype = getattr(msg, "mission_type", 0)
        if mtype not in self.missions:
            self._ack(peer, M.MAV_MISSION_UNSUPPORTED, mtype)
            return
        if msg.count == 0:
            self.missions[mtype] = []
            self._upload = None
            self._ack(peer, M.MAV_MISSION_ACCEPTED, mtype)
            return
        if msg.count > MAX_ITEMS:
            self._ack(peer, M.MAV_MISSION_NO_SPACE, mtype)
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
        peer = _peer(msg)
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
        self._ack(peer, M.MAV_MISSION_ACCEPTED, up.mission_type)

    def check_upload_timeout(self) -> None:
        """Ask again for the item an upload waits for, or cancel it after too many tries."""
        up = self._upload
        if up is None or time.monotonic() - up.last_request < UPLOAD_RETRY_S:
            return
        if up.retries >= UPLOAD_MAX_RETRIES:
            log.warning("mission upload timed out waiting for item %d", up.next_seq)
            self._ack(up.peer, M.MAV_MISSION_OPERATION_CANCELLED, up.mission_type)
            self._upload = None
            return
        up.retries += 1
        self._request_item()

    # -- download and clear ------------------------------------------------------------------------
    def _on_mission_request_list(self, msg: Any) -> None:
        mtype = getattr(msg, "mission_type", 0)
        peer = _peer(msg)
        if mtype not in self.missions:
            self._ack(peer, M.MAV_MISSION_UNSUPPORTED, mtype)
            return
        self.link.send(
            "MISSION_COUNT",
            self.link.mav.mission_count_send,
            peer[0],
            peer[1],
            len(self.missions[mtype]),
            mtype,
        )

    def _send_item(self, msg: Any, as_int: bool) -> None:
        mtype = getattr(msg, "mission_type", 0)
        peer = _peer(msg)
        items = self.missions.get(mtype)
        if items is None or not 0 <= msg.seq < len(items):
            self._ack(peer, M.MAV_MISSION_INVALID_SEQUENCE, mtype)
            return
        it = items[msg.seq]
        head = (
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
        )
        if as_int:
            self.link.send(
                "MISSION_ITEM_INT",
                self.link.mav.mission_item_int_send,
                *head,
                it.x,
                it.y,
                it.z,
                mtype,
            )
        else:
            self.link.send(
                "MISSION_ITEM",
                self.link.mav.mission_item_send,
                *head,
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
        self._ack(_peer(msg), M.MAV_MISSION_ACCEPTED, mtype)

    def _on_mission_ack(self, msg: Any) -> None:
        log.debug("mission ack %d from %d/%d", msg.type, *_peer(msg))
