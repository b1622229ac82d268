"""A COCO video dataset's annotations as the frames the alert scorer reads.

:func:`~sarmission.evaluation.alert_scoring.score_flight` scores confirmed alerts against frames
that list the people in view and everything else. Any annotated footage with tracks (and, for
matching by position, true positions) can be scored that way: the held-out worlds, a user's
SeaDronesSee-style dataset replayed with ``sarmission replay``. A category is a person only when
its name says so (swimmer, swimmer with life jacket, person, or a dataset's alias of one); rocks,
boats and buoys are what a false alert lay on.
"""

from __future__ import annotations

from dataclasses import dataclass

from sarmission.class_roles import CATEGORY_ALIASES, PERSON_CLASSES, normalise_class
from sarmission.data.coco_video import VideoDataset
from sarmission.data.sequence import sequence_images


@dataclass(frozen=True)
class TruthBox:
    """One annotated object in one frame: its track, category, box edges and true position."""

    track_id: int
    category: str
    bbox_xyxy: tuple[float, float, float, float]
    lat: float | None = None
    lon: float | None = None


@dataclass(frozen=True)
class TruthFrame:
    """One frame of the footage: index, time (s from the first frame) and what was in it."""

    index: int
    sim_time: float
    targets: list[TruthBox]
    others: list[TruthBox]


def is_person_category(name: str) -> bool:
    """True for a category that names people (unknown names are not people here)."""
    key = normalise_class(name)
    return CATEGORY_ALIASES.get(key, key) in PERSON_CLASSES


def dataset_truth(dataset: VideoDataset, video_id: int | None, fps: float) -> list[TruthFrame]:
    """The frames of one video (``None``: a file without videos) in order, each at
    ``frame_index / fps`` seconds, as ``sarmission replay`` times them. An annotation without
    a track is a track of its own."""
    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    names = {c.id: c.name for c in dataset.categories}
    by_image = dataset.annotations_by_image()
    frames = []
    for n, image in enumerate(sequence_images(dataset, video_id)):
        index = image.frame_index if image.frame_index is not None else n
        targets, others = [], []
        for ann in by_image.get(image.id, []):
            x, y, w, h = ann.bbox
            category = names.get(ann.category_id, str(ann.category_id))
            box = TruthBox(
                ann.track_id if ann.track_id is not None else -ann.id,
                category,
                (x, y, x + w, y + h),
                ann.gt_lat,
                ann.gt_lon,
            )
            (targets if is_person_category(category) else others).append(box)
        frames.append(TruthFrame(index, index / fps, targets, others))
    return frames
