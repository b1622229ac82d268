"""MOT Challenge style text: one box per line, ``frame,id,x,y,w,h,conf,class,visibility``.

Frames are 1-based, boxes ``x, y, w, h`` in pixels (top-left corner). Lines with only the first
six or seven columns are accepted (``conf``, ``class`` and ``visibility`` then default to 1, -1
and 1); columns after the ninth are ignored. Blank lines are skipped.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from sarmission.data.coco_video import DatasetFormatError


@dataclass(frozen=True)
class MotRow:
    """One MOT line: a box of track ``track_id`` in 1-based ``frame``."""

    frame: int
    track_id: int
    bbox: tuple[float, float, float, float]
    conf: float = 1.0
    class_id: int = -1
    visibility: float = 1.0


def _integer(text: str) -> int:
    value = float(text)
    if not value.is_integer():
        raise ValueError(f"{text!r} is not an integer")
    return int(value)


def read_mot(path: str | Path) -> list[MotRow]:
    """Read a MOT text file; :class:`DatasetFormatError` names the file and line on bad input."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise DatasetFormatError(f"{path}: cannot read MOT file ({exc})") from exc
    rows = []
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        cols = [c.strip() for c in line.split(",")]
        if len(cols) < 6:
            raise DatasetFormatError(
                f"{path}:{number}: expected at least 6 comma-separated columns "
                f"(frame,id,x,y,w,h), got {len(cols)}"
            )
        try:
            frame = _integer(cols[0])
            row = MotRow(
                frame=frame,
                track_id=_integer(cols[1]),
                bbox=(float(cols[2]), float(cols[3]), float(cols[4]), float(cols[5])),
                conf=float(cols[6]) if len(cols) > 6 else 1.0,
                class_id=_integer(cols[7]) if len(cols) > 7 else -1,
                visibility=float(cols[8]) if len(cols) > 8 else 1.0,
            )
        except ValueError as exc:
            raise DatasetFormatError(f"{path}:{number}: bad value ({exc})") from exc
        if frame < 1:
            raise DatasetFormatError(f"{path}:{number}: frames are 1-based, got {frame}")
        rows.append(row)
    return rows


def _fmt(value: float) -> str:
    return repr(float(value)).removesuffix(".0") if float(value).is_integer() else repr(value)


def write_mot(rows: Iterable[MotRow], path: str | Path) -> None:
    """Write rows as MOT text (nine columns, shortest exact float text); read back identically."""
    with Path(path).open("w", encoding="utf-8") as out:
        for r in rows:
            out.write(
                ",".join(
                    [
                        str(r.frame),
                        str(r.track_id),
                        *map(_fmt, r.bbox),
                        _fmt(r.conf),
                        str(r.class_id),
                        _fmt(r.visibility),
                    ]
                )
                + "\n"
            )
