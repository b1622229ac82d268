"""``sarmission sim generate``: clips rendered along a preset's flight, merged into one file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sarmission.cli import main
from sarmission.data.coco_video import read_coco_video
from sarmission.data.sequence import iter_sequence


def test_generate_writes_merged_clips_that_read_back_frame_by_frame(tmp_path: Path) -> None:
    out = tmp_path / "split"
    code = main(
        [
            "sim",
            "generate",
            "--scenario",
            "maritime_val",
            "--frames",
            "3",
            "--sequences",
            "2",
            "--size",
            "320x180",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    dataset = read_coco_video(out / "maritime_val.json")
    assert [v.id for v in dataset.videos] == [1, 2]
    assert len({im.id for im in dataset.images}) == len(dataset.images) == 6
    image_ids = {im.id for im in dataset.images}
    assert all(a.image_id in image_ids for a in dataset.annotations)
    assert len({a.id for a in dataset.annotations}) == len(dataset.annotations)
    first_frames = []
    for video in dataset.videos:
        frames = list(iter_sequence(dataset, video.id))
        assert [f.image.frame_index for f in frames] == [0, 1, 2]
        assert frames[0].frame_bgr.shape == (180, 320, 3)
        first_frames.append(frames[0].frame_bgr.astype(np.int16))
        assert all(f.image.telemetry.latitude is not None for f in frames)
    # the two clips start 15 s apart along the flight: they see different sea
    assert np.abs(first_frames[0] - first_frames[1]).mean() > 2.0
    # every target annotation carries its true position on the globe
    targets = [a for a in dataset.annotations if a.category_id in (1, 2)]
    assert targets and all(a.gt_lat is not None and a.gt_lon is not None for a in targets)


def test_generate_writes_mot_and_yolo_that_agree_with_the_coco_file(tmp_path: Path) -> None:
    from sarmission.boxes import xywh_to_xyxy
    from sarmission.data.mot import read_mot
    from sarmission.data.yolo import read_yolo, yolo_to_xyxy

    out = tmp_path / "gen"
    assert (
        main(
            [
                "sim",
                "generate",
                "--scenario",
                "maritime_test",
                "--frames",
                "2",
                "--size",
                "480x270",
                "--mot",
                "--yolo",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    dataset = read_coco_video(out / "maritime_test.json")
    video = dataset.videos[0].name
    rows = read_mot(out / "mot" / f"{video}.txt")
    assert len(rows) == len(dataset.annotations) > 0
    by_track = {(r.frame, r.track_id): r for r in rows}
    images = {im.id: im for im in dataset.images}
    for ann in dataset.annotations:
        row = by_track[(images[ann.image_id].frame_index + 1, ann.track_id)]
        assert row.bbox == pytest.approx(ann.bbox) and row.class_id == ann.category_id
    first = dataset.images[0]
    anns = dataset.annotations_by_image()[first.id]
    boxes, classes = yolo_to_xyxy(read_yolo(out / "yolo" / video / "000000.txt"), 480, 270)
    expected = xywh_to_xyxy(np.array([a.bbox for a in anns]))
    assert np.allclose(boxes, expected, atol=1e-3)
    assert list(classes) == [a.category_id - 1 for a in anns]


def test_generate_rejects_an_unknown_preset(tmp_path: Path, capsys) -> None:
    code = main(["sim", "generate", "--scenario", "lake", "--frames", "1", "--out", str(tmp_path)])
    assert code == 2
    assert "unknown scenario preset" in capsys.readouterr().err
