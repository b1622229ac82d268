"""DJI still images (JPEG): position from EXIF GPS, height and angles from DJI's XMP, per image.

EXIF (read with exifread): ``GPSLatitude``/``GPSLongitude`` with their N/S, E/W references,
``DateTimeOriginal`` (+ ``SubSecTimeOriginal``) the capture time on the camera's clock. XMP
(text in the JPEG's APP1 segment, ``drone-dji:`` namespace, attributes or elements):
``RelativeAltitude`` (m above take-off; needed: EXIF's altitude is not above the ground),
``AbsoluteAltitude``, ``GimbalPitchDegree`` (0 at the horizon, -90 straight down),
``GimbalYawDegree`` (from north clockwise: the earth frame), ``GimbalRollDegree``,
``FlightYawDegree``/``FlightPitchDegree``/``FlightRollDegree`` (the aircraft, ZYX, pitch up
positive), and ``GpsLatitude``/``GpsLongitude`` (also spelt ``GpsLongtitude``) where EXIF
has no GPS.

Clock: capture times in seconds when every placed image has one (made strictly increasing
by a millisecond where two share a time), else the images' order one second apart.
:attr:`FlightLog.image_times` maps each placed image's file name to its time; an image
without a position is counted and gets none.
"""

from __future__ import annotations

import math
import re
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from sarmission.flightlog.model import ACCURACY, FlightLog, FlightLogError, LogBuilder

JPEG_EXTENSIONS = {".jpg", ".jpeg"}
#: Bytes searched for the XMP packet (DJI writes it near the start).
XMP_SEARCH_BYTES = 512 * 1024


def _natural_key(path: Path) -> list[object]:
    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", path.name)]


def xmp_values(data: bytes) -> dict[str, str]:
    """``drone-dji:`` fields of the XMP packet in ``data`` (attributes or elements)."""
    start = data.find(b"<x:xmpmeta")
    end = data.find(b"</x:xmpmeta>", start)
    if start < 0 or end < 0:
        return {}
    text = data[start:end].decode("utf-8", errors="replace")
    values = dict(re.findall(r'drone-dji:(\w+)\s*=\s*"([^"]*)"', text))
    values.update(re.findall(r"<drone-dji:(\w+)>([^<]*)</drone-dji:\1>", text))
    return values


def _float(values: dict[str, str], *names: str) -> float | None:
    for name in names:
        if name in values:
            try:
                v = float(values[name])
            except ValueError:
                continue
            if math.isfinite(v):
                return v
    return None


def _ratio(value: Any) -> float:
    return float(value.num) / float(value.den) if value.den else math.nan


def _exif_gps(tags: dict[str, Any]) -> tuple[float, float] | None:
    try:
        lat_v, lon_v = tags["GPS GPSLatitude"].values, tags["GPS GPSLongitude"].values
        lat = sum(_ratio(v) / 60**k for k, v in enumerate(lat_v))
        lon = sum(_ratio(v) / 60**k for k, v in enumerate(lon_v))
    except (KeyError, AttributeError, ZeroDivisionError, TypeError):
        return None
    if str(tags.get("GPS GPSLatitudeRef", "N")).strip().upper().startswith("S"):
        lat = -lat
    if str(tags.get("GPS GPSLongitudeRef", "E")).strip().upper().startswith("W"):
        lon = -lon
    return lat, lon


def _capture_time(tags: dict[str, Any]) -> float | None:
    raw = str(tags.get("EXIF DateTimeOriginal", "")).strip()
    try:
        when = datetime.strptime(raw, "%Y:%m:%d %H:%M:%S").replace(tzinfo=UTC)
    except ValueError:
        return None
    sub = str(tags.get("EXIF SubSecTimeOriginal", "")).strip()
    frac = float(f"0.{sub}") if sub.isdigit() else 0.0
    return when.timestamp() + frac


def read_image(path: Path) -> dict[str, Any] | None:
    """What one JPEG says (keys lat, lon, rel_alt, abs_alt, time, gimbal and flight angles),
    or None when it cannot be read."""
    import exifread

    try:
        data = path.read_bytes()
    except OSError:
        return None
    import io

    try:
        tags = exifread.process_file(io.BytesIO(data), details=False)
    except Exception:  # noqa: BLE001 - exifread raises anything on a corrupt image
        tags = {}
    xmp = xmp_values(data[:XMP_SEARCH_BYTES])
    where = _exif_gps(tags)
    if where is None:
        lat, lon = _float(xmp, "GpsLatitude"), _float(xmp, "GpsLongitude", "GpsLongtitude")
        where = (lat, lon) if lat is not None and lon is not None else None
    return {
        "where": where,
        "rel_alt": _float(xmp, "RelativeAltitude"),
        "abs_alt": _float(xmp, "AbsoluteAltitude"),
        "time": _capture_time(tags),
        "gimbal": tuple(_float(xmp, f"Gimbal{a}Degree") for a in ("Roll", "Pitch", "Yaw")),
        "flight": tuple(_float(xmp, f"Flight{a}Degree") for a in ("Roll", "Pitch", "Yaw")),
        "exif": bool(tags) or bool(xmp),
    }


def read_dji_images(folder: str | Path) -> FlightLog:
    """Read every JPEG of ``folder`` (see the module docstring)."""
    folder = Path(folder)
    files = (
        sorted(
            (p for p in folder.iterdir() if p.suffix.lower() in JPEG_EXTENSIONS), key=_natural_key
        )
        if folder.is_dir()
        else []
    )
    builder = LogBuilder(
        "DJI image EXIF/XMP",
        folder,
        "capture time (DateTimeOriginal)",
        ACCURACY["dji"],
        home_note="home altitude from the first image (AbsoluteAltitude - RelativeAltitude)",
    )
    log = builder.log
    placed: list[tuple[str, dict[str, Any]]] = []
    no_meta = no_position = 0
    for path in files:
        info = read_image(path)
        if info is None or not info["exif"]:
            no_meta += 1
        elif info["where"] is None or info["rel_alt"] is None:
            no_position += 1
        else:
            placed.append((path.name, info))
    if not placed:
        raise FlightLogError(
            f"{folder.name}: no JPEG with EXIF GPS and DJI RelativeAltitude "
            f"({len(files)} JPEGs, {no_meta} without EXIF): no positions"
        )
    if all(info["time"] is not None for _, info in placed):
        times = [info["time"] for _, info in placed]
    else:
        times = [float(k) for k in range(len(placed))]
        log.clock = "image order, 1 s apart (capture times missing)"
    previous = -math.inf
    for (name, info), t in zip(placed, times, strict=True):
        t = max(t, previous + 1e-3)
        previous = t
        _add(builder, name, info, t)
    for count, what in (
        (no_meta, "without EXIF"),
        (no_position, "without GPS or RelativeAltitude"),
    ):
        if count:
            log.rejected[f"image {what}"] += count
            log.notes.append(
                f"{folder.name}: {count} of {len(files)} images {what}: no position for them"
            )
    return builder.build()


def _add(builder: LogBuilder, name: str, info: dict[str, Any], t: float) -> None:
    log = builder.log
    lat, lon = info["where"]
    abs_alt = info["abs_alt"] if info["abs_alt"] is not None else math.nan
    if not builder.position(t, lat, lon, info["rel_alt"], abs_alt):
        return
    log.image_times[name] = t
    g_roll, g_pitch, g_yaw = info["gimbal"]
    f_roll, f_pitch, f_yaw = info["flight"]
    if g_pitch is None or g_yaw is None:
        return
    if f_yaw is not None:
        builder.attitude_euler(
            t, math.radians(f_roll or 0.0), math.radians(f_pitch or 0.0), math.radians(f_yaw)
        )
    else:
        builder.attitude_euler(t, 0.0, 0.0, math.radians(g_yaw))
    builder.gimbal_euler(
        t, math.radians(g_roll or 0.0), math.radians(g_pitch), math.radians(g_yaw), "earth"
    )
