"""How much an object's look changes over a second (:mod:`sarmission.perception.look`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sarmission.perception.look import PATCH_PX, LookMemory, grey_patch, look_change
from sarmission.yuv import YuvImage

YY, XX = np.mgrid[0:PATCH_PX, 0:PATCH_PX]


def blob(cx, cy, arm, rng):
    """A body at (cx, cy) with an arm at angle ``arm``, on water, with sensor noise."""
    body = 120 * np.exp(-((XX - cx) ** 2 + (YY - cy) ** 2) / 6.0)
    ax, ay = cx + 4 * np.cos(arm), cy + 4 * np.sin(arm)
    limb = 90 * np.exp(-((XX - ax) ** 2 + (YY - ay) ** 2) / 2.0)
    return (60 + body + limb + rng.normal(0, 2, (PATCH_PX, PATCH_PX))).astype(np.float32)


def test_jitter_and_noise_are_no_change_a_swinging_arm_is():
    rng = np.random.default_rng(1)
    still = [
        look_change(blob(8, 8, 0.0, rng), blob(8 + dx, 8 - dy, 0.0, rng))
        for dx, dy in [(1, 0), (-1, 1), (2, 2), (0, -1)]
    ]
    moved = [look_change(blob(8, 8, 0.0, rng), blob(8, 8, a, rng)) for a in (1.5, 2.5, 3.1)]
    assert max(still) < 0.05
    assert min(moved) > 0.1 and min(moved) > 4 * max(still)


def test_a_flat_patch_has_no_look_to_compare():
    flat = np.full((PATCH_PX, PATCH_PX), 80, np.float32)
    textured = blob(8, 8, 0.0, np.random.default_rng(2))
    assert look_change(flat, textured) is None
    assert look_change(textured, flat) is None


def test_the_patch_is_centred_on_the_box_and_scaled_to_its_size():
    frame = np.zeros((100, 200, 3), np.uint8)
    frame[40:60, 90:110] = 200  # a 20 px square object
    small = grey_patch(frame, np.array([96.0, 46.0, 104.0, 54.0]))  # an 8 px box on it
    assert small.shape == (PATCH_PX, PATCH_PX) and small.dtype == np.float32
    assert small.min() == pytest.approx(200, abs=1)  # 16 px wholly inside the object
    large = grey_patch(frame, np.array([90.0, 40.0, 110.0, 60.0]))  # 30 px around a 20 px box
    assert large.shape == (PATCH_PX, PATCH_PX)
    assert large[8, 8] > 150 and large[0, 0] < 50  # the object in the middle, water around
    # out of the frame or not a number: nothing
    assert grey_patch(frame, np.array([0.0, 0.0, 6.0, 6.0])) is None
    assert grey_patch(frame, np.array([190.0, 40.0, 199.0, 50.0])) is None
    assert grey_patch(frame, np.array([math.nan, 40.0, 110.0, 60.0])) is None


def test_a_decoded_frame_gives_its_luma():
    y = np.zeros((100, 200), np.uint8)
    y[40:60, 90:110] = 180
    yuv = YuvImage(y, np.full((50, 100), 128, np.uint8), np.full((50, 100), 128, np.uint8))
    patch = grey_patch(yuv, np.array([96.0, 46.0, 104.0, 54.0]))
    assert patch is not None and patch.min() == pytest.approx(180, abs=1)


def test_each_sighting_is_compared_with_its_object_a_second_earlier():
    rng = np.random.default_rng(3)
    memory = LookMemory(lag_s=1.0, tolerance_s=0.25)
    changes = []
    for k in range(61):  # 2 s at 30 frames a second, the arm turning once a second
        t = k / 30
        changes.append(memory.change(7, t, blob(8, 8, 2 * np.pi * t / 1.5, rng)))
    assert all(c is None for c in changes[:30])  # nothing a second old yet
    assert all(c is not None and c > 0.15 for c in changes[30:])
    # another object has its own memory; a missed frame (no patch) neither counts nor breaks it
    assert memory.change(8, 2.0, blob(8, 8, 0.0, rng)) is None
    assert memory.change(7, 2.04, None) is None
    steady = LookMemory()
    looks = [steady.change(1, k / 30, blob(8, 8, 0.0, rng)) for k in range(45)]
    assert all(c < 0.05 for c in looks[30:])


def test_old_patches_and_objects_out_of_sight_are_forgotten():
    rng = np.random.default_rng(4)
    memory = LookMemory(lag_s=1.0, tolerance_s=0.25)
    for k in range(300):
        memory.change(1, k / 30, blob(8, 8, 0.0, rng))
    assert len(memory._patches[1]) <= 1.25 * 30 + 2
    memory.change(2, 10.0, blob(8, 8, 0.0, rng))
    memory.forget_before(10.5)  # object 1 last seen at 9.97 s, object 2 at 10 s: both kept
    assert set(memory._patches) == {1, 2}
    memory.forget_before(11.23)
    assert set(memory._patches) == {2}
    memory.forget_before(11.26)
    assert memory._patches == {}
    memory.change(2, 10.0, blob(8, 8, 0.0, rng))
    # a gap longer than the tolerance: the old patch is no comparison
    assert memory.change(2, 12.0, blob(8, 8, 1.0, rng)) is None
