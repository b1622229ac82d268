"""A COCO video file's annotations as the alert scorer's frames: people by name only (a rock is
not a person, SeaDronesSee's floater is), frames in order at index / fps, one video at a time,
and the scorer finding a person and naming what a false alert lay on."""

from dataclasses import dataclass

import pytest

from sarmission.data.coco_video import Annotation, Category, ImageRecord, Video, VideoDataset
from sarmission.evaluation.alert_scoring import score_flight
from sarmission.evaluation.dataset_truth import dataset_truth, is_person_category


def dataset() -> VideoDataset:
    """Two videos; video 1 has 40 frames listed out of order: a swimmer (track 7) in every
    frame at (100, 100), a floater without a track in frame 0, a rock at (300, 200)."""
    categories = [
        Category(1, "swimmer"),
        Category(2, "floater"),
        Category(3, "rock"),
        Category(4, "Life-saving appliances"),
    ]
    images, annotations = [], []
    for frame in reversed(range(40)):
        images.append(ImageRecord(len(images) + 1, f"a/{frame}.jpg", 540, 960, 1, frame))
        image_id = images[-1].id
        annotations.append(Annotation(len(annotations) + 1, image_id, 1, (95, 95, 10, 10), 7, 1))
        annotations.append(Annotation(len(annotations) + 1, image_id, 3, (290, 190, 20, 20), 8, 1))
        if frame == 0:
            annotations.append(Annotation(len(annotations) + 1, image_id, 2, (500, 50, 8, 8)))
    images.append(ImageRecord(len(images) + 1, "b/0.jpg", 540, 960, 2, 0))
    annotations.append(Annotation(len(annotations) + 1, images[-1].id, 1, (10, 10, 5, 5), 1, 2))
    return VideoDataset([Video(1, "a"), Video(2, "b")], images, annotations, categories)


def test_people_are_named_people_and_nothing_else():
    assert is_person_category("Swimmer with life jacket")
    assert is_person_category("floater")  # SeaDronesSee's alias
    assert is_person_category("person")
    assert not is_person_category("rock")  # unknown names are no person in the truth
    assert not is_person_category("life_saving_appliances")
    assert not is_person_category("boat")


def test_frames_in_order_with_people_apart_from_the_rest():
    frames = dataset_truth(dataset(), 1, fps=20.0)
    assert [f.index for f in frames] == list(range(40))
    assert frames[10].sim_time == pytest.approx(0.5)
    first = frames[0]
    assert sorted(a.category for a in first.targets) == ["floater", "swimmer"]
    assert [a.category for a in first.others] == ["rock"]
    swimmer = next(a for a in first.targets if a.category == "swimmer")
    assert swimmer.track_id == 7 and swimmer.bbox_xyxy == (95, 95, 105, 105)
    floater = next(a for a in first.targets if a.category == "floater")
    assert floater.track_id < 0  # no track in the file: a track of its own
    assert all(len(f.targets) == 1 for f in frames[1:])
    (only,) = dataset_truth(dataset(), 2, fps=20.0)
    assert [a.track_id for a in only.targets] == [1]


def test_bad_frame_rate_is_refused():
    with pytest.raises(ValueError, match="fps"):
        dataset_truth(dataset(), 1, fps=0.0)


@dataclass
class Alert:
    frame_index: int
    pixel_track: list
    position: tuple[float, float] | None = None
    error_m: float | None = None
    class_name: str = "swimmer"


def test_the_scorer_finds_the_swimmer_and_names_the_rock():
    frames = dataset_truth(dataset(), 1, fps=10.0)
    on_swimmer = Alert(5, [(5, 100.0, 100.0)])
    on_rock = Alert(6, [(6, 300.0, 200.0)])
    score = score_flight(frames, [(on_swimmer, 25, 2.5), (on_rock, 30, 3.0)])
    assert score.people_in_view == 1  # the swimmer, 3.9 s; the floater one frame
    assert score.found == 1 and score.time_to_alert_s == [pytest.approx(2.5)]
    assert score.false_alerts == 1 and dict(score.false_on) == {"rock": 1}
