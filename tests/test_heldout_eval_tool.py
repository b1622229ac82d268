"""``tools/heldout_eval.py``: the scores of detections on people and on background, and the
false detections per frame, counted from a run and its annotations."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from conftest import load_tool

from sarmission.data.coco_video import Annotation
from sarmission.evaluation.matching import FrameBoxes


@pytest.fixture(scope="module")
def tool():
    module = load_tool("heldout_eval")
    return module


def test_detection_scores_split_people_from_background(tool) -> None:
    person = Annotation(1, 1, 7, (100.0, 100.0, 10.0, 10.0))
    boat = Annotation(2, 1, 3, (300.0, 300.0, 40.0, 20.0))  # not a target: background
    dataset = SimpleNamespace(annotations=[person, boat])
    run = SimpleNamespace(
        detections={
            1: FrameBoxes.of(
                np.array(
                    [
                        [100.0, 100.0, 110.0, 110.0],  # on the person
                        [301.0, 301.0, 317.0, 317.0],  # on the boat
                        [500.0, 500.0, 516.0, 516.0],  # on open water
                    ]
                ),
                scores=np.array([0.8, 0.95, 0.4]),
            ),
            2: FrameBoxes.of(np.array([[100.0, 100.0, 110.0, 110.0]]), scores=np.array([0.6])),
        }
    )
    scores = tool.detection_scores(dataset, run, targets={7})
    assert scores["frames"] == 2
    assert scores["on_person"]["n"] == 1 and scores["on_person"]["quantiles"][1] == 0.8
    # frame 2 has no person annotated: its detection is on none
    assert scores["on_none"]["n"] == 3
    assert scores["on_none"]["quantiles"][1] == pytest.approx(0.6)
    assert scores["false_per_frame_above_0.5"] == pytest.approx(1.0)  # 0.95 and 0.6 over 2
    assert scores["false_per_frame_above_0.9"] == pytest.approx(0.5)


def test_people_called_counts_the_class_of_the_best_detection(tool) -> None:
    swimmer = Annotation(1, 1, 1, (100.0, 100.0, 10.0, 10.0))
    jacket = Annotation(2, 1, 2, (300.0, 300.0, 12.0, 12.0))
    unseen = Annotation(3, 1, 2, (700.0, 700.0, 12.0, 12.0))  # nothing near it
    buoy = Annotation(4, 1, 3, (900.0, 900.0, 12.0, 12.0))  # not a target
    dataset = SimpleNamespace(
        annotations=[swimmer, jacket, unseen, buoy],
        categories=[
            SimpleNamespace(id=1, name="swimmer"),
            SimpleNamespace(id=2, name="swimmer_with_life_jacket"),
            SimpleNamespace(id=3, name="buoy"),
        ],
    )
    run = SimpleNamespace(
        detections={
            1: FrameBoxes.of(
                np.array(
                    [
                        [100.0, 100.0, 110.0, 110.0],  # swimmer, called swimmer
                        [300.0, 300.0, 312.0, 312.0],  # jacket: best-scored is swimmer
                        [301.0, 301.0, 313.0, 313.0],  # jacket: called jacket, lower score
                        [700.0, 700.0, 712.0, 712.0],  # on the unseen one, but at 0.4
                        [900.0, 900.0, 912.0, 912.0],  # on the buoy
                    ]
                ),
                scores=np.array([0.9, 0.8, 0.7, 0.4, 0.99]),
                class_ids=np.array([0, 0, 1, 1, 1]),
            )
        }
    )
    called = tool.people_called(
        dataset, run, targets={1, 2}, classes=("swimmer", "swimmer_with_life_jacket")
    )
    assert list(called) == ["swimmer", "swimmer_with_life_jacket"]
    assert called["swimmer"] == {
        "boxes": 1,
        "found": 1,
        "called": {"swimmer": 1, "swimmer_with_life_jacket": 0},
    }
    assert called["swimmer_with_life_jacket"] == {
        "boxes": 2,
        "found": 1,
        "called": {"swimmer": 1, "swimmer_with_life_jacket": 0},
    }
    study = {"people_called": called}
    section = tool._people_called_table({"splits": {"heldout_maritime": {"study": study}}})
    assert "| `heldout_maritime` | swimmer_with_life_jacket | 2 | 1 | 100 % | 0 % |" in section
    # results written before the table existed render without it
    assert tool._people_called_table({"splits": {"x": {"study": {}}}}) == []


def test_operating_points_count_people_found_and_clutter_per_threshold(tool) -> None:
    person = Annotation(1, 1, 7, (100.0, 100.0, 10.0, 10.0))
    other = Annotation(2, 1, 7, (400.0, 400.0, 10.0, 10.0))  # found by nothing
    buoy = Annotation(3, 1, 3, (300.0, 300.0, 12.0, 12.0))  # not a target: clutter
    dataset = SimpleNamespace(annotations=[person, other, buoy])
    run = SimpleNamespace(
        detections={
            1: FrameBoxes.of(
                np.array(
                    [
                        [100.0, 100.0, 110.0, 110.0],  # on the person, 0.65
                        [102.0, 101.0, 114.0, 113.0],  # near the person, 0.85: found, no clutter
                        [300.0, 300.0, 312.0, 312.0],  # on the buoy: clutter
                        [700.0, 700.0, 716.0, 716.0],  # open water, under every threshold
                    ]
                ),
                scores=np.array([0.65, 0.85, 0.75, 0.45]),
            ),
            2: FrameBoxes.of(np.array([[10.0, 10.0, 26.0, 26.0]]), scores=np.array([0.95])),
        }
    )
    op = tool.operating_points(dataset, run, targets={7})
    assert op["boxes"] == 2 and op["frames"] == 2
    by_t = {p["threshold"]: p for p in op["points"]}
    assert [by_t[t]["found"] for t in (0.5, 0.8, 0.9)] == [0.5, 0.5, 0.0]
    # clutter: 0.75 (buoy) and 0.95 (frame without people) over 2 frames
    assert [by_t[t]["clutter_per_frame"] for t in (0.5, 0.7, 0.8, 0.9)] == [1.0, 1.0, 0.5, 0.5]
    study = {"operating_points": op}
    section = tool._operating_points_table({"splits": {"heldout_maritime": {"study": study}}})
    assert "| `heldout_maritime` | 2 | 2 | 50.0 % / 1.00 |" in "\n".join(section)
    assert tool._operating_points_table({"splits": {"x": {"study": {}}}}) == []


def test_objects_called_count_each_track_by_the_share_of_its_frames(tool) -> None:
    """An object is taken for a person when a detection above 0.7 lies on it (NWD 0.1 or
    centred inside its box) in at least 30 % of its frames; one without a track is its own."""
    swimmer = [Annotation(10 + f, f, 1, (100.0, 100.0, 10.0, 10.0), 1, 1) for f in range(5)]
    buoy = [Annotation(20 + f, f, 2, (300.0, 300.0, 12.0, 12.0), 2, 1) for f in range(5)]
    boat = [Annotation(30 + f, f, 3, (500.0, 500.0, 80.0, 40.0), 3, 1) for f in range(5)]
    loose = [Annotation(40 + f, f, 2, (700.0, 700.0, 12.0, 12.0)) for f in range(2)]
    dataset = SimpleNamespace(
        categories=[
            SimpleNamespace(id=1, name="swimmer"),
            SimpleNamespace(id=2, name="buoy"),
            SimpleNamespace(id=3, name="boat"),
        ],
        annotations=swimmer + buoy + boat + loose,
    )
    on_swimmer, on_buoy = [100.0, 100.0, 110.0, 110.0], [300.0, 300.0, 312.0, 312.0]
    on_boat_deck = [530.0, 510.0, 546.0, 526.0]  # far in NWD, centred inside the boat's box
    on_loose = [700.0, 700.0, 712.0, 712.0]
    frames = {
        0: ([on_swimmer, on_buoy, on_boat_deck, on_loose], [0.9, 0.72, 0.8, 0.9]),
        1: ([on_swimmer, on_buoy], [0.71, 0.69]),  # the buoy's under the score
        2: ([on_swimmer], [0.5]),
        3: ([], []),
        4: ([on_buoy], [0.95]),
    }
    run = SimpleNamespace(
        detections={
            f: FrameBoxes.of(np.array(boxes, np.float64).reshape(-1, 4), scores=np.array(s))
            for f, (boxes, s) in frames.items()
        }
    )
    called = tool.objects_called(dataset, run)
    # swimmer 2 of 5 frames, buoy 2 of 5, boat 1 of 5 (under 30 %); the two loose boxes are
    # two buoys, one seen in its only frame
    assert called == {
        "boat": {"objects": 1, "called": 0},
        "buoy": {"objects": 3, "called": 2},
        "swimmer": {"objects": 1, "called": 1},
    }
    section = "\n".join(
        tool._objects_called_table({"splits": {"x": {"study": {"objects_called": called}}}})
    )
    assert "| `x` | 0 / 1 | 2 / 3 | 1 / 1 |" in section
    assert tool._objects_called_table({"splits": {"x": {"study": {}}}}) == []
    # the same rule at every threshold of the curve
    curve = tool.object_curve(dataset, run)
    at = {t: i for i, t in enumerate(curve["thresholds"])}
    taken = {k: v["called"] for k, v in curve["classes"].items()}
    assert {k: v["objects"] for k, v in curve["classes"].items()} == {
        "boat": 1,
        "buoy": 3,
        "swimmer": 1,
    }
    assert [taken["swimmer"][at[t]] for t in (0.3, 0.7, 0.75)] == [1, 1, 0]
    # buoy track 0.72 / 0.69 / - / - / 0.95; the loose one seen once at 0.9
    assert [taken["buoy"][at[t]] for t in (0.65, 0.7, 0.75, 0.85, 0.9)] == [2, 2, 1, 1, 0]
    assert set(taken["boat"]) == {0}


def test_a_render_of_other_clips_is_not_reused(tool, tmp_path) -> None:
    """Validation clips (150 on) and test clips (0 on) have the same counts: the first video's
    index tells them apart, so a folder of one is never scored as the other."""
    import json

    path = tmp_path / "heldout_maritime.json"
    videos = [{"id": i + 1, "name": f"heldout_maritime_{150 + i}"} for i in range(2)]
    images = [{"id": i + 1} for i in range(2 * 3)]
    path.write_text(json.dumps({"videos": videos, "images": images}))
    assert tool._rendered(path, 2, 3)
    assert tool._rendered(path, 2, 3, first_clip=150)
    assert not tool._rendered(path, 2, 3, first_clip=0)
    assert not tool._rendered(path, 2, 4, first_clip=150)
    assert not tool._rendered(tmp_path / "missing.json", 2, 3)


def test_clips_flown_at_another_altitude_render_apart_and_say_so(tool, tmp_path, monkeypatch):
    """A render at another altitude has the same clip and frame counts as the world's own: it
    goes to a folder of its own, so neither is ever scored as the other."""
    commands: list[list[str]] = []
    monkeypatch.setattr(tool, "_run", lambda cmd: commands.append(cmd) or "")
    reused: list[str] = []
    plain = tool.render_heldout(tmp_path, "heldout_maritime", 2, 3, reused, 150)
    low = tool.render_heldout(tmp_path, "heldout_maritime", 2, 3, reused, 150, (35.0, 55.0))
    assert plain == tmp_path / "heldout_maritime" / "heldout_maritime.json"
    assert low == tmp_path / "heldout_maritime_alt35-55" / "heldout_maritime.json"
    assert "--altitude" not in commands[0]
    assert commands[1][commands[1].index("--altitude") + 1] == "35,55"
    assert commands[1][commands[1].index("--out") + 1] == str(low.parent)


def test_a_split_is_evaluated_and_studied_with_the_detector_settings_asked(tool, monkeypatch):
    seen: list[tuple] = []
    monkeypatch.setattr(tool, "evaluate", lambda path, model, extra=(): seen.append(extra) or {})
    monkeypatch.setattr(
        tool,
        "box_study",
        lambda path, model, ds=2, scales=(1.0,), sized=(0.0, 0.0): (
            seen.append((ds, scales, sized)) or {}
        ),
    )
    monkeypatch.setattr(tool, "clip_conditions", lambda path: [])
    tool.heldout_split(Path("a.json"), None)
    tool.heldout_split(Path("a.json"), None, ds=4)
    tool.heldout_split(Path("a.json"), None, crop_scales=(4.0,))
    tool.heldout_split(Path("a.json"), None, ds=8, crop_scales=(1.0, 2.5))
    tool.heldout_split(Path("a.json"), None, range_crops=(0.45, 0.5))
    assert seen == [
        (),
        (2, (1.0,), (0.0, 0.0)),
        ("--ds", "4"),
        (4, (1.0,), (0.0, 0.0)),
        ("--crop-scales", "4"),
        (2, (4.0,), (0.0, 0.0)),
        ("--ds", "8", "--crop-scales", "1,2.5"),
        (8, (1.0, 2.5), (0.0, 0.0)),
        ("--person-m", "0.45", "--range-shift", "0.5"),
        (2, (1.0,), (0.45, 0.5)),
    ]


def test_a_buoy_the_head_names_a_buoy_is_not_taken_for_a_person(tool) -> None:
    """With the head's person classes given, only their detections count: a buoy detected as
    ``buoy`` is not taken, one detected as ``swimmer`` is."""
    named = [Annotation(1 + f, f, 2, (300.0, 300.0, 12.0, 12.0), 1, 1) for f in range(2)]
    mistaken = [Annotation(10 + f, f, 2, (500.0, 500.0, 12.0, 12.0), 2, 1) for f in range(2)]
    dataset = SimpleNamespace(
        categories=[SimpleNamespace(id=2, name="buoy")], annotations=named + mistaken
    )
    boxes = np.array([[300.0, 300.0, 312.0, 312.0], [500.0, 500.0, 512.0, 512.0]])
    run = SimpleNamespace(
        detections={
            f: FrameBoxes.of(boxes, scores=np.array([0.9, 0.8]), class_ids=np.array([4, 0]))
            for f in range(2)
        }
    )
    assert tool.objects_called(dataset, run, person_ids=[0, 1]) == {
        "buoy": {"objects": 2, "called": 1}
    }
    assert tool.objects_called(dataset, run) == {"buoy": {"objects": 2, "called": 2}}
    curve = tool.object_curve(dataset, run, person_ids=[0, 1])
    assert curve["classes"]["buoy"]["called"][curve["thresholds"].index(0.75)] == 1
    assert curve["classes"]["buoy"]["called"][curve["thresholds"].index(0.8)] == 0
