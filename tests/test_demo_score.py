"""The demo's scoring of alerts against the simulator's truth, and its --actions option."""

from __future__ import annotations

import argparse

import pytest

from sarmission.alerts.model import Alert
from sarmission.commands.demo import parse_actions
from sarmission.commands.truth_score import score
from sim.camera import FrameTruth
from sim.render import ObjectAnnotation


def _object(track_id: int, category: str, cx: float, cy: float) -> ObjectAnnotation:
    return ObjectAnnotation(
        track_id=track_id,
        category=category,
        category_id=1,
        is_target=category == "swimmer",
        bbox_xyxy=(cx - 4.5, cy - 4.5, cx + 5.5, cy + 5.5),
        area=100.0,
        visibility=1.0,
        position_ned=(0.0, 0.0, 0.0),
        lat=54.0,
        lon=7.0,
    )


class _Truth:
    """What the scoring reads of the simulated camera: the truth of every delivered frame."""

    def __init__(self, frames: list[FrameTruth]) -> None:
        self.truth = frames

    def targets_at(self, frame_index: int) -> list[ObjectAnnotation]:
        return self.truth[frame_index].targets

    def others_at(self, frame_index: int) -> list[ObjectAnnotation]:
        return self.truth[frame_index].others


def _alert(target_id: int, frame_index: int, cx: float, cy: float) -> Alert:
    return Alert(
        mission_id="m",
        target_id=target_id,
        class_name="swimmer",
        score=0.8,
        lock_time=0.0,
        frame_index=frame_index,
        position=(54.0, 7.0),
        error_m=1.0,
        pixel_track=[(frame_index, cx, cy)],
    )


def test_false_alerts_say_what_they_sat_on() -> None:
    swimmer = _object(1, "swimmer", 100.0, 100.0)
    boat, bird = _object(2, "boat", 300.0, 200.0), _object(3, "bird", 500.0, 50.0)
    camera = _Truth([FrameTruth(i, i / 30.0, [swimmer], [boat, bird]) for i in range(4)])
    alerts = [
        _alert(1, 3, 102.0, 99.0),
        _alert(2, 3, 305.0, 203.0),
        _alert(3, 3, 700.0, 400.0),
        _alert(4, 3, 301.0, 199.0),
    ]
    lines = score(alerts, camera, min_frames=3)
    assert lines[0] == "people in view (>= 3 frames): 1, found: 1 of them"
    assert lines[1] == "alerts: 4, false alerts: 3 (on boat 2, open water 1), duplicates: 0"
    assert any("FALSE ALERT (swimmer 0.80, frame 3, on open water)" in line for line in lines)


def test_actions_option_takes_known_actions_only() -> None:
    assert parse_actions("alert,roi") == ("alert", "roi")
    with pytest.raises(argparse.ArgumentTypeError, match="alert, loiter, roi, mission"):
        parse_actions("alert,dance")
