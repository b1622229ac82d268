"""``tools/class_confusion.py``: what counts as a head calling a box a person, and which
simulator presets it may render."""

from __future__ import annotations

import argparse

import numpy as np
import pytest
from conftest import load_tool

from sarmission.evaluation.matching import FrameBoxes


@pytest.fixture(scope="module")
def tool():
    return load_tool("class_confusion")


def test_presets_are_the_simulators_own(tool) -> None:
    assert tool.parse_presets("maritime_test, maritime_oblique_low") == (
        "maritime_test",
        "maritime_oblique_low",
    )
    with pytest.raises(argparse.ArgumentTypeError, match="maritime_tset"):
        tool.parse_presets("maritime_test,maritime_tset")
    with pytest.raises(argparse.ArgumentTypeError, match="none given"):
        tool.parse_presets(" , ")


def test_a_detection_lies_on_a_box_by_its_centre_or_by_nwd(tool) -> None:
    truth = np.array(
        [
            [100.0, 100.0, 200.0, 140.0],  # a boat: a small detection on its cabin
            [300.0, 300.0, 310.0, 310.0],  # a swimmer: a detection just beside it (NWD)
            [500.0, 500.0, 510.0, 510.0],  # a swimmer nobody detected
        ]
    )
    found = FrameBoxes.of(
        np.array(
            [
                [150.0, 110.0, 160.0, 120.0],  # centre inside the boat, NWD far too small
                [307.0, 300.0, 317.0, 310.0],  # centre outside the swimmer's box, NWD 0.58
                [501.0, 501.0, 509.0, 509.0],  # on the third, but scored 0.5: not a call
                [800.0, 800.0, 810.0, 810.0],  # on open water
            ]
        ),
        scores=np.array([0.9, 0.8, 0.5, 0.95]),
    )
    on = tool.hits(found, truth)
    assert on.shape == (3, 3)  # the detection scored 0.5 is left out
    assert on.tolist() == [[True, False, False], [False, True, False], [False, False, False]]
