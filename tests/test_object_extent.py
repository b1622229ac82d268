"""The object under a detection measured against its surroundings: a boat far larger than the
head's box is measured whole, a small blob small; mixed backgrounds, objects cut by the frame
or larger than the largest window, and bad boxes give no measurement rather than a wrong one."""

import cv2
import numpy as np
import pytest
from test_yuv import yuv_of

from sarmission.perception.extent import fit_boxes, object_extent

H, W = 720, 960
WATER = (110, 90, 40)  # BGR, a dark blue-green sea


def sea(seed: int = 0, h: int = H, w: int = W) -> np.ndarray:
    """Water with pixel noise and soft swell, as a nadir camera sees it."""
    rng = np.random.default_rng(seed)
    image = np.empty((h, w, 3), np.float32)
    image[:] = WATER
    swell = cv2.GaussianBlur(rng.normal(0, 6, (h, w)).astype(np.float32), (0, 0), 4)
    image += swell[..., None] * 3 + rng.normal(0, 3, (h, w, 3))
    return np.clip(image, 0, 255).astype(np.uint8)


def centred(box, side: float = 16.0):
    """A head-sized detection box around the centre of ``box``."""
    cx, cy = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2
    return (cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2)


def test_a_boat_is_measured_whole_from_a_box_on_part_of_it():
    image = sea()
    hull = (400, 330, 560, 380)  # 160 x 50 px
    cv2.rectangle(image, hull[:2], (hull[2] - 1, hull[3] - 1), (235, 235, 240), -1)
    cv2.rectangle(image, (450, 340), (500, 370), (60, 60, 70), -1)  # a dark cabin on deck
    found = object_extent(image, (470, 345, 486, 361))  # the head boxed the cabin
    assert found is not None
    assert found == pytest.approx(np.array(hull, float), abs=2.0)


def test_a_small_swimmer_is_measured_small():
    image = sea(1)
    cv2.circle(image, (300, 200), 3, (40, 120, 250), -1)  # an orange cap, 7 px
    found = object_extent(image, centred((297, 197, 304, 204)))
    assert found is not None
    width, height = found[2] - found[0], found[3] - found[1]
    assert 5 <= width <= 9 and 5 <= height <= 9


def test_a_gray_picture_is_measured_like_its_colour():
    image = sea(2)
    cv2.rectangle(image, (200, 200), (299, 239), (250, 250, 250), -1)
    gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    assert object_extent(gray, (240, 212, 256, 228)) == pytest.approx(
        np.array([200, 200, 300, 240], float), abs=2.0
    )


def test_the_decoders_planes_give_the_same_extent_as_bgr():
    image = sea(3)
    cv2.rectangle(image, (500, 100), (619, 149), (230, 230, 235), -1)
    box = (552, 117, 568, 133)
    from_bgr = object_extent(image, box)
    from_yuv = object_extent(yuv_of(image), box)
    assert from_bgr is not None and from_yuv is not None
    assert from_yuv == pytest.approx(from_bgr, abs=2.0)


def test_the_window_grows_until_the_object_fits():
    image = sea(4)
    cv2.rectangle(image, (100, 300), (699, 379), (230, 230, 235), -1)  # 600 px: a ship
    found = object_extent(image, (392, 332, 408, 348))
    assert found == pytest.approx(np.array([100, 300, 700, 380], float), abs=2.0)
    # no window large enough: the object's size is unknown, not the window's
    assert object_extent(image, (392, 332, 408, 348), max_half_px=128) is None


def test_an_object_cut_by_the_frame_edge_is_not_measured():
    image = sea(5)
    cv2.rectangle(image, (0, 300), (129, 349), (230, 230, 235), -1)
    assert object_extent(image, (60, 317, 76, 333)) is None


def test_a_mixed_background_is_not_measured():
    image = sea(6)
    image[:, 512:] = (120, 170, 190)  # a sandy shore beside the water, in every window
    cv2.circle(image, (480, 360), 4, (30, 30, 200), -1)
    assert object_extent(image, centred((476, 356, 484, 364))) is None
    image[:, 512:] = sea(6)[:, 512:]  # the same swimmer in open water
    assert object_extent(image, centred((476, 356, 484, 364))) is not None


def test_nothing_that_stands_out_is_not_measured():
    assert object_extent(sea(7), (300, 300, 316, 316)) is None


@pytest.mark.parametrize(
    "box",
    [
        (np.nan, 10.0, 20.0, 30.0),
        (10.0, 10.0, 10.0, 30.0),  # empty
        (30.0, 10.0, 20.0, 30.0),  # reversed
        (W + 5.0, 10.0, W + 20.0, 30.0),  # outside
        (1.0, 2.0, 3.0),  # not a box
    ],
)
def test_a_bad_box_is_not_measured(box):
    assert object_extent(sea(8), box) is None


def test_a_picture_that_is_not_uint8_is_refused():
    with pytest.raises(ValueError, match="uint8"):
        object_extent(sea(9).astype(np.float32), (300, 300, 316, 316))


def test_a_person_lying_40_px_long_gets_a_box_of_their_length():
    image = sea(7)
    body = (300, 300, 340, 312)  # 40 x 12 px, on their back
    cv2.rectangle(image, body[:2], (body[2] - 1, body[3] - 1), (60, 110, 230), -1)
    torso = np.array([[306, 298, 322, 314]], np.float32)  # the head's 16 px box
    fitted, replaced = fit_boxes(image, torso, max_side_px=64)
    assert replaced == 1
    assert fitted[0] == pytest.approx(np.array(body, np.float32), abs=2.0)
    assert torso[0] == pytest.approx([306, 298, 322, 314])  # the input is not changed


@pytest.mark.parametrize("length", [90, 160])
def test_fitting_keeps_the_heads_box_where_the_object_is_longer_than_the_cap(length: int):
    image = sea(8)
    left = 478 - length // 2
    cv2.rectangle(image, (left, 340), (left + length - 1, 369), (235, 235, 240), -1)  # a hull
    box = np.array([[470, 345, 486, 361]], np.float32)
    fitted, replaced = fit_boxes(image, box, max_side_px=64)
    assert replaced == 0
    np.testing.assert_array_equal(fitted, box)


def test_fitting_never_shrinks_a_box_nor_moves_it_off_its_centre():
    image = sea(9)
    cv2.circle(image, (200, 200), 3, (40, 120, 250), -1)  # a 7 px cap inside a 16 px box
    cv2.rectangle(image, (400, 400), (439, 409), (250, 250, 250), -1)  # 40 px, a box on its end
    boxes = np.array([[192, 192, 208, 208], [434, 397, 450, 413]], np.float32)
    fitted, replaced = fit_boxes(image, boxes, max_side_px=64)
    assert replaced == 0
    np.testing.assert_array_equal(fitted, boxes)


def test_fitting_no_boxes_gives_none():
    fitted, replaced = fit_boxes(sea(10), np.zeros((0, 4), np.float32), max_side_px=64)
    assert fitted.shape == (0, 4) and replaced == 0
