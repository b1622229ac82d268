"""The alert: one confirmed target, as the operator and the autopilot are told about it.

An :class:`Alert` is created once per confirmed (locked) target and never changes afterwards except
for its acknowledgement, what is known of its way to the autopilot, and - for a target that could
not be geolocated when it was confirmed - the position attached once it is; the store keeps these.

What is known differs by channel. A command (DO_REPOSITION, ROI, mission upload) is answered by
the autopilot: it is *delivered* when accepted, *refused* (with the autopilot's result and reason)
otherwise. A STATUSTEXT has no acknowledgement in MAVLink: all that is known is that it was *sent*
n times, so it is sent several times and never called delivered (:data:`UNACKNOWLEDGED_CHANNELS`).
Positions are WGS84 degrees; times are UTC POSIX seconds.
"""

from __future__ import annotations

import base64
import hashlib
import math
import uuid
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, Literal

#: STATUSTEXT's ``text`` field holds 50 bytes.
STATUSTEXT_MAX_BYTES = 50

#: Delivery channel name for the MAVLink STATUSTEXT alert.
CHANNEL_MAVLINK = "mavlink"

#: Channels without an acknowledgement: only how often the alert was sent is known.
UNACKNOWLEDGED_CHANNELS = frozenset({CHANNEL_MAVLINK})

#: Alphabet of the short id's suffix: lower-case letters and digits that are not mistaken for
#: one another on a ground station's screen (no 0/o, 1/l/i).
_SHORT_ALPHABET = "23456789abcdefghjkmnpqrstuvwxyz"

ThumbnailMode = Literal["url", "base64", "omit"]


def new_alert_id() -> str:
    """A fresh, globally unique alert id (uuid4 hex, 32 characters)."""
    return uuid.uuid4().hex


def plain_decimal(value: float) -> str:
    """``value`` in plain decimal notation at full precision (shortest round-trip digits).

    ``repr`` would write tiny values as ``1e-05``, which KML and CoT readers reject.
    """
    text = repr(float(value))
    if "e" in text or "E" in text:
        text = f"{value:.17f}".rstrip("0").rstrip(".")
    return text


def check_position(position: tuple[float, float]) -> tuple[float, float]:
    """``(lat, lon)`` as floats; ValueError unless both are finite and in range."""
    lat, lon = (float(v) for v in position)
    if not (math.isfinite(lat) and math.isfinite(lon)):
        raise ValueError(f"alert position must be finite, got {position}")
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        raise ValueError(f"alert position out of range: {position}")
    return lat, lon


def utc_iso(t: float) -> str:
    """POSIX seconds as ISO 8601 UTC with milliseconds, e.g. ``2024-05-01T12:00:00.250Z``."""
    return datetime.fromtimestamp(t, UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def make_short_id(target_id: int, alert_id: str) -> str:
    """``T<target id>-<2 characters of a hash of alert_id>``, e.g. ``T12-k3``.

    Target ids are unique within a mission; the suffix tells apart two alerts of one target (or
    of two runs), and is the same after a restart because the alert id is stored."""
    digest = int.from_bytes(hashlib.sha256(alert_id.encode()).digest()[:4], "big")
    n = len(_SHORT_ALPHABET)
    return f"T{int(target_id)}-{_SHORT_ALPHABET[digest % n]}{_SHORT_ALPHABET[digest // n % n]}"


@dataclass(frozen=True)
class Sends:
    """How often an alert went out on a channel without acknowledgement, and when (POSIX s)."""

    count: int
    first: float
    last: float


@dataclass(frozen=True)
class Refusal:
    """The autopilot's answer refusing a command: when, its result code (MAV_RESULT or
    MAV_MISSION_RESULT) and the readable reason (with the autopilot's own text when it gave
    one)."""

    time: float
    result: int
    reason: str


@dataclass
class Alert:
    """A confirmed target.

    ``position`` is ``(lat, lon)`` of the target, or None when it could not be geolocated;
    ``position_note`` then says why (e.g. ``"telemetry stale (2.3 s)"``). ``error_m`` is the
    estimated horizontal error radius in metres. ``drone_position`` is ``(lat, lon, alt_m)`` of
    the aircraft at the frame's capture time, altitude above home. ``track`` holds the target's
    geolocated history ``(t, lat, lon)``; ``pixel_track`` its image history
    ``(frame_index, cx, cy)`` in full-resolution pixels. ``thumbnail`` is a JPEG crop of the raw
    frame around the target. ``delivered`` maps an acknowledged channel (e.g.
    ``"mavlink_loiter"``) to the POSIX time the autopilot accepted the command; ``refused``
    maps one to the autopilot's :class:`Refusal`; ``sent`` maps an unacknowledged channel
    (``"mavlink"``: STATUSTEXT) to its :class:`Sends`.
    """

    mission_id: str
    target_id: int
    class_name: str
    score: float
    lock_time: float
    frame_index: int
    position: tuple[float, float] | None = None
    position_note: str = ""
    error_m: float | None = None
    target_hae_m: float | None = None
    drone_position: tuple[float, float, float] | None = None
    track: list[tuple[float, float, float]] = field(default_factory=list)
    pixel_track: list[tuple[int, float, float]] = field(default_factory=list)
    thumbnail: bytes | None = None
    alert_id: str = field(default_factory=new_alert_id)
    ack_time: float | None = None
    ack_by: str | None = None
    delivered: dict[str, float] = field(default_factory=dict)
    refused: dict[str, Refusal] = field(default_factory=dict)
    sent: dict[str, Sends] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.position is not None:
            self.position = check_position(self.position)

    @property
    def acknowledged(self) -> bool:
        """True once an operator has acknowledged the alert."""
        return self.ack_time is not None

    @property
    def mavlink_sent(self) -> bool:
        """True once the STATUSTEXT alert has been sent at least once (whether it arrived is
        not known: STATUSTEXT has no acknowledgement)."""
        return CHANNEL_MAVLINK in self.sent

    @property
    def short_id(self) -> str:
        """Short id that starts the STATUSTEXT (e.g. ``T12-k3``): repeats and duplicates of
        one alert are recognisable on the ground station. See :func:`make_short_id`."""
        return make_short_id(self.target_id, self.alert_id)

    @property
    def cot_uid(self) -> str:
        """Cursor-on-Target uid: stable per target, so a re-sent event moves the same marker."""
        return f"sarmission.{self.mission_id}.target-{self.target_id}"

    def format_position(self, decimals: int = 5) -> str:
        """``"lat,lon"`` with ``decimals`` decimals (5 ≈ 1 m), or ``"pos unknown"``."""
        if self.position is None:
            return "pos unknown"
        lat, lon = self.position
        return f"{lat:.{decimals}f},{lon:.{decimals}f}"

    def format_error(self) -> str:
        """Error radius as ``"±4m"`` (whole metres, at least 1), or ``""`` when unknown."""
        if self.error_m is None or not math.isfinite(self.error_m):
            return ""
        return f"±{max(1, round(self.error_m))}m"

    def statustext(self) -> str:
        """One-line alert for MAVLink STATUSTEXT, at most 50 bytes in UTF-8, starting with the
        short id, e.g. ``T1-k3 SAR swimmer 0.91 -35.36291,149.16523 ±4m``. The class name is
        shortened if needed, and left out, then the error radius, if even that does not fit."""
        head = f"{self.short_id} SAR"
        tail = f" {self.score:.2f} {self.format_position()}"
        error = f" {self.format_error()}" if self.position is not None else ""
        if not error.strip():
            error = ""
        if len(head.encode()) + len((tail + error).encode()) > STATUSTEXT_MAX_BYTES:
            error = ""
        tail += error
        room = STATUSTEXT_MAX_BYTES - len(head.encode()) - 1 - len(tail.encode())
        name = self.class_name.encode()[: max(room, 0)].decode(errors="ignore").strip()
        text = f"{head} {name}{tail}" if name else f"{head}{tail}"
        return text.encode()[:STATUSTEXT_MAX_BYTES].decode(errors="ignore")

    def to_json_dict(self, thumbnail: ThumbnailMode = "url") -> dict[str, Any]:
        """A JSON-ready document. ``thumbnail``: ``"url"`` gives ``/thumb/<id>.jpg`` (the feed
        server's route), ``"base64"`` the JPEG itself, ``"omit"`` leaves it out; either way the
        value is None when there is no thumbnail. Coordinates keep full float precision."""
        doc: dict[str, Any] = {
            "alert_id": self.alert_id,
            "mission_id": self.mission_id,
            "target_id": self.target_id,
            "class_name": self.class_name,
            "score": self.score,
            "lock_time": self.lock_time,
            "lock_time_iso": utc_iso(self.lock_time),
            "frame_index": self.frame_index,
            "position": (
                None
                if self.position is None
                else {"lat": self.position[0], "lon": self.position[1]}
            ),
            "position_note": self.position_note,
            "error_m": self.error_m,
            "target_hae_m": self.target_hae_m,
            "drone_position": (
                None
                if self.drone_position is None
                else dict(zip(("lat", "lon", "alt_m"), self.drone_position, strict=True))
            ),
            "track": [list(p) for p in self.track],
            "pixel_track": [list(p) for p in self.pixel_track],
            "acknowledged": self.acknowledged,
            "ack_time": self.ack_time,
            "ack_by": self.ack_by,
            "delivered": dict(self.delivered),
            "refused": {
                ch: {"time": r.time, "result": r.result, "reason": r.reason}
                for ch, r in self.refused.items()
            },
            "sent": {
                ch: {"count": s.count, "first": s.first, "last": s.last}
                for ch, s in self.sent.items()
            },
            "short_id": self.short_id,
            "statustext": self.statustext(),
        }
        if thumbnail == "url":
            doc["thumbnail"] = f"/thumb/{self.alert_id}.jpg" if self.thumbnail else None
        elif thumbnail == "base64":
            doc["thumbnail"] = (
                base64.b64encode(self.thumbnail).decode("ascii") if self.thumbnail else None
            )
        return doc
