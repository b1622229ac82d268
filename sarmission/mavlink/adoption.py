"""Which sender on the link is *the* autopilot: one adopted (system, component), and who may speak.

Anyone on a MAVLink link can claim to be an autopilot. The link adopts one: the first sender of an
autopilot-type HEARTBEAT (``autopilot`` not MAV_AUTOPILOT_INVALID, ``type`` a vehicle, not a ground
station, companion computer, gimbal, camera, ADS-B receiver, antenna tracker...), restricted to
``target_system`` / ``target_component`` when those are pinned. It keeps that one until it has been
silent for longer than ``link_timeout_s`` and another candidate *of the same system* is heard;
only then is the other adopted (a re-adoption, logged with both ids). The companion computer is on
one vehicle: another system id is adopted only after the adopted autopilot has been silent for
``system_switch_s`` (:data:`SYSTEM_SWITCH_S`, a minute: gone, not a fading link), and the former
autopilot is taken back as soon as it is heard again. Data of one autopilot is never used for
another (the telemetry buffer is emptied and refuses times before a switch). A second
candidate heard while the adopted one is alive is only warned about (at most every
:data:`RIVAL_WARN_S`): two autopilots on one link is either a misconfiguration or a spoofer, and
pinning is the cure.

:func:`source_kind` says whether a message comes from the adopted autopilot, from a gimbal of its
system, or from someone else, for the link's source filter. Of several gimbals the telemetry
buffer uses one (:class:`~sarmission.mavlink.telemetry.TelemetryBuffer`: the configured one,
else the first heard).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Hashable
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as M

log = logging.getLogger(__name__)

#: HEARTBEAT ``type`` values of things that are not the vehicle's flight controller.
NON_AUTOPILOT_TYPES = frozenset(
    {
        M.MAV_TYPE_ANTENNA_TRACKER,
        M.MAV_TYPE_GCS,
        M.MAV_TYPE_ONBOARD_CONTROLLER,
        M.MAV_TYPE_GIMBAL,
        M.MAV_TYPE_ADSB,
        M.MAV_TYPE_CAMERA,
        M.MAV_TYPE_CHARGING_STATION,
        M.MAV_TYPE_FLARM,
        M.MAV_TYPE_SERVO,
        M.MAV_TYPE_ODID,
        M.MAV_TYPE_BATTERY,
        M.MAV_TYPE_PARACHUTE,
        M.MAV_TYPE_LOG,
        M.MAV_TYPE_OSD,
        M.MAV_TYPE_IMU,
        M.MAV_TYPE_GPS,
        M.MAV_TYPE_WINCH,
        M.MAV_TYPE_ILLUMINATOR,
        M.MAV_TYPE_GRIPPER,
    }
)

#: Component ids of gimbals (MAV_COMP_ID_GIMBAL and GIMBAL2..6).
GIMBAL_COMPONENTS = frozenset(
    {
        M.MAV_COMP_ID_GIMBAL,
        M.MAV_COMP_ID_GIMBAL2,
        M.MAV_COMP_ID_GIMBAL3,
        M.MAV_COMP_ID_GIMBAL4,
        M.MAV_COMP_ID_GIMBAL5,
        M.MAV_COMP_ID_GIMBAL6,
    }
)

#: Gimbal attitude messages, accepted from the autopilot or from a gimbal of its system.
GIMBAL_TYPES = frozenset({"GIMBAL_DEVICE_ATTITUDE_STATUS", "MOUNT_ORIENTATION"})

#: Seconds between two warnings about a second autopilot (or a pinned-out one) on the link.
RIVAL_WARN_S = 10.0
#: Seconds the adopted autopilot must be silent before one of another system is adopted.
SYSTEM_SWITCH_S = 60.0

Source = tuple[int, int]


def is_autopilot_heartbeat(msg: Any) -> bool:
    """True for a HEARTBEAT that claims to come from a vehicle's flight controller."""
    return (
        msg.get_type() == "HEARTBEAT"
        and msg.autopilot != M.MAV_AUTOPILOT_INVALID
        and msg.type not in NON_AUTOPILOT_TYPES
        and msg.get_srcComponent() not in GIMBAL_COMPONENTS
    )


def source_kind(src: Source, adopted: Source | None) -> str:
    """``"autopilot"`` (the adopted one), ``"gimbal"`` (a gimbal component of its system) or
    ``"foreign"`` (anyone else, and everyone while no autopilot is adopted)."""
    if adopted is None:
        return "foreign"
    if src == adopted:
        return "autopilot"
    if src[0] == adopted[0] and src[1] in GIMBAL_COMPONENTS:
        return "gimbal"
    return "foreign"


@dataclass(frozen=True)
class AdoptionChange:
    """An autopilot was adopted: ``new``, replacing ``old`` (None the first time), which had been
    silent for ``silent_s`` seconds (inf the first time)."""

    new: Source
    old: Source | None
    silent_s: float


class Adoption:
    """The adopted autopilot of one link and the other candidates heard (reader thread only).

    ``heartbeat`` is fed every accepted autopilot-type HEARTBEAT (signature already verified when
    signing is on), ``heard`` every accepted message; times are ``time.monotonic()`` values.
    """

    def __init__(
        self,
        link_timeout_s: float,
        target_system: int | None = None,
        target_component: int | None = None,
        label: str = "",
        system_switch_s: float = SYSTEM_SWITCH_S,
    ) -> None:
        self.link_timeout_s = link_timeout_s
        self.system_switch_s = max(system_switch_s, link_timeout_s)
        self.target_system = target_system
        self.target_component = target_component
        self.label = label
        self.adopted: Source | None = None
        #: The autopilot adopted before the current one (taken back when heard again).
        self.former: Source | None = None
        self.adoptions = 0
        self.last_heard: float | None = None
        #: Other autopilot-type senders -> time of their last HEARTBEAT (pinned-out ones too).
        self.candidates: dict[Source, float] = {}
        self._warned: dict[Hashable, float] = {}

    def eligible(self, src: Source) -> bool:
        """Whether ``src`` may be adopted (matches the pinned system/component, if any)."""
        return (self.target_system is None or src[0] == self.target_system) and (
            self.target_component is None or src[1] == self.target_component
        )

    def silence_s(self, now: float) -> float:
        """Seconds since the adopted autopilot was last heard (inf if never)."""
        return math.inf if self.last_heard is None else now - self.last_heard

    def heard(self, src: Source, arrival: float) -> None:
        """Any accepted message: refreshes the adopted autopilot's last-heard time."""
        if src == self.adopted:
            self.last_heard = arrival

    def heartbeat(self, src: Source, arrival: float) -> AdoptionChange | None:
        """An autopilot-type HEARTBEAT from ``src``; returns the change when it is adopted."""
        if src == self.adopted:
            self.last_heard = arrival
            return None
        self.candidates[src] = arrival
        if not self.eligible(src):
            self._warn(
                ("pinned", src),
                arrival,
                "ignoring autopilot %d/%d: the link is pinned to %s",
                *src,
                self.pin_text(),
            )
            return None
        silent = self.silence_s(arrival)
        if self.adopted is not None and src != self.former:
            other_system = src[0] != self.adopted[0]
            if silent <= self.link_timeout_s:
                self._warn(
                    "rival",
                    arrival,
                    "two autopilots on the link: %d/%d (adopted) and %d/%d; pin one with "
                    "--target-system",
                    *self.adopted,
                    *src,
                )
                return None
            if other_system and silent <= self.system_switch_s:
                self._warn(
                    ("other system", src),
                    arrival,
                    "autopilot %d/%d silent for %.1f s; not adopting %d/%d of another system "
                    "before %.0f s of silence (pin it with --target-system)",
                    *self.adopted,
                    silent,
                    *src,
                    self.system_switch_s,
                )
                return None
        change = AdoptionChange(src, self.adopted, silent)
        taken_back = self.adopted is not None and src == self.former
        self.candidates.pop(src, None)
        self.former = self.adopted
        self.adopted = src
        self.adoptions += 1
        self.last_heard = arrival
        if change.old is None:
            log.info("autopilot %d/%d adopted%s", *src, self.label)
        elif taken_back:
            log.warning(
                "autopilot %d/%d heard again: taken back from %d/%d%s",
                *src,
                *change.old,
                self.label,
            )
        else:
            log.warning(
                "autopilot %d/%d silent for %.1f s; adopting autopilot %d/%d instead%s",
                *change.old,
                silent,
                *src,
                self.label,
            )
        return change

    def rivals(self, now: float) -> list[Source]:
        """Other autopilot-type senders whose HEARTBEAT was heard within ``link_timeout_s``."""
        heard = list(self.candidates.items())  # a copy in one step: the reader thread adds to it
        return sorted(s for s, t in heard if now - t <= self.link_timeout_s)

    def pin_text(self) -> str:
        """The pin in words: "system 1", "component 1", "1/1"."""
        if self.target_system is not None and self.target_component is not None:
            return f"{self.target_system}/{self.target_component}"
        if self.target_system is not None:
            return f"system {self.target_system}"
        return f"component {self.target_component}"

    def _warn(self, key: Hashable, now: float, message: str, *args: object) -> None:
        last = self._warned.get(key)
        if last is not None and now - last < RIVAL_WARN_S:
            return
        self._warned[key] = now
        log.warning(message, *args)
