"""Cut a small piece out of an ArduPilot DataFlash log (.BIN), byte for byte.

Keeps every format message (FMT, FMTU, UNIT, MULT), the message types named (default: the ones
:mod:`sarmission.flightlog.dataflash` reads) inside a time window, and always ORGN and the
PARM entries named; each kept message is copied unchanged, so the cut is a valid log of the
same firmware. Used to make the test fixture from an ArduPilot SITL flight::

    python tools/cut_dataflash.py logs/00000001.BIN cut.BIN --start 70 --end 82
"""

from __future__ import annotations

import argparse
import struct
from pathlib import Path

HEAD = b"\xa3\x95"
FMT_ID = 128
FORMAT_TYPES = {"FMT", "FMTU", "UNIT", "MULT"}
DEFAULT_TYPES = ("GPS", "GPA", "ATT", "POS", "MNT", "CAM", "TRIG", "MSG", "MODE")
DEFAULT_PARAMS = ("MNT1_TYPE", "CAM1_TYPE")


def cut(data: bytes, start_s: float, end_s: float, types: set[str], params: set[str]) -> bytes:
    """The kept messages of ``data`` (see the module docstring), in their original order."""
    lengths = {FMT_ID: 89}
    names = {FMT_ID: "FMT"}
    out = bytearray()
    i = 0
    while i + 3 <= len(data):
        if data[i : i + 2] != HEAD:
            i += 1
            continue
        mid = data[i + 2]
        size = lengths.get(mid)
        if size is None or i + size > len(data):
            i += 1
            continue
        msg = data[i : i + size]
        if mid == FMT_ID:
            ftype, flen = msg[3], msg[4]
            lengths[ftype] = flen
            names[ftype] = msg[5:9].rstrip(b"\0").decode("ascii", "replace")
        name = names[mid]
        keep = name in FORMAT_TYPES or name == "ORGN"
        if name == "PARM":
            keep = msg[11:27].rstrip(b"\0").decode("ascii", "replace") in params
        elif name in types:
            (time_us,) = struct.unpack_from("<Q", msg, 3)
            keep = start_s <= time_us / 1e6 <= end_s
        if keep:
            out += msg
        i += size
    return bytes(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("src", type=Path)
    parser.add_argument("dst", type=Path)
    parser.add_argument("--start", type=float, required=True, help="window start (s of TimeUS)")
    parser.add_argument("--end", type=float, required=True, help="window end (s of TimeUS)")
    parser.add_argument("--types", default=",".join(DEFAULT_TYPES))
    parser.add_argument("--params", default=",".join(DEFAULT_PARAMS))
    args = parser.parse_args()
    piece = cut(
        args.src.read_bytes(),
        args.start,
        args.end,
        set(args.types.split(",")),
        set(args.params.split(",")),
    )
    args.dst.write_bytes(piece)
    print(f"wrote {args.dst} ({len(piece)} bytes)")


if __name__ == "__main__":
    main()
