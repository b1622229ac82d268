"""COCO-style detection results: one record per detection, as written by ``sarmission detect``.

Record: ``{"image_id": int, "frame_index": int, "bbox": [x, y, w, h], "score": float,
"category_id": int}``; ``category_id`` is the head's class index + 1 (COCO ids start at 1).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from sarmission.boxes import xyxy_to_xywh
from sarmission.perception.types import Detections


def detections_to_coco(detections: Detections, image_id: int, frame_index: int) -> list[dict]:
    """Turn one frame's detections into COCO result records."""
    xywh = xyxy_to_xywh(detections.boxes) if len(detections) else np.zeros((0, 4))
    return [
        {
            "image_id": int(image_id),
            "frame_index": int(frame_index),
            "bbox": [round(float(v), 2) for v in box],
            "score": round(float(score), 5),
            "category_id": int(class_id) + 1,
        }
        for box, score, class_id in zip(xywh, detections.scores, detections.class_ids, strict=True)
    ]


def read_coco_results(path: str | Path) -> list[dict]:
    """Read a results file written by :func:`detections_to_coco` (a JSON list of records)."""
    path = Path(path)
    try:
        records = json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"detections file not found: {path}") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(records, list):
        raise ValueError(f"{path}: expected a JSON list of detection records")
    for i, rec in enumerate(records):
        if not isinstance(rec, dict):
            raise ValueError(f"{path}: record {i} is a {type(rec).__name__}, not an object")
        missing = {"image_id", "bbox", "score", "category_id"} - set(rec)
        if missing:
            raise ValueError(f"{path}: record {i} lacks {sorted(missing)}")
    return records
