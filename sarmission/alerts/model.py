"""The alert: one target, as the operator and the autopilot are told about it.

An alert has a *tier*. A frame-level lock makes a ``candidate``: shown to the operator
("unconfirmed") but never sent to the autopilot or the team. Evidence over seconds in the world
frame makes it ``confirmed`` (:attr:`Alert.evidence` says why); the system may instead give up on
a candidate (:attr:`Alert.discarded` says why). Independently, an operator may confirm or dismiss
any alert (:attr:`Alert.decision`, with who and when); an operator's confirmation also confirms a
candidate, and a dismissed position suppresses new alerts around it (:func:`dismiss_radius_m`).

An :class:`Alert` is created once per locked target and never changes afterwards except for its
tier and decision, its acknowledgement, what is known of its way to the autopilot, and its
position: attached once found for a target that could not be geolocated when it was locked,
and refined as its target's fixes come in (:mod:`sarmission.mission.refinement`); the store
keeps these.

What is known differs by channel. A command (DO_REPOSITION, ROI, mission upload) is answered by
the autopilot: it is *delivered* when accepted, *refused* (with the autopilot's result and reason)
otherwise. A STATUSTEXT has no acknowledgement in MAVLink: all that is known is that it was *sent*
n times, so it is sent several times and never called delivered (:data:`UNACKNOWLEDGED_CHANNELS`);
so is a Cursor-on-Target event to the team's TAK (:data:`CHANNEL_COT`).
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

from sarmission.alerts.operator_calibration import check_logit
from sarmission.class_roles import short_label

#: STATUSTEXT's ``text`` field holds 50 bytes.
STATUSTEXT_MAX_BYTES = 50

#: Delivery channel name for the MAVLink STATUSTEXT alert.
CHANNEL_MAVLINK = "mavlink"

#: Delivery channel name for the team's Cursor-on-Target events (TAK).
CHANNEL_COT = "cot"

#: Channels without an acknowledgement: only how often the alert was sent is known.
UNACKNOWLEDGED_CHANNELS = frozenset({CHANNEL_MAVLINK, CHANNEL_COT})

#: Alphabet of the short id's suffix: lower-case letters and digits that are not mistaken for
#: one another on a ground station's screen (no 0/o, 1/l/i).
_SHORT_ALPHABET = "23456789abcdefghjkmnpqrstuvwxyz"

ThumbnailMode = Literal["url", "base64", "omit"]

#: ``candidate``: a frame-level lock, for the operator only; ``confirmed``: evidence over
#: seconds in the world frame (or an operator's confirmation), for the autopilot and the team.
Tier = Literal["candidate", "confirmed"]
TIERS: tuple[Tier, ...] = ("candidate", "confirmed")
#: What an operator decided about an alert.
Decision = Literal["confirmed", "dismissed"]
DECISIONS: tuple[Decision, ...] = ("confirmed", "dismissed")

#: Smallest radius (m) a dismissed position suppresses, and the radius used when the dismissed
#: alert's error is unknown.
DISMISS_MIN_RADIUS_M = 10.0
DISMISS_UNKNOWN_RADIUS_M = 25.0


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


#: Fastest drift an alert may carry (m/s): beyond what any person or current moves.
MAX_DRIFT_M_S = 10.0


def check_drift(drift_ne: tuple[float, float]) -> tuple[float, float]:
    """``(north, east)`` m/s as floats; ValueError unless both are finite and no faster than
    :data:`MAX_DRIFT_M_S`."""
    north, east = (float(v) for v in drift_ne)
    if not (math.isfinite(north) and math.isfinite(east)):
        raise ValueError(f"alert drift must be finite, got {drift_ne}")
    if math.hypot(north, east) > MAX_DRIFT_M_S:
        raise ValueError(f"alert drift faster than {MAX_DRIFT_M_S} m/s: {drift_ne}")
    return north, east


def check_confidence(confidence: float | None) -> float | None:
    """A probability as a float (None stays None); ValueError unless it lies in [0, 1]."""
    if confidence is None:
        return None
    value = float(confidence)
    if not 0.0 <= value <= 1.0:  # also refuses NaN
        raise ValueError(f"alert confidence must lie in [0, 1], got {confidence}")
    return value


def confidence_percent(confidence: float) -> int:
    """A probability in whole percent, at least 1 and at most 99: the model is never sure."""
    return min(99, max(1, round(100 * confidence)))


#: A confidence whose range is at least this wide is shown with its range: one number would
#: claim more than is known (:mod:`sarmission.alerts.operator_calibration`).
WIDE_RANGE = 0.2


def check_confidence_range(
    confidence_range: tuple[float, float] | None, confidence: float | None
) -> tuple[float, float] | None:
    """A confidence's range as floats (None stays None); ValueError unless both ends lie in
    [0, 1] around ``confidence``, which it needs."""
    if confidence_range is None:
        return None
    low, high = (float(v) for v in confidence_range)
    if confidence is None or not 0.0 <= low <= confidence <= high <= 1.0:
        raise ValueError(
            f"confidence range must lie in [0, 1] around the confidence {confidence}, "
            f"got {confidence_range}"
        )
    return low, high


def is_wide(confidence_range: tuple[float, float] | None) -> bool:
    """Whether a confidence's range is too wide to show it as one number."""
    return confidence_range is not None and (
        confidence_range[1] - confidence_range[0] >= WIDE_RANGE
    )


def format_confidence(
    confidence: float | None, confidence_range: tuple[float, float] | None = None
) -> str:
    """``"35 % likely a person"``, with its range when wide (``"35 % likely a person, between
    4 and 75 %"``), or ``""`` when unknown."""
    if confidence is None:
        return ""
    text = f"{confidence_percent(confidence)} % likely a person"
    if is_wide(confidence_range):
        low, high = (confidence_percent(v) for v in confidence_range)
        text += f", between {low} and {high} %"
    return text


def short_confidence(confidence: float, confidence_range: tuple[float, float] | None = None) -> str:
    """The confidence for a short line: ``"35%"``, or its range when wide (``"4-75%"``)."""
    if is_wide(confidence_range):
        low, high = (confidence_percent(v) for v in confidence_range)
        return f"{low}-{high}%"
    return f"{confidence_percent(confidence)}%"


def drift_course_speed(drift_ne: tuple[float, float]) -> tuple[float, float]:
    """A drift (m/s north, east) as (course in degrees from true north, 0-360; speed m/s)."""
    north, east = drift_ne
    return math.degrees(math.atan2(east, north)) % 360.0, math.hypot(north, east)


def dismiss_radius_m(error_m: float | None) -> float:
    """Radius (m) around a dismissed alert's position in which new alerts are suppressed:
    twice its error radius (about 2 sigma: the same thing seen again lands inside), at least
    :data:`DISMISS_MIN_RADIUS_M`; :data:`DISMISS_UNKNOWN_RADIUS_M` when the error is unknown."""
    if error_m is None or not math.isfinite(error_m) or error_m < 0:
        return DISMISS_UNKNOWN_RADIUS_M
    return max(2.0 * float(error_m), DISMISS_MIN_RADIUS_M)


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
    """A located (or locked but not yet located) target.

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

    ``tier`` is ``"candidate"`` or ``"confirmed"`` (the default, which is what every alert was
    before there were tiers); ``evidence`` is the controller's short line on why it was confirmed
    or discarded; ``confirmed_at`` when a candidate became confirmed (None for an alert stored
    confirmed: its ``lock_time`` is then the time); ``discarded`` the reason the system gave up
    on a candidate, at ``discarded_at``. ``decision`` is the operator's (``"confirmed"`` or
    ``"dismissed"``, the newest one counts), made by ``decided_by`` at ``decided_at`` (the
    store's clock).
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
    tier: Tier = "confirmed"
    evidence: str = ""
    confirmed_at: float | None = None
    discarded: str | None = None
    discarded_at: float | None = None
    decision: Decision | None = None
    decided_by: str | None = None
    decided_at: float | None = None
    #: POSIX time of the latest fix the position rests on (None: the lock's, or no position);
    #: a drifting swimmer's position is as old as this
    position_time: float | None = None
    #: The target's drift as of ``position_time``, m/s (north, east): (0, 0) when its fixes
    #: showed it still, None when not estimated (a single fix, or an older store)
    drift_ne: tuple[float, float] | None = None
    #: The calibrated probability, when it was confirmed, that a person is there
    #: (:mod:`sarmission.mission.confidence`); None: unknown (no model for the head, an
    #: operator's confirmation, a candidate, an older store). ``score`` is the head's raw score.
    confidence: float | None = None
    #: The range of ``confidence`` (its central 80 %) given what the mission's operator
    #: decisions have taught so far; None: no such range (a model without a mission's
    #: calibration, or unknown)
    confidence_range: tuple[float, float] | None = None
    #: The log-odds of a person that the confidence model read from the evidence alone, before
    #: the mission's calibration; None: no model
    evidence_logit: float | None = None

    def __post_init__(self) -> None:
        if self.position is not None:
            self.position = check_position(self.position)
        if self.drift_ne is not None:
            self.drift_ne = check_drift(self.drift_ne)
        self.confidence = check_confidence(self.confidence)
        self.confidence_range = check_confidence_range(self.confidence_range, self.confidence)
        if self.evidence_logit is not None:
            self.evidence_logit = check_logit(self.evidence_logit)
        if self.tier not in TIERS:
            raise ValueError(f"alert tier must be one of {TIERS}, got {self.tier!r}")
        if self.decision is not None and self.decision not in DECISIONS:
            raise ValueError(f"operator decision must be one of {DECISIONS}, got {self.decision!r}")

    @property
    def dismissed(self) -> bool:
        """True when an operator's newest decision is that this is no person."""
        return self.decision == "dismissed"

    @property
    def awaiting_review(self) -> bool:
        """A candidate nobody has decided on yet and the system has not given up on."""
        return self.tier == "candidate" and self.discarded is None and self.decision is None

    @property
    def dismiss_radius_m(self) -> float:
        """Radius (m) this alert's position suppresses once dismissed (:func:`dismiss_radius_m`)."""
        return dismiss_radius_m(self.error_m)

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

    def drift_json(self) -> dict[str, float] | None:
        """The drift for JSON: m/s north and east, speed and course (degrees from true north;
        0 for a target taken as still), or None when not estimated."""
        if self.drift_ne is None:
            return None
        course, speed = drift_course_speed(self.drift_ne)
        return {
            "north_m_s": self.drift_ne[0],
            "east_m_s": self.drift_ne[1],
            "speed_m_s": speed,
            "course_deg": course,
        }

    def format_drift(self) -> str:
        """``"drifting 0.4 m/s to 045°"``, ``"still"``, or ``""`` when not estimated."""
        if self.drift_ne is None:
            return ""
        course, speed = drift_course_speed(self.drift_ne)
        if speed == 0.0:
            return "still"
        return f"drifting {speed:.1f} m/s to {round(course) % 360:03d}°"

    def format_confidence(self) -> str:
        """``"35 % likely a person"`` (with its range when wide), or ``""`` when unknown
        (:func:`format_confidence`)."""
        return format_confidence(self.confidence, self.confidence_range)

    def format_score(self) -> str:
        """The head's score with the calibrated confidence when known:
        ``"0.86 (35 % likely a person)"``, else ``"0.86"``."""
        if self.confidence is None:
            return f"{self.score:.2f}"
        return f"{self.score:.2f} ({self.format_confidence()})"

    def statustext(self) -> str:
        """One-line alert for MAVLink STATUSTEXT, at most 50 bytes in UTF-8, starting with the
        short id, e.g. ``T1-k3 SAR swimmer 0.91 -35.36291,149.16523 ±4m``: the head's score, or
        with a calibrated confidence that instead as a percentage (``swimmer 35%``, or its range
        ``swimmer 4-75%`` while that is wide). The class
        name is shortened if needed, and left out, then the error radius, if even that does not
        fit."""
        head = f"{self.short_id} SAR"
        likely = (
            f"{self.score:.2f}"
            if self.confidence is None
            else short_confidence(self.confidence, self.confidence_range)
        )
        tail = f" {likely} {self.format_position()}"
        error = f" {self.format_error()}" if self.position is not None else ""
        if not error.strip():
            error = ""
        if len(head.encode()) + len((tail + error).encode()) > STATUSTEXT_MAX_BYTES:
            error = ""
        tail += error
        room = STATUSTEXT_MAX_BYTES - len(head.encode()) - 1 - len(tail.encode())
        label = short_label(self.class_name).encode()
        name = label[: max(room, 0)].decode(errors="ignore").strip()
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
            "confidence": self.confidence,
            "confidence_range": (
                None if self.confidence_range is None else list(self.confidence_range)
            ),
            "evidence_logit": self.evidence_logit,
            "lock_time": self.lock_time,
            "lock_time_iso": utc_iso(self.lock_time),
            "frame_index": self.frame_index,
            "position": (
                None
                if self.position is None
                else {"lat": self.position[0], "lon": self.position[1]}
            ),
            "position_note": self.position_note,
            "position_time": self.position_time,
            "drift": self.drift_json(),
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
            "tier": self.tier,
            "evidence": self.evidence,
            "confirmed_at": self.confirmed_at,
            "discarded": self.discarded,
            "discarded_at": self.discarded_at,
            "decision": self.decision,
            "decided_by": self.decided_by,
            "decided_at": self.decided_at,
            "dismiss_radius_m": self.dismiss_radius_m,
        }
        if thumbnail == "url":
            doc["thumbnail"] = f"/thumb/{self.alert_id}.jpg" if self.thumbnail else None
        elif thumbnail == "base64":
            doc["thumbnail"] = (
                base64.b64encode(self.thumbnail).decode("ascii") if self.thumbnail else None
            )
        return doc
