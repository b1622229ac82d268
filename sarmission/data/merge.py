"""Merge annotation files from different folders and renderers into one training or validation set.

:func:`merge_annotation_files` reads COCO video files, renumbers image, annotation and video ids,
unites the categories by name (after ``rename``: e.g. ``{"person": "swimmer"}`` scores people on
land as the maritime head's ``swimmer`` class) and makes every video and image path absolute, so
the merged file may be written anywhere. Categories that end up with one name, in one file or
across files, become one category: with ``{"person": "swimmer"}`` a file's ``person`` and
``swimmer`` annotations are all ``swimmer``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from pathlib import Path

from sarmission.data.coco_video import Category, VideoDataset, read_coco_video


def _absolute(dataset: VideoDataset) -> VideoDataset:
    """The dataset with absolute paths: a video's file, or the images of videos without one
    (resolved as the readers do)."""
    videos, with_file = [], set()
    for video in dataset.videos:
        name = video.extra.get("file_name")
        if name:
            with_file.add(video.id)
            if not Path(name).is_absolute() and dataset.source_path is not None:
                path = (dataset.source_path.parent / name).resolve()
                video = dataclasses.replace(video, extra=dict(video.extra, file_name=str(path)))
        videos.append(video)
    images = [
        im
        if im.video_id in with_file
        else dataclasses.replace(im, file_name=str(dataset.image_path(im).resolve()))
        for im in dataset.images
    ]
    return dataclasses.replace(dataset, videos=videos, images=images)


def merge_datasets_by_name(
    datasets: list[VideoDataset], rename: Mapping[str, str] | None = None, info: dict | None = None
) -> VideoDataset:
    """One dataset of the videos of several (module docstring); ``ValueError`` for none."""
    if not datasets:
        raise ValueError("nothing to merge")
    rename = dict(rename or {})
    category_ids: dict[str, int] = {}
    supercategory: dict[str, str] = {}
    videos, images, annotations = [], [], []
    for dataset in datasets:
        dataset = _absolute(dataset)
        names = {c.id: rename.get(c.name, c.name) for c in dataset.categories}
        for c in dataset.categories:
            category_ids.setdefault(names[c.id], len(category_ids) + 1)
            supercategory.setdefault(names[c.id], c.supercategory)
        category = {cid: category_ids[name] for cid, name in names.items()}
        video_ids = {v.id: len(videos) + i + 1 for i, v in enumerate(dataset.videos)}
        image_ids = {im.id: len(images) + i + 1 for i, im in enumerate(dataset.images)}
        videos += [dataclasses.replace(v, id=video_ids[v.id]) for v in dataset.videos]
        images += [
            dataclasses.replace(
                im, id=image_ids[im.id], video_id=video_ids.get(im.video_id, im.video_id)
            )
            for im in dataset.images
        ]
        annotations += [
            dataclasses.replace(
                a,
                id=len(annotations) + i + 1,
                image_id=image_ids[a.image_id],
                category_id=category[a.category_id],
                video_id=video_ids.get(a.video_id, a.video_id),
            )
            for i, a in enumerate(dataset.annotations)
        ]
    categories = [Category(cid, name, supercategory[name]) for name, cid in category_ids.items()]
    return VideoDataset(
        videos=videos,
        images=images,
        annotations=annotations,
        categories=categories,
        info=info or {},
    )


def merge_annotation_files(
    paths: Iterable[str | Path], rename: Mapping[str, str] | None = None, info: dict | None = None
) -> VideoDataset:
    """Read and merge annotation files (:func:`merge_datasets_by_name`)."""
    return merge_datasets_by_name([read_coco_video(p) for p in paths], rename, info)
