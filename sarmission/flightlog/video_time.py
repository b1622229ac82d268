"""When a video was recorded: the ``creation_time`` of an MP4/MOV movie header (``mvhd``).

ISO base media files (MP4, MOV) hold boxes of ``size (4 bytes) + type (4)``; ``moov/mvhd``
gives ``creation_time`` in seconds since 1904-01-01 UTC (32-bit in version 0, 64-bit in
version 1). Cameras write the start of the recording there, DJI and many others on their own
clock (which may be local time). 0 means unknown. :func:`set_creation_time` writes it in
place (the simulator uses it to stamp a rendered clip).
"""

from __future__ import annotations

import struct
from pathlib import Path

#: Seconds from 1904-01-01 to 1970-01-01.
MP4_EPOCH_OFFSET = 2_082_844_800
_CONTAINERS = {b"moov"}


def _find_mvhd(data: bytes) -> int | None:
    """Offset of the ``mvhd`` payload (after size and type), None if absent."""

    def walk(start: int, end: int) -> int | None:
        i = start
        while i + 8 <= end:
            size, kind = struct.unpack_from(">I4s", data, i)
            header = 8
            if size == 1 and i + 16 <= end:
                size = struct.unpack_from(">Q", data, i + 8)[0]
                header = 16
            elif size == 0:
                size = end - i
            if size < header or i + size > end:
                return None
            if kind == b"mvhd":
                return i + header
            if kind in _CONTAINERS:
                found = walk(i + header, i + size)
                if found is not None:
                    return found
            i += size
        return None

    return walk(0, len(data))


def creation_time(path: str | Path) -> float | None:
    """POSIX seconds of the movie's ``creation_time``; None when absent, zero or unreadable."""
    try:
        data = Path(path).read_bytes()
    except OSError:
        return None
    at = _find_mvhd(data)
    if at is None or at + 12 > len(data):
        return None
    version = data[at]
    if version == 1 and at + 12 <= len(data):
        value = struct.unpack_from(">Q", data, at + 4)[0]
    else:
        value = struct.unpack_from(">I", data, at + 4)[0]
    return float(value - MP4_EPOCH_OFFSET) if value else None


def set_creation_time(path: str | Path, posix_s: float) -> None:
    """Write ``creation_time`` (and ``modification_time``) of the movie header in place."""
    path = Path(path)
    data = bytearray(path.read_bytes())
    at = _find_mvhd(bytes(data))
    if at is None:
        raise ValueError(f"{path}: no movie header (mvhd)")
    value = int(round(posix_s)) + MP4_EPOCH_OFFSET
    if data[at] == 1:
        struct.pack_into(">QQ", data, at + 4, value, value)
    else:
        struct.pack_into(">II", data, at + 4, value, value)
    path.write_bytes(bytes(data))
