"""LADD, the Lacmus Drone Dataset: people lost in forests and fields, seen from drones.

Pascal VOC layout (``Annotations/*.xml``, ``JPEGImages/``, ``ImageSets/Main/{train,val,
test}.txt``; :mod:`sarmission.data.importers.voc`); its one class, ``Pedestrian``, becomes
``person``. No telemetry.
"""

from __future__ import annotations

from pathlib import Path

from sarmission.data.coco_video import VideoDataset
from sarmission.data.importers.voc import import_voc

SOURCE = "LADD (Lacmus Drone Dataset)"
LICENCE = "as published by the Lacmus Foundation (see docs/datasets.md)"


def person_or_other(name: str) -> str:
    """``Pedestrian`` (any case) -> ``person``; other names kept as they are."""
    return "person" if name.strip().lower() in ("pedestrian", "person", "human") else name


def import_ladd(root: Path, split: str | None = None, progress: bool = True) -> VideoDataset:
    """The LADD folder ``root`` (or one split of it) as the project's dataset."""
    return import_voc(
        root,
        source=SOURCE,
        licence=LICENCE,
        category=person_or_other,
        split=split,
        progress=progress,
    )
