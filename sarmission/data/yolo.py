"""YOLO text labels: one file per image, one line ``class cx cy w h`` per box, normalised to [0, 1]
by the image width and height. An optional sixth column (a score, as detectors write) is kept.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sarmission.boxes import cxcywh_to_xyxy, xyxy_to_cxcywh
from sarmission.data.coco_video import DatasetFormatError


@dataclass(frozen=True)
class YoloBox:
    """One label line: class and normalised centre/size; ``score`` only for detector output."""

    class_id: int
    cx: float
    cy: float
    w: float
    h: float
    score: float | None = None


def read_yolo(path: str | Path) -> list[YoloBox]:
    """Read one YOLO label file (a missing file is an error; an empty file has no boxes)."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise DatasetFormatError(f"{path}: cannot read YOLO label file ({exc})") from exc
    boxes = []
    for number, line in enumerate(lines, start=1):
        cols = line.split()
        if not cols:
            continue
        if len(cols) not in (5, 6):
            raise DatasetFormatError(
                f"{path}:{number}: expected 'class cx cy w h [score]', got {len(cols)} columns"
            )
        try:
            class_value = float(cols[0])
            if not class_value.is_integer():
                raise ValueError(f"class {cols[0]!r} is not an integer")
            cx, cy, w, h = (float(c) for c in cols[1:5])
            score = float(cols[5]) if len(cols) == 6 else None
        except ValueError as exc:
            raise DatasetFormatError(f"{path}:{number}: bad value ({exc})") from exc
        boxes.append(YoloBox(int(class_value), cx, cy, w, h, score))
    return boxes


def write_yolo(boxes: Iterable[YoloBox], path: str | Path) -> None:
    """Write one YOLO label file (exact float text, so it reads back identically)."""
    with Path(path).open("w", encoding="utf-8") as out:
        for b in boxes:
            cols = [str(b.class_id), *(repr(float(v)) for v in (b.cx, b.cy, b.w, b.h))]
            if b.score is not None:
                cols.append(repr(float(b.score)))
            out.write(" ".join(cols) + "\n")


def yolo_to_xyxy(
    boxes: Sequence[YoloBox], width: int, height: int
) -> tuple[np.ndarray, np.ndarray]:
    """Pixel corner boxes ``[N, 4]`` and class ids ``[N]`` for a ``width`` x ``height`` image."""
    norm = np.array([[b.cx, b.cy, b.w, b.h] for b in boxes], dtype=np.float64).reshape(-1, 4)
    scaled = norm * np.array([width, height, width, height], dtype=np.float64)
    return cxcywh_to_xyxy(scaled), np.array([b.class_id for b in boxes], dtype=np.int64)


def xyxy_to_yolo(
    boxes_xyxy: np.ndarray, class_ids: Sequence[int], width: int, height: int
) -> list[YoloBox]:
    """YOLO boxes from pixel corner boxes ``[N, 4]`` of a ``width`` x ``height`` image."""
    cxcywh = xyxy_to_cxcywh(np.asarray(boxes_xyxy, dtype=np.float64).reshape(-1, 4))
    norm = cxcywh / np.array([width, height, width, height], dtype=np.float64)
    return [
        YoloBox(int(c), *(float(v) for v in row)) for c, row in zip(class_ids, norm, strict=True)
    ]
