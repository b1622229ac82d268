"""Which reader a telemetry file needs, from its content (the extension only breaks ties).

- ULog: starts with ``ULog`` and the magic ``01 12 35``;
- DataFlash binary: starts with the message header ``A3 95``; DataFlash text: ``FMT,``;
- tlog: an 8-byte microsecond timestamp (a plausible date) then a MAVLink start byte
  (``FE`` v1, ``FD`` v2);
- DJI SRT: text with a subtitle time line (``00:00:00,000 --> ...``);
- a folder of JPEGs: DJI EXIF/XMP.
"""

from __future__ import annotations

import re
import struct
from collections.abc import Callable
from pathlib import Path

from sarmission.flightlog.dji_srt import srt_text
from sarmission.flightlog.model import FlightLog, FlightLogError

_SRT_TIME = re.compile(rb"\d+:\d{2}:\d{2}[,.]\d{1,3}\s*-->")
_SRT_TIME_TEXT = re.compile(_SRT_TIME.pattern.decode())
#: Timestamps a tlog may start with: 2000-01-01 to 2100-01-01 in microseconds.
_TLOG_RANGE_US = (946_684_800 * 10**6, 4_102_444_800 * 10**6)


def sniff(path: str | Path) -> str:
    """The format name of ``path`` ("ulog", "dataflash", "tlog", "srt", "images"), or raise
    :class:`FlightLogError` saying what it is not."""
    path = Path(path)
    if path.is_dir():
        return "images"
    try:
        with path.open("rb") as f:
            head = f.read(4096)
    except OSError as exc:
        raise FlightLogError(f"{path}: cannot read telemetry file ({exc.strerror})") from exc
    if not head:
        raise FlightLogError(f"{path.name}: empty telemetry file")
    if head.startswith(b"ULog\x01\x12\x35"):
        return "ulog"
    if head.startswith(b"\xa3\x95"):
        return "dataflash"
    if head.startswith(b"FMT,") or head.startswith(b"FMT, "):
        return "dataflash"
    if len(head) >= 9 and head[8] in (0xFE, 0xFD):
        (stamp,) = struct.unpack(">Q", head[:8])
        if _TLOG_RANGE_US[0] <= stamp <= _TLOG_RANGE_US[1]:
            return "tlog"
    if _SRT_TIME.search(head) or _SRT_TIME_TEXT.search(srt_text(head[: len(head) & ~1])):
        return "srt"  # UTF-8, or UTF-16 with its byte-order mark (an even number of bytes)
    raise FlightLogError(
        f"{path.name}: not a flight log this program reads (tlog, DataFlash "
        ".bin/.log, PX4 .ulg, DJI .SRT or a folder of DJI JPEGs)"
    )


def readers() -> dict[str, Callable[[Path], FlightLog]]:
    """Format name -> reader (imported on use: each pulls in its library)."""
    from sarmission.flightlog.dataflash import read_dataflash
    from sarmission.flightlog.dji_images import read_dji_images
    from sarmission.flightlog.dji_srt import read_dji_srt
    from sarmission.flightlog.tlog import read_tlog
    from sarmission.flightlog.ulog import read_ulog

    return {
        "ulog": read_ulog,
        "dataflash": read_dataflash,
        "tlog": read_tlog,
        "srt": read_dji_srt,
        "images": read_dji_images,
    }


def open_flight_log(path: str | Path) -> FlightLog:
    """Read ``path`` with the reader its content calls for; :class:`FlightLogError` (one line)
    when it is not a flight log or gives no position."""
    path = Path(path)
    if not path.exists():
        raise FlightLogError(f"{path}: no such telemetry file")
    return readers()[sniff(path)](path)
