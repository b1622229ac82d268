"""Which head classes are people: the roles the evaluation, the confirmation and the alert scorer
read, and what each does with a head that names boats, buoys and life rings."""

import numpy as np
import pytest

from sarmission.class_roles import (
    MARITIME_CLASSES,
    person_class_ids,
    role_of,
    role_of_id,
)
from sarmission.data.coco_video import Annotation, Category, ImageRecord, Video, VideoDataset
from sarmission.evaluation.matching import FrameBoxes
from sarmission.evaluation.report import evaluate_detections, person_category_map


@pytest.mark.parametrize(
    ("name", "role"),
    [
        ("swimmer", "person"),
        ("Swimmer with life-jacket", "person"),
        ("floater", "person"),
        ("person", "person"),
        ("boat", "object"),
        ("Jetski", "object"),
        ("buoy", "object"),
        ("life_saving_appliances", "appliance"),
        ("Life ring", "appliance"),
        ("target", "person"),  # a name nobody told us about: alert rather than miss
    ],
)
def test_roles_of_names(name, role):
    assert role_of(name) == role


def test_the_maritime_heads_people_keep_the_ids_of_earlier_heads():
    assert MARITIME_CLASSES[:2] == ("swimmer", "swimmer_with_life_jacket")
    assert person_class_ids(MARITIME_CLASSES).tolist() == [0, 1]
    assert role_of_id(MARITIME_CLASSES, 5) == "appliance"
    assert role_of_id(MARITIME_CLASSES, 99) == "person"


def dataset() -> VideoDataset:
    """One frame with a swimmer at (100, 100) and a boat at (300, 300)."""
    categories = [Category(1, "swimmer"), Category(3, "boat")]
    images = [ImageRecord(1, "f.png", 480, 640, video_id=1, frame_index=0)]
    annotations = [
        Annotation(1, 1, 1, (96.0, 96.0, 8.0, 8.0), track_id=1, video_id=1),
        Annotation(2, 1, 3, (280.0, 290.0, 40.0, 20.0), track_id=2, video_id=1),
    ]
    return VideoDataset(
        videos=[Video(1, "v")], images=images, annotations=annotations, categories=categories
    )


def test_a_head_that_names_boats_is_scored_on_people_only():
    data = dataset()
    swimmer = [96.0, 96.0, 104.0, 104.0]
    boat = [280.0, 290.0, 320.0, 310.0]
    assert person_category_map(data.categories, MARITIME_CLASSES) == {1: 0}
    # the boat called a boat: not a false alarm
    right = {1: FrameBoxes.of([swimmer, boat], [0.9, 0.9], [0, 2])}
    report = evaluate_detections(data, right, MARITIME_CLASSES, m=1, k=1)
    assert report["boxes"]["bands"]["all"]["precision"] == 1.0
    assert report["sar"]["n_false_alarms"] == 0
    assert [t["name"] for t in report["categories"]["targets"]] == ["swimmer"]
    # the boat called a swimmer: a false alarm
    wrong = {1: FrameBoxes.of([swimmer, boat], [0.9, 0.9], [0, 0])}
    report = evaluate_detections(data, wrong, MARITIME_CLASSES, m=1, k=1)
    assert report["boxes"]["bands"]["all"]["precision"] == 0.5
    assert report["sar"]["n_false_alarms"] == 1


def test_a_dataset_with_no_person_category_is_refused():
    with pytest.raises(ValueError, match="no annotation category is a person class"):
        person_category_map([Category(3, "boat")], MARITIME_CLASSES)


def test_people_only_keeps_ids_and_order():
    from sarmission.evaluation.report import people_only

    boxes = FrameBoxes.of(np.arange(12.0).reshape(3, 4), [0.1, 0.2, 0.3], [2, 0, 1], ids=[7, 8, 9])
    kept = people_only(boxes, np.array([0, 1]))
    assert kept.ids.tolist() == [8, 9] and kept.class_ids.tolist() == [0, 1]


def test_validation_f2_picks_epochs_on_people_only():
    """A boat the head does not detect costs the selection nothing; a swimmer it misses does."""
    import torch

    from sarmission.perception.head_config import HeadConfig
    from sarmission.training.dataset import CropSet
    from sarmission.training.train import validate_f2

    class Stub(torch.nn.Module):
        """Says "swimmer" (logit 4) on the crops whose index is in ``found``, nothing elsewhere."""

        def __init__(self, found: list[int]) -> None:
            super().__init__()
            self.config = HeadConfig(classes=("swimmer", "boat"))
            self.found = found

        def forward(self, crops):
            logits = torch.full((len(crops), 2), -6.0)
            logits[self.found, 0] = 4.0
            return logits, torch.full((len(crops), 4), 8.0)  # the crop's own box

    swimmer, boat = [96.0, 96.0, 112.0, 112.0], [300.0, 300.0, 316.0, 316.0]
    val = CropSet(
        crops=torch.zeros(2, 4, 16, 16),
        labels=torch.tensor([0, 1]),
        target_ltrb=torch.zeros(2, 4),
        boxes=torch.tensor([swimmer, boat]),
        image_ids=torch.tensor([1, 1]),
        jittered=torch.tensor([False, False]),
        frame_ids=torch.tensor([1]),
        gt_boxes=torch.tensor([swimmer, boat]),
        gt_classes=torch.tensor([0, 1]),
        gt_image_ids=torch.tensor([1, 1]),
    )
    assert validate_f2(Stub([0]), val)["recall"] == 1.0
    assert validate_f2(Stub([]), val)["recall"] == 0.0
