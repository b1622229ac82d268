"""``sarmission eval`` on a tiny annotated dataset: results files, MITE-Net runs and the sweep."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from motion_scenes import render, textured_background, to_bgr

from sarmission.commands import eval as eval_cmd
from sarmission.data.coco_video import (
    Annotation,
    Category,
    ImageRecord,
    Video,
    VideoDataset,
    write_coco_video,
)
from sarmission.evaluation.report import format_sweep, target_category_map

H, W = 120, 160
FRAMES = 8
# (video id, track id, category id, start (x, y), velocity px/frame, side px, shape)
TARGETS = [
    (1, 1, 1, (40.0, 50.0), (2.0, 1.0), 6.0, "disc"),  # swimmer, 36 px^2: extremely tiny
    (1, 2, 2, (110.0, 30.0), (-1.5, 2.0), 12.0, "square"),  # with life jacket, 144 px^2: tiny
    (2, 4, 1, (30.0, 80.0), (3.0, -1.0), 8.0, "square"),  # swimmer, 64 px^2: extremely tiny
]
BOAT = (1, 3, 3, (120.0, 95.0), (0.0, 0.0), 24.0, "square")  # not a target category


def _bbox(cx: float, cy: float, side: float) -> list[float]:
    return [cx - side / 2, cy - side / 2, side, side]


@pytest.fixture(scope="module")
def annotations(tmp_path_factory) -> Path:
    """Two videos of 8 PNG frames with moving blobs, annotated with track ids."""
    root = tmp_path_factory.mktemp("tiny_sar")
    (root / "images").mkdir()
    images, anns = [], []
    for video_id in (1, 2):
        background = textured_background(H, W, seed=video_id)
        for t in range(FRAMES):
            image_id = video_id * 100 + t
            frame = background
            for vid, track, category, (x, y), (vx, vy), side, shape in TARGETS + [BOAT]:
                if vid != video_id:
                    continue
                cx, cy = x + vx * t, y + vy * t
                frame = render(frame, cx, cy, side, value=0.95, shape=shape)
                anns.append(
                    Annotation(
                        id=len(anns) + 1,
                        image_id=image_id,
                        category_id=category,
                        bbox=tuple(_bbox(cx, cy, side)),
                        track_id=track,
                        video_id=video_id,
                        area=side * side,
                    )
                )
            name = f"v{video_id}_{t:03d}.png"
            cv2.imwrite(str(root / "images" / name), to_bgr(frame))
            images.append(
                ImageRecord(
                    id=image_id, file_name=name, height=H, width=W, video_id=video_id, frame_index=t
                )
            )
    dataset = VideoDataset(
        videos=[Video(1, "seq_a"), Video(2, "seq_b")],
        images=images,
        annotations=anns,
        categories=[
            Category(1, "swimmer"),
            Category(2, "swimmer with life jacket"),
            Category(3, "boat"),
        ],
    )
    path = root / "annotations.json"
    write_coco_video(dataset, path)
    return path


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    eval_cmd.add_parser(parser.add_subparsers())
    return parser.parse_args(["eval", "--no-progress", *argv])


def _run_json(capsys, *argv: str):
    assert eval_cmd.run(_args(*argv, "--json")) == 0
    return json.loads(capsys.readouterr().out)


def _results_file(annotations: Path, tmp_path: Path, shift: float = 0.0) -> Path:
    """Detections equal to the target GT (score 0.9), moved by ``shift`` px in x and y."""
    doc = json.loads(annotations.read_text())
    frame_of = {im["id"]: im["frame_index"] for im in doc["images"]}
    records = [
        {
            "image_id": a["image_id"],
            "frame_index": frame_of[a["image_id"]],
            "bbox": [a["bbox"][0] + shift, a["bbox"][1] + shift, *a["bbox"][2:]],
            "score": 0.9,
            "category_id": a["category_id"],
        }
        for a in doc["annotations"]
        if a["category_id"] in (1, 2)
    ]
    path = tmp_path / "dets.json"
    path.write_text(json.dumps(records))
    return path


def test_perfect_detections(annotations, tmp_path, capsys):
    report = _run_json(
        capsys,
        "--annotations",
        str(annotations),
        "--detections",
        str(_results_file(annotations, tmp_path)),
    )
    sar = report["sar"]
    assert sar["n_trajectories"] == 3  # the boat's track is not a target
    assert sar["search_success_rate"] == 100.0
    assert sar["false_alarm_rate_per_frame"] == 0.0 and sar["false_alarm_rate_detections"] == 0.0
    assert sar["avg_search_time_frames"] == 2.0 and sar["max_search_time_frames"] == 2
    bands = report["boxes"]["bands"]
    assert bands["extremely_tiny"]["n_gt"] == 2 * FRAMES
    assert bands["tiny"]["n_gt"] == FRAMES
    assert bands["small"]["n_gt"] == 0 and bands["small"]["ap"] is None  # boat left out
    for band in ("extremely_tiny", "tiny", "all"):
        assert bands[band]["ap"] == pytest.approx(1.0)
        assert bands[band]["f2"] == pytest.approx(1.0)
    assert report["module_recall"]["rpn"] is None
    assert report["module_recall"]["head"] == {"R@0.1": 1.0, "R@0.5": 1.0}
    assert report["detector"] is None

    assert (
        eval_cmd.run(
            _args(
                "--annotations",
                str(annotations),
                "--detections",
                str(_results_file(annotations, tmp_path)),
            )
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "Search Success Rate (%)" in text and "100.00" in text
    assert "boat" in text and "extremely tiny" in text


def test_detections_far_from_the_targets(annotations, tmp_path, capsys):
    report = _run_json(
        capsys,
        "--annotations",
        str(annotations),
        "--detections",
        str(_results_file(annotations, tmp_path, shift=40.0)),
    )
    sar = report["sar"]
    n_dets, n_frames = 3 * FRAMES, 2 * FRAMES
    assert sar["search_success_rate"] == 0.0
    assert sar["n_detections"] == n_dets and sar["n_frames"] == n_frames
    assert sar["false_alarm_rate_per_frame"] == pytest.approx(100.0 * n_dets / n_frames)
    assert sar["false_alarm_rate_detections"] == 100.0
    assert sar["avg_search_time_frames"] is None
    assert report["boxes"]["bands"]["all"]["ap"] == 0.0


def test_max_frames_restricts_a_results_file(annotations, tmp_path, capsys):
    report = _run_json(
        capsys,
        "--annotations",
        str(annotations),
        "--max-frames",
        "2",
        "--detections",
        str(_results_file(annotations, tmp_path)),
    )
    assert report["sar"]["n_frames"] == 4
    assert report["sar"]["search_success_rate"] == 0.0  # 2 frames cannot hold 3 hits


def test_model_run_reports_module_recall(annotations, tmp_path, capsys):
    import torch

    from sarmission.perception.head import MiteHead
    from sarmission.perception.runtime import save_head_checkpoint

    torch.manual_seed(0)
    model = save_head_checkpoint(MiteHead(), tmp_path / "head.pt")
    report = _run_json(
        capsys,
        "--annotations",
        str(annotations),
        "--model",
        str(model),
        "--runtime",
        "torch",
        "--topn",
        "5",
    )
    recall = report["module_recall"]
    for module in ("rpn", "head"):
        assert set(recall[module]) == {"R@0.1", "R@0.5"}
        assert all(0.0 <= v <= 1.0 for v in recall[module].values())
    assert recall["rpn"]["R@0.1"] > 0.3  # the learning-free RPN finds the moving blobs
    assert report["detector"]["frames"] == 2 * FRAMES
    assert report["detector"]["median_ms"] > 0 and report["detector"]["model"] == str(model)
    assert 0.0 <= report["sar"]["search_success_rate"] <= 100.0

    assert (
        eval_cmd.run(
            _args(
                "--annotations",
                str(annotations),
                "--model",
                str(model),
                "--runtime",
                "torch",
                "--topn",
                "5",
                "--max-frames",
                "3",
                "--crop-scales",
                "1,2",
            )
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "6 frames" in text and "TTM-RPN (no category)" in text
    assert "crop scales=1,2 (further scales from score 0.3)" in text
    assert report["detector"]["crop_scales"] == [1.0]  # the default, in the first run
    assert report["detector"]["refine_threshold"] == 0.3


def test_unknown_image_ids_are_an_error(annotations, tmp_path):
    path = tmp_path / "dets.json"
    path.write_text(
        json.dumps([{"image_id": 9999, "bbox": [1, 2, 3, 4], "score": 0.9, "category_id": 1}])
    )
    with pytest.raises(ValueError, match="not in the annotations: 9999"):
        eval_cmd.run(_args("--annotations", str(annotations), "--detections", str(path)))


def test_bad_inputs_are_clear_errors(annotations, tmp_path):
    with pytest.raises(OSError, match="not found"):
        eval_cmd.run(
            _args("--annotations", str(annotations), "--detections", str(tmp_path / "missing.json"))
        )
    broken = tmp_path / "broken.json"
    broken.write_text("[{")
    with pytest.raises(ValueError, match="not valid JSON"):
        eval_cmd.run(_args("--annotations", str(annotations), "--detections", str(broken)))
    with pytest.raises(ValueError, match="not valid JSON"):
        eval_cmd.run(_args("--annotations", str(broken)))
    bad_class = tmp_path / "bad_class.json"
    bad_class.write_text(
        json.dumps([{"image_id": 100, "bbox": [1, 2, 3, 4], "score": 0.9, "category_id": 7}])
    )
    with pytest.raises(ValueError, match="category_id 7"):
        eval_cmd.run(_args("--annotations", str(annotations), "--detections", str(bad_class)))
    for records, message in (
        ([1, 2, 3], "record 0 is a int, not an object"),  # once a TypeError
        (
            [{"image_id": 100, "bbox": [1, 2, 3, 4], "score": float("nan"), "category_id": 1}],
            "bbox and score must be finite",  # once "ECE nan"
        ),
    ):
        odd = tmp_path / "odd.json"
        odd.write_text(json.dumps(records))
        with pytest.raises(ValueError, match=message):
            eval_cmd.run(_args("--annotations", str(annotations), "--detections", str(odd)))
    with pytest.raises(ValueError, match="cannot be combined"):
        eval_cmd.run(
            _args("--annotations", str(annotations), "--detections", str(bad_class), "--sweep")
        )
    with pytest.raises(ValueError, match="--m"):
        eval_cmd.run(_args("--annotations", str(annotations), "--m", "6"))


def test_json_has_the_documented_keys(annotations, tmp_path, capsys):
    report = _run_json(
        capsys,
        "--annotations",
        str(annotations),
        "--detections",
        str(_results_file(annotations, tmp_path)),
        "--m",
        "2",
        "--k",
        "4",
    )
    assert set(report) == {
        "dataset",
        "classes",
        "categories",
        "settings",
        "sar",
        "boxes",
        "module_recall",
        "reliability",
        "definitions",
        "detector",
    }
    # the detections equal the targets' boxes at score 0.9: one bin, every one right
    (only,) = report["reliability"]["bins"]
    assert only["n"] == report["dataset"]["n_gt_boxes"] and only["share_correct"] == 1.0
    assert only["low"] == 0.9 and report["reliability"]["ece"] == pytest.approx(0.1)
    assert report["settings"]["m"] == 2 and report["settings"]["k"] == 4
    assert report["classes"] == ["swimmer", "swimmer_with_life_jacket"]
    assert [c["class"] for c in report["categories"]["targets"]] == list(report["classes"])
    assert [c["name"] for c in report["categories"]["ignored"]] == ["boat"]
    for key in (
        "search_success_rate",
        "false_alarm_rate_per_frame",
        "false_alarm_rate_detections",
        "avg_search_time_frames",
        "max_search_time_frames",
        "trajectories",
    ):
        assert key in report["sar"]
    assert set(report["boxes"]["bands"]) == {"extremely_tiny", "tiny", "small", "all"}
    assert {"ap", "ar", "f2", "n_gt"} <= set(report["boxes"]["bands"]["all"])
    for key in (
        "false_alarm_rate_per_frame",
        "false_alarm_rate_detections",
        "search_success_rate",
        "module_recall_rpn",
        "target_categories",
    ):
        assert report["definitions"][key]


def test_sweep_gives_one_row_per_configuration(annotations, capsys):
    rows = _run_json(
        capsys,
        "--annotations",
        str(annotations),
        "--sweep",
        "--sweep-ds",
        "2,4",
        "--sweep-topn",
        "5",
        "--runtime",
        "torch",
        "--max-frames",
        "4",
    )
    assert [(r["ds"], r["topn"]) for r in rows] == [(2, 5), (4, 5)]
    for row in rows:
        assert row["frames"] == 8 and row["median_ms"] > 0
        assert row["fps"] == pytest.approx(1e3 / row["median_ms"])
        g = row["gflops"]
        assert g["total"] == pytest.approx(g["vstmd"] + g["rpn_other"] + g["head"])
        assert 0.0 <= row["far_detections"] <= 100.0
    assert rows[0]["gflops"]["vstmd"] > rows[1]["gflops"]["vstmd"]
    table = format_sweep(rows).splitlines()
    assert len(table) == 2 + len(rows) + 2 and table[2].split()[:2] == ["2", "5"]


def test_category_names_map_to_head_classes():
    classes = ("swimmer", "swimmer_with_life_jacket")
    categories = [
        Category(0, "ignored"),
        Category(1, "Swimmer"),
        Category(2, "floater"),
        Category(3, "swimmer on boat"),
        Category(4, "Swimmer-with-life-jacket"),
    ]
    assert target_category_map(categories, classes) == {1: 0, 2: 1, 4: 1}
    with pytest.raises(ValueError, match="no annotation category"):
        target_category_map([Category(1, "boat")], classes)


def test_rpn_recall_ignores_classes():
    """RPN proposals count whatever their class; the head's detections must match the class."""
    from sarmission.evaluation.matching import FrameBoxes
    from sarmission.evaluation.report import evaluate_detections

    dataset = VideoDataset(
        videos=[Video(1, "v")],
        images=[ImageRecord(i, f"{i}.png", H, W, 1, i) for i in range(3)],
        annotations=[Annotation(1, 1, 1, (10.0, 10.0, 6.0, 6.0), track_id=1)],
        categories=[Category(1, "swimmer")],
    )
    proposals = {1: FrameBoxes.of([[5.0, 5.0, 21.0, 21.0]], class_ids=[1])}
    detections = {1: FrameBoxes.of([[10.0, 10.0, 16.0, 16.0]], scores=[0.9], class_ids=[1])}
    report = evaluate_detections(
        dataset, detections, ("swimmer", "swimmer_with_life_jacket"), proposals
    )
    assert report["module_recall"]["rpn"]["R@0.1"] == 1.0
    assert report["module_recall"]["head"]["R@0.1"] == 0.0
    assert report["dataset"]["n_gt_boxes"] == 1 and report["sar"]["n_frames"] == 3


def test_run_mitenet_resets_between_videos_in_frame_order(annotations):
    """Every video starts a new stream; frames arrive in frame order; results keyed by image id."""
    from sarmission.data.coco_video import read_coco_video
    from sarmission.evaluation.run_model import run_mitenet
    from sarmission.perception.types import Detections, FrameResult, MotionMaps, Proposals

    class Recorder:
        def __init__(self) -> None:
            self.calls: list[str] = []
            self.per_stage_ms = {"head": 1.5}

        def reset(self) -> None:
            self.calls.append("reset")

        def process(self, frame, timestamp: float, person_px=None) -> FrameResult:
            self.calls.append(f"{frame.shape[1]}x{frame.shape[0]}@{timestamp * 30:.0f}")
            empty = np.zeros((0, 0), np.float32)
            return FrameResult(
                timestamp,
                Detections(),
                Proposals(),
                MotionMaps(1, empty, empty, empty, empty, empty),
            )

    net = Recorder()
    run = run_mitenet(net, read_coco_video(annotations), max_frames=3, progress=False)
    per_video = ["reset"] + [f"{W}x{H}@{t}" for t in range(3)]
    assert net.calls == per_video * 2
    assert sorted(run.image_ids) == [100, 101, 102, 200, 201, 202]
    assert run.frame_size == (H, W) and run.skipped == 0 and len(run.frame_ms) == 6
    assert run.stage_ms == {"head": [1.5] * 6}
