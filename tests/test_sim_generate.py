"""``sarmission sim generate``: clips rendered along a preset's flight, merged into one file."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sarmission.cli import main
from sarmission.data.coco_video import read_coco_video
from sarmission.data.sequence import iter_sequence


def test_generate_writes_merged_clips_that_read_back_frame_by_frame(tmp_path: Path) -> None:
    out = tmp_path / "split"
    code = main(["sim", "generate", "--scenario", "maritime_val", "--frames", "3",
                 "--sequences", "2", "--size", "320x180", "--out", str(out)])
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


def test_generate_rejects_an_unknown_preset(tmp_path: Path, capsys) -> None:
    code = main(["sim", "generate", "--scenario", "lake", "--frames", "1", "--out", str(tmp_path)])
    assert code == 2
    assert "unknown scenario preset" in capsys.readouterr().err
