"""A dataset's per-frame telemetry read with the dataset's own conventions.

Datasets agree on key names less than on meaning. What differs, and how it is decided here:

- gimbal pitch sign. ``depression``: a positive angle below the horizon, 90 straight down
  (SeaDronesSee, v1 and v2 keys alike). ``elevation``: a signed angle, negative below the
  horizon, -90 straight down (DJI flight records, MAVLink, the geolocation's own frames). The
  same key (``gimbal_pitch(degrees)``) carries either, so the key does not decide: the file's
  ``info.meta_conventions.gimbal_pitch`` does, else an option, else the signs of all the file's
  pitches (all >= 0: depression; all <= 0: elevation). Both signs and nothing stated is a mixed
  file: :class:`ConventionError`, never a guess.
- altitude: height above take-off (``height_above_takeoff``, SeaDronesSee v1 ``altitude``).
- headings: degrees clockwise from north, ``compass_heading`` the aircraft's,
  ``gimbal_heading`` the camera's in the earth frame.

:func:`meta_pose` turns one frame into a :class:`MetaPose` in the geolocation's conventions, or a
:class:`NoMetaPose` whose ``reason`` is one line (missing field, pitch above the horizon, not in
the air ...): no position rather than a wrong one.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from sarmission.data.coco_video import FrameTelemetry, VideoDataset

DEPRESSION = "depression"
ELEVATION = "elevation"
PITCH_CONVENTIONS = (DEPRESSION, ELEVATION)
#: What each pitch convention means, for messages and ``--help``.
PITCH_MEANING = {
    DEPRESSION: "positive below the horizon, 90 straight down (SeaDronesSee)",
    ELEVATION: "negative below the horizon, -90 straight down (DJI logs, MAVLink)",
}
#: Key of the statement in a COCO file's ``info`` (``{"gimbal_pitch": "depression"}``).
INFO_KEY = "meta_conventions"


class ConventionError(ValueError):
    """A file's telemetry conventions cannot be told apart (or are stated wrongly)."""


@dataclass(frozen=True)
class MetaConventions:
    """How a file's ``meta`` is read. ``how``: where the convention came from, in words."""

    pitch: str
    how: str

    def describe(self) -> str:
        return f"gimbal pitch {PITCH_MEANING[self.pitch]}; {self.how}"


@dataclass(frozen=True)
class MetaPose:
    """One frame's camera placement in the geolocation's conventions.

    Degrees; ``height_m`` above take-off (> 0); ``gimbal_pitch_deg`` elevation (negative below
    the horizon); headings clockwise from north in [0, 360); ``gimbal_heading_deg`` is the
    camera's in the earth frame. ``notes``: what was filled in (e.g. the compass heading standing
    in for a missing gimbal heading).
    """

    latitude: float
    longitude: float
    height_m: float
    heading_deg: float
    gimbal_pitch_deg: float
    gimbal_heading_deg: float
    gimbal_roll_deg: float = 0.0
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class NoMetaPose:
    """A frame whose meta cannot place the camera; ``reason`` is one line."""

    reason: str


def _stated(info: Mapping[str, Any] | None) -> str | None:
    if not isinstance(info, Mapping):
        return None
    block = info.get(INFO_KEY)
    if block is None:
        return None
    value = block.get("gimbal_pitch") if isinstance(block, Mapping) else None
    if value not in PITCH_CONVENTIONS:
        raise ConventionError(
            f"info.{INFO_KEY}.gimbal_pitch must be one of "
            f"{', '.join(PITCH_CONVENTIONS)}, got {value!r}"
        )
    return str(value)


def detect_conventions(
    telemetry: Iterable[FrameTelemetry],
    info: Mapping[str, Any] | None = None,
    option: str | None = None,
) -> MetaConventions:
    """The conventions of one file's frames (see the module docstring for the order).

    ``option`` (``depression`` / ``elevation``, or None / ``auto``) is what the user stated; it
    must agree with a statement in ``info``. Raises :class:`ConventionError` for a mixed file.
    """
    if option not in (None, "auto", *PITCH_CONVENTIONS):
        raise ConventionError(
            f"gimbal pitch convention must be auto, "
            f"{' or '.join(PITCH_CONVENTIONS)}, got {option!r}"
        )
    stated = _stated(info)
    if option in PITCH_CONVENTIONS:
        if stated is not None and stated != option:
            raise ConventionError(
                f"the file states gimbal pitch as {stated}, the option as "
                f"{option}: mixed conventions"
            )
        return MetaConventions(str(option), "as stated by the option")
    if stated is not None:
        return MetaConventions(stated, f"as stated in the file's info.{INFO_KEY}")
    pitches = [m.gimbal_pitch for m in telemetry if m.gimbal_pitch is not None]
    positive = sum(1 for p in pitches if p > 0)
    negative = sum(1 for p in pitches if p < 0)
    if positive and negative:
        raise ConventionError(
            f"gimbal pitch has both signs ({positive} frames positive, {negative} negative): "
            f"mixed conventions; state one ({DEPRESSION}: {PITCH_MEANING[DEPRESSION]}; "
            f"{ELEVATION}: {PITCH_MEANING[ELEVATION]})"
        )
    if negative:
        return MetaConventions(ELEVATION, f"from the values: {negative} pitches, none positive")
    if positive:
        return MetaConventions(DEPRESSION, f"from the values: {positive} pitches, none negative")
    # No pitch, or only 0 (the horizon in both conventions): nothing to tell apart.
    return MetaConventions(
        ELEVATION, f"from the values: {len(pitches)} pitches, all 0 (the horizon either way)"
    )


def dataset_conventions(dataset: VideoDataset, option: str | None = None) -> MetaConventions:
    """The conventions of a whole annotation file (every image's meta, and its ``info``)."""
    return detect_conventions((im.telemetry for im in dataset.images), dataset.info, option)


def _heading(value: float) -> float:
    return value % 360.0


def meta_pose(meta: FrameTelemetry, conventions: MetaConventions) -> MetaPose | NoMetaPose:
    """One frame's placement with ``conventions``, or the reason it has none."""
    missing = [
        name
        for name, value in (
            ("latitude", meta.latitude),
            ("longitude", meta.longitude),
            ("height above take-off", meta.altitude),
            ("gimbal pitch", meta.gimbal_pitch),
        )
        if value is None
    ]
    if meta.compass_heading is None and meta.gimbal_heading is None:
        missing.append("heading")
    if missing:
        return NoMetaPose(f"meta lacks {', '.join(missing)}")
    assert meta.latitude is not None and meta.longitude is not None
    assert meta.altitude is not None and meta.gimbal_pitch is not None
    if not (-90.0 <= meta.latitude <= 90.0 and -180.0 <= meta.longitude <= 180.0):
        return NoMetaPose(f"position {meta.latitude}, {meta.longitude} out of range")
    if meta.latitude == 0.0 and meta.longitude == 0.0:
        return NoMetaPose("position 0, 0 (no GNSS fix)")
    if meta.altitude <= 0.0:
        return NoMetaPose(f"height above take-off {meta.altitude:g} m: not in the air")
    pitch = -meta.gimbal_pitch if conventions.pitch == DEPRESSION else meta.gimbal_pitch
    if not -90.0 <= pitch <= 90.0:
        return NoMetaPose(f"gimbal pitch {meta.gimbal_pitch:g} out of range ({conventions.pitch})")
    if pitch > 0.0:
        return NoMetaPose(
            f"gimbal pitch {meta.gimbal_pitch:g} ({conventions.pitch}) looks above the horizon"
        )
    notes: tuple[str, ...] = ()
    heading = meta.compass_heading if meta.compass_heading is not None else meta.gimbal_heading
    gimbal_heading = meta.gimbal_heading
    if gimbal_heading is None:
        gimbal_heading = heading
        notes = ("no gimbal heading: the compass heading stands in",)
    assert heading is not None and gimbal_heading is not None
    return MetaPose(
        meta.latitude,
        meta.longitude,
        meta.altitude,
        _heading(heading),
        pitch,
        _heading(gimbal_heading),
        meta.gimbal_roll or 0.0,
        notes,
    )
