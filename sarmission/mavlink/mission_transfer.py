"""The pilot's mission: read it from the autopilot, and put visits into it without losing it.

The ``mission`` action must never replace the survey the pilot planned. So the mission is first
downloaded (MISSION_REQUEST_LIST -> MISSION_COUNT -> MISSION_REQUEST_INT per item ->
MISSION_ITEM_INT -> MISSION_ACK), the visits are inserted before the item the vehicle is flying
to (:func:`insert_visits`, DO_JUMP targets renumbered so the pilot's loops still close), and the
whole list is uploaded back; the vehicle then flies the visits and resumes the pilot's survey at
the item it had reached. Item 0 is home on ArduPilot (the autopilot overwrites it on upload).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

from sarmission.mavlink.connection import M, MavlinkLink

#: MAV_CMD whose param1 is an item sequence number (must follow items that move).
_SEQ_PARAM1_COMMANDS = frozenset((M.MAV_CMD_DO_JUMP,))


@dataclass(frozen=True)
class WireItem:
    """One mission item exactly as MISSION_ITEM_INT carries it (``x``/``y`` degE7 in global
    frames, raw integers otherwise; ``z`` metres in ``frame``)."""

    frame: int
    command: int
    params: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    x: int = 0
    y: int = 0
    z: float = 0.0
    autocontinue: int = 1

    @classmethod
    def from_message(cls, msg: Any) -> WireItem:
        return cls(
            int(msg.frame),
            int(msg.command),
            (float(msg.param1), float(msg.param2), float(msg.param3), float(msg.param4)),
            int(msg.x),
            int(msg.y),
            float(msg.z),
            int(msg.autocontinue),
        )


class MissionTransferError(RuntimeError):
    """The autopilot did not complete a mission transfer (the message says how far it got)."""


def download_mission(
    link: MavlinkLink,
    timeout_s: float = 1.5,
    retries: int = 3,
    mission_type: int = M.MAV_MISSION_TYPE_MISSION,
) -> list[WireItem]:
    """The autopilot's mission, item 0 (home) included. Each request is re-sent up to
    ``retries`` times when no answer comes within ``timeout_s``; raises
    :class:`MissionTransferError` when the autopilot stays silent or refuses."""
    if link.autopilot is None:
        raise MissionTransferError("no autopilot adopted on the link")
    mav = link.mav
    ts, tc = link.target_system, link.target_component

    def for_us(msg: Any) -> bool:
        return (
            link.from_autopilot(msg)
            and getattr(msg, "target_system", 0) in (0, link.source_system)
            and getattr(msg, "mission_type", 0) == mission_type
        )

    with link.expect(["MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ACK"], for_us) as replies:
        count_msg = _ask(
            link,
            replies,
            mav.mission_request_list_encode(ts, tc, mission_type),
            "MISSION_COUNT",
            timeout_s,
            retries,
            "the mission's item count",
        )
        items: list[WireItem] = []
        for seq in range(int(count_msg.count)):
            item = _ask(
                link,
                replies,
                mav.mission_request_int_encode(ts, tc, seq, mission_type),
                "MISSION_ITEM_INT",
                timeout_s,
                retries,
                f"mission item {seq}",
                lambda m, s=seq: m.seq == s,
            )
            items.append(WireItem.from_message(item))
        link.send(mav.mission_ack_encode(ts, tc, M.MAV_MISSION_ACCEPTED, mission_type))
    return items


def _ask(
    link: MavlinkLink,
    replies: Any,
    request: Any,
    reply_type: str,
    timeout_s: float,
    retries: int,
    what: str,
    match: Any = None,
) -> Any:
    for _ in range(retries + 1):
        link.send(request)
        deadline = time.monotonic() + timeout_s
        while (remaining := deadline - time.monotonic()) > 0:
            msg = replies.get(remaining)
            if msg is None:
                break
            if msg.get_type() == "MISSION_ACK":
                name = M.enums["MAV_MISSION_RESULT"].get(msg.type)
                raise MissionTransferError(
                    f"autopilot refused the download of {what}: {name.name if name else msg.type}"
                )
            if msg.get_type() == reply_type and (match is None or match(msg)):
                return msg
    raise MissionTransferError(f"no answer for {what} after {retries + 1} requests")


def insert_visits(items: Sequence[WireItem], at: int, visits: Sequence[WireItem]) -> list[WireItem]:
    """``items`` with ``visits`` inserted before item ``at`` (the vehicle's current item;
    1 <= at <= len(items), item 0 being home). DO_JUMP targets at or after ``at`` move with the
    items they point to."""
    if not 1 <= at <= len(items):
        raise ValueError(f"insertion point {at} outside 1..{len(items)}")
    shift = len(visits)
    moved = [
        replace(it, params=(it.params[0] + shift, *it.params[1:]))
        if it.command in _SEQ_PARAM1_COMMANDS and it.params[0] >= at
        else it
        for it in items
    ]
    return [*moved[:at], *visits, *moved[at:]]


def loiter_item(lat: float, lon: float, alt_m: float, seconds: float) -> WireItem:
    """NAV_LOITER_TIME at ``lat``/``lon``, ``alt_m`` above home, for ``seconds``."""
    return WireItem(
        M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        M.MAV_CMD_NAV_LOITER_TIME,
        (float(seconds), 0.0, 0.0, 0.0),
        round(lat * 1e7),
        round(lon * 1e7),
        float(alt_m),
    )
