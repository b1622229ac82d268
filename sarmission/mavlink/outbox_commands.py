"""What the outbox can deliver: one small frozen dataclass per kind of command.

Each knows how a :class:`~sarmission.mavlink.commands.CommandSender` sends it
(:meth:`send`), so the outbox needs no table of method names, and a caller's typo is a type
error instead of a runtime lookup. :class:`StatusText` is the one kind that is never
acknowledged: the outbox sends it a number of times instead of waiting for an answer.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from sarmission.mavlink.connection import M

if TYPE_CHECKING:
    from sarmission.mavlink.commands import CommandResult, CommandSender, MissionItem
    from sarmission.mavlink.mission_transfer import WireItem


@dataclass(frozen=True)
class StatusText:
    """STATUSTEXT ``text`` at ``severity`` (chunked above 50 characters; never acknowledged)."""

    text: str
    severity: int = M.MAV_SEVERITY_ALERT

    def send(self, sender: CommandSender) -> CommandResult:
        return sender.statustext(self.text, self.severity)


@dataclass(frozen=True)
class Reposition:
    """MAV_CMD_DO_REPOSITION to ``lat``/``lon`` (degrees), ``alt`` metres above home."""

    lat: float
    lon: float
    alt: float

    def send(self, sender: CommandSender) -> CommandResult:
        return sender.reposition(self.lat, self.lon, self.alt)


@dataclass(frozen=True)
class SetRoi:
    """MAV_CMD_DO_SET_ROI_LOCATION at ``lat``/``lon`` (degrees), ``alt`` metres above home."""

    lat: float
    lon: float
    alt: float

    def send(self, sender: CommandSender) -> CommandResult:
        return sender.set_roi(self.lat, self.lon, self.alt)


@dataclass(frozen=True)
class ClearRoi:
    """MAV_CMD_DO_SET_ROI_NONE: the camera back to its mission or mount orientation."""

    def send(self, sender: CommandSender) -> CommandResult:
        return sender.clear_roi()


@dataclass(frozen=True)
class UploadMission:
    """Replace the autopilot's mission with a placeholder home and ``items``."""

    items: tuple[MissionItem, ...]

    def send(self, sender: CommandSender) -> CommandResult:
        return sender.upload_mission(self.items)


@dataclass(frozen=True)
class InsertVisits:
    """Insert ``visits`` into the pilot's mission before the item the vehicle flies to."""

    visits: tuple[WireItem, ...]

    def send(self, sender: CommandSender) -> CommandResult:
        return sender.insert_visits(self.visits)


@dataclass(frozen=True)
class CommandInt:
    """A COMMAND_INT with ``params`` 1-4, ``x``/``y`` (degE7 for global frames) and ``z``."""

    command: int
    frame: int
    params: Sequence[float] = (0.0, 0.0, 0.0, 0.0)
    x: int = 0
    y: int = 0
    z: float = 0.0

    def send(self, sender: CommandSender) -> CommandResult:
        return sender.command_int(self.command, self.frame, self.params, self.x, self.y, self.z)


@dataclass(frozen=True)
class CommandLong:
    """A COMMAND_LONG with up to 7 ``params``."""

    command: int
    params: tuple[float, ...] = ()

    def send(self, sender: CommandSender) -> CommandResult:
        return sender.command_long(self.command, *self.params)


OutboxCommand = (
    StatusText
    | Reposition
    | SetRoi
    | ClearRoi
    | UploadMission
    | InsertVisits
    | CommandInt
    | CommandLong
)
#: Every kind :meth:`~sarmission.mavlink.commands.Outbox.submit` takes.
COMMAND_KINDS = (
    StatusText,
    Reposition,
    SetRoi,
    ClearRoi,
    UploadMission,
    InsertVisits,
    CommandInt,
    CommandLong,
)
