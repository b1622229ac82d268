"""Importers of published drone datasets into the project's COCO-video format.

``sarmission data import FORMAT FOLDER --out FILE.json`` (:mod:`sarmission.commands.data`)
picks one by name; each reads the dataset's own layout (docs/datasets.md says where each is
published, its licence and its layout) and returns a
:class:`~sarmission.data.coco_video.VideoDataset` with absolute image paths.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from pathlib import Path

from sarmission.data.coco_video import VideoDataset

Importer = Callable[..., VideoDataset]

#: Dataset name -> module of ``sarmission.data.importers`` holding ``import_<name>(root,
#: split=None, progress=True)``.
IMPORTERS: dict[str, str] = {
    "seadronessee": "seadronessee",
    "ladd": "ladd",
    "visdrone": "visdrone",
    "heridal": "heridal",
    "tinyperson": "tinyperson",
}


def importer(name: str) -> Importer:
    """The importer of dataset ``name`` (``ValueError`` for an unknown name)."""
    if name not in IMPORTERS:
        raise ValueError(f"unknown dataset {name!r}; known: {', '.join(IMPORTERS)}")
    module = importlib.import_module(f"sarmission.data.importers.{IMPORTERS[name]}")
    return getattr(module, f"import_{name}")


def import_dataset(
    name: str, root: Path, split: str | None = None, progress: bool = True
) -> VideoDataset:
    """Import the dataset ``name`` found at ``root``."""
    return importer(name)(root, split=split, progress=progress)
