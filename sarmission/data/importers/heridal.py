"""HERIDAL: people in Mediterranean wilderness (karst, forest, fields), for search and rescue.

Images with one Pascal VOC XML each (:mod:`sarmission.data.importers.voc`), the train and
test parts in folders of their own (``--split train`` / ``test`` picks the folder whose name
starts so). Every labelled object is a person (``human``, ``person``, ``pedestrian``, or any
other label the annotators used), stored as ``person``. No telemetry.
"""

from __future__ import annotations

from pathlib import Path

from sarmission.data.coco_video import VideoDataset
from sarmission.data.importers.voc import import_voc

SOURCE = "HERIDAL"
LICENCE = "as published by the HERIDAL authors, University of Split (see docs/datasets.md)"


def import_heridal(root: Path, split: str | None = None, progress: bool = True) -> VideoDataset:
    """The HERIDAL folder ``root`` (or one split of it) as the project's dataset."""
    return import_voc(
        root,
        source=SOURCE,
        licence=LICENCE,
        category=lambda name: "person",
        split=split,
        progress=progress,
    )
