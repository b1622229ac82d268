"""Write a COCO video dataset's ground truth in the other formats: MOT text and YOLO labels.

- MOT: one ``<video name>.txt`` per video, 1-based frames (``frame_index + 1``), the track id,
  the box, confidence 1, the COCO ``category_id`` as class and the annotation's ``visibility``
  (1 when absent).
- YOLO: one ``<video name>/<frame_index:06d>.txt`` per image, class = ``category_id - 1``
  (YOLO classes start at 0), boxes normalised by the image size; images without boxes get an
  empty file, as YOLO tools expect.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sarmission.boxes import xywh_to_xyxy
from sarmission.data.coco_video import VideoDataset
from sarmission.data.mot import MotRow, write_mot
from sarmission.data.yolo import write_yolo, xyxy_to_yolo


def _video_names(dataset: VideoDataset) -> dict[int | None, str]:
    names: dict[int | None, str] = {v.id: v.name for v in dataset.videos}
    names.setdefault(None, "images")
    return names


def write_mot_files(dataset: VideoDataset, out_dir: str | Path) -> list[Path]:
    """Write one MOT ground-truth file per video into ``out_dir``; returns their paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    images = {im.id: im for im in dataset.images}
    rows: dict[int | None, list[MotRow]] = {}
    for ann in dataset.annotations:
        image = images[ann.image_id]
        frame = (image.frame_index if image.frame_index is not None else image.id - 1) + 1
        rows.setdefault(image.video_id, []).append(
            MotRow(
                frame=frame,
                track_id=ann.track_id if ann.track_id is not None else -1,
                bbox=tuple(float(v) for v in ann.bbox),
                conf=1.0,
                class_id=ann.category_id,
                visibility=float(ann.extra.get("visibility", 1.0)),
            )
        )
    paths = []
    for video_id, name in _video_names(dataset).items():
        if video_id not in rows:
            continue
        path = out / f"{name}.txt"
        write_mot(sorted(rows[video_id], key=lambda r: (r.frame, r.track_id)), path)
        paths.append(path)
    return paths


def write_yolo_files(dataset: VideoDataset, out_dir: str | Path) -> int:
    """Write one YOLO label file per image under ``out_dir/<video name>/``; returns the count."""
    out = Path(out_dir)
    names = _video_names(dataset)
    by_image = dataset.annotations_by_image()
    for image in dataset.images:
        anns = by_image.get(image.id, [])
        boxes = xywh_to_xyxy(np.array([a.bbox for a in anns], np.float64).reshape(-1, 4))
        labels = xyxy_to_yolo(boxes, [a.category_id - 1 for a in anns], image.width, image.height)
        index = image.frame_index if image.frame_index is not None else image.id - 1
        folder = out / names[image.video_id if image.video_id in names else None]
        folder.mkdir(parents=True, exist_ok=True)
        write_yolo(labels, folder / f"{index:06d}.txt")
    return len(dataset.images)
