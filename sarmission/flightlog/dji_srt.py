"""DJI subtitle sidecars (.SRT): per-frame position, height and gimbal angles of a DJI video.

An SRT is text: numbered blocks, each a ``start --> end`` time in the video
(``HH:MM:SS,mmm``) and lines of values. Two layouts are read:

- bracketed (Mavic 2/3, Air 2S, Mini 2/3/4, M30 ...): ``[latitude: 43.1] [longitude: 10.2]
  [rel_alt: 50.0 abs_alt: 120.0]`` (or ``[altitude: 50.0]``: some firmwares write it above
  sea level, so it is believed only up to :data:`MAX_BARE_HEIGHT_M`), gimbal as
  ``[gb_yaw: 90.1 gb_pitch: -90.0 gb_roll: 0.0]`` where the model writes it. Several
  firmwares (Mavic 2 Enterprise, Mini 2, Air 2S) spell it ``longtitude``, and older ones drop
  the colons (``[rel_alt 57.2 abs_alt 204.6]``): both are read;
- parenthesised (Phantom 4, Mavic Pro, Inspire): ``GPS(10.2,43.1,16)`` (longitude first!),
  ``BAROMETER:50.3`` or ``H 50.3m`` the height above take-off.

Clock: the video's own (a block's start time); no alignment is needed. Conventions: degrees;
``gb_pitch`` 0 at the horizon and -90 straight down, ``gb_yaw`` from north clockwise (the
earth frame), ``gb_roll`` right side down positive: the gimbal is taken in the earth frame.
Without gimbal angles the camera's pointing is unknown and no pixel is placed (positions
still draw the track). Home: the first position's ground (``abs_alt - rel_alt``).
A block without a time or a position is skipped and counted.
"""

from __future__ import annotations

import math
import re
from datetime import UTC, datetime
from pathlib import Path

from sarmission.flightlog.model import ACCURACY, FlightLog, FlightLogError, LogBuilder

#: Largest ``altitude`` (without ``rel_alt``) believed to be a height above take-off: drones
#: fly at most 120-150 m above the ground where they are flown legally; a larger one is a
#: height above sea level, which the file gives no take-off altitude to turn into a height.
MAX_BARE_HEIGHT_M = 150.0
_TIME = re.compile(r"(\d+):(\d{2}):(\d{2})[,.](\d{1,3})\s*-->")
_NUM = r"([-+]?\d+(?:\.\d+)?)"


def _field(text: str, *names: str) -> float | None:
    for name in names:
        m = re.search(rf"\b{name}\s*[:=]?\s*{_NUM}", text)
        if m:
            return float(m.group(1))
    return None


def _seconds(m: re.Match[str]) -> float:
    h, mi, s, ms = m.groups()
    return int(h) * 3600 + int(mi) * 60 + int(s) + int(ms.ljust(3, "0")) / 1000.0


def _values(text: str) -> dict[str, float | None]:
    gps = re.search(rf"GPS\s*\(\s*{_NUM}\s*,\s*{_NUM}\s*,\s*{_NUM}\s*\)", text)
    if gps:  # GPS(lon, lat, satellites or altitude)
        lon, lat = float(gps.group(1)), float(gps.group(2))
    else:
        lat, lon = _field(text, "latitude"), _field(text, "longitude", "longtitude")
    height = _field(text, "rel_alt", "BAROMETER")
    if height is None:
        m = re.search(rf"\bH\s*{_NUM}\s*m", text)
        height = float(m.group(1)) if m else None
    bare = _field(text, "altitude") if height is None else None
    return {
        "lat": lat,
        "lon": lon,
        "rel_alt": height if bare is None else bare,
        "bare_altitude": bare,
        "abs_alt": _field(text, "abs_alt"),
        "gb_yaw": _field(text, "gb_yaw"),
        "gb_pitch": _field(text, "gb_pitch"),
        "gb_roll": _field(text, "gb_roll"),
    }


_DATE = re.compile(r"(\d{4})-(\d{2})-(\d{2})[ T](\d{2}):(\d{2}):(\d{2})")


def _stated_posix(block: str) -> float | None:
    """The block's date line (``2024-05-01 12:00:00.000``, the drone's clock) as POSIX
    seconds read as UTC; None without one."""
    m = _DATE.search(block)
    if m is None:
        return None
    try:
        when = datetime(*(int(g) for g in m.groups()), tzinfo=UTC)
    except ValueError:
        return None
    return when.timestamp()


def srt_text(raw: bytes) -> str:
    """An SRT's text: UTF-16 where it starts with that byte-order mark (Windows editors save
    it so), else UTF-8 (a bad byte replaced); line ends as ``\n``."""
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        text = raw.decode("utf-16", errors="replace")
    else:
        text = raw.decode("utf-8", errors="replace")
    return text.replace("\ufeff", "").replace("\r\n", "\n").replace("\r", "\n")


def read_dji_srt(path: str | Path) -> FlightLog:
    """Read a DJI SRT (see the module docstring)."""
    path = Path(path)
    try:
        text = srt_text(path.read_bytes())
    except OSError as exc:
        raise FlightLogError(f"{path.name}: cannot read ({exc.strerror})") from exc
    builder = LogBuilder(
        "DJI SRT",
        path,
        "the video's own time",
        ACCURACY["dji"],
        home_note="home altitude from the first block (abs_alt - rel_alt)",
    )
    log = builder.log
    log.per_frame = True
    # a block runs from its time line to the next one: editors and converters drop the blank
    # lines between blocks (or write CR-only line ends), which once left one block
    starts = [m.start() for m in _TIME.finditer(text)]
    blocks = [text[a:b] for a, b in zip(starts, [*starts[1:], len(text)], strict=True)]
    missing = 0
    bare_heights: list[float] = []
    for block in blocks:
        if not block.strip():
            continue
        m = _TIME.search(block)
        if m is None:
            missing += 1
            continue
        v = _values(block)
        if v["lat"] is None or v["lon"] is None or v["rel_alt"] is None:
            missing += 1
            continue
        t = _seconds(m)
        if log.stated_start_posix is None and (stated := _stated_posix(block)) is not None:
            log.stated_start_posix = stated - t
        if v["bare_altitude"] is not None:
            bare_heights.append(v["bare_altitude"])
        abs_alt = v["abs_alt"] if v["abs_alt"] is not None else math.nan
        if not builder.position(t, v["lat"], v["lon"], v["rel_alt"], abs_alt):
            continue
        if v["gb_pitch"] is not None and v["gb_yaw"] is not None:
            yaw = math.radians(v["gb_yaw"])
            builder.attitude_euler(t, 0.0, 0.0, yaw)  # vehicle yaw unknown; earth-frame gimbal
            builder.gimbal_euler(
                t, math.radians(v["gb_roll"] or 0.0), math.radians(v["gb_pitch"]), yaw, "earth"
            )
    if bare_heights and max(bare_heights) > MAX_BARE_HEIGHT_M:
        raise FlightLogError(
            f"{path.name}: heights given as 'altitude' (no rel_alt) reach "
            f"{max(bare_heights):.0f} m: above sea level on this model, not above take-off, "
            "and the file has no height above take-off; no position from it"
        )
    if bare_heights:
        log.notes.append(
            f"{path.name}: heights given as 'altitude' (no rel_alt) taken as above take-off "
            f"(at most {max(bare_heights):.0f} m); some firmwares write it above sea level, "
            "which misplaces every alert inland"
        )
    if missing:
        log.rejected["subtitle block without a time or position"] += missing
        log.notes.append(
            f"{path.name}: {missing} subtitle blocks without a time or a position skipped"
        )
    if log.positions and not log.gimbal:
        log.notes.append(
            f"{path.name}: no gimbal angles (gb_pitch, gb_yaw): the camera's "
            "pointing is unknown, so no alert gets a position"
        )
    return builder.build()
