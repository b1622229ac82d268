"""YUV 4:2:0 pictures: conversion to BGR (whole and per pixel), gray, chroma, and what the
perception stages make of them compared with the same picture as BGR."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from sarmission.alerts.thumbnail import crop_thumbnail
from sarmission.data.frames import Frame
from sarmission.perception.chroma import chroma_anomaly, chroma_if_wanted
from sarmission.perception.crops import motion_enhanced_crops, roi_align
from sarmission.perception.pyramid import half_resolution
from sarmission.perception.types import MotionMaps
from sarmission.yuv import YuvImage


def yuv_of(bgr: np.ndarray) -> YuvImage:
    """``bgr`` (even size) as limited-range BT.601 4:2:0, by OpenCV."""
    h, w = bgr.shape[:2]
    i420 = cv2.cvtColor(bgr, cv2.COLOR_BGR2YUV_I420)
    chroma = i420[h:].reshape(-1)
    q = h * w // 4
    return YuvImage(
        i420[:h], chroma[:q].reshape(h // 2, w // 2), chroma[q:].reshape(h // 2, w // 2)
    )


def smooth_scene(h: int = 96, w: int = 128, seed: int = 0) -> np.ndarray:
    """A sea-like BGR picture whose colour varies slowly (4:2:0 keeps it) with an orange patch."""
    rng = np.random.default_rng(seed)
    coarse = rng.integers(40, 200, (h // 16, w // 16, 3), dtype=np.uint8)
    image = cv2.resize(coarse, (w, h), interpolation=cv2.INTER_CUBIC)
    image[40:48, 64:72] = (0, 128, 255)  # an orange life jacket
    return image


def test_planes_are_checked() -> None:
    y = np.zeros((6, 9), np.uint8)
    YuvImage(y, np.zeros((3, 5), np.uint8), np.zeros((3, 5), np.uint8))  # odd width: ceil
    with pytest.raises(ValueError, match="4:2:0"):
        YuvImage(y, np.zeros((3, 4), np.uint8), np.zeros((3, 5), np.uint8))
    with pytest.raises(ValueError, match="uint8"):
        YuvImage(y.astype(np.float32), np.zeros((3, 5), np.uint8), np.zeros((3, 5), np.uint8))


def test_known_colours_convert_to_their_bgr() -> None:
    """Limited-range BT.601 codes of black, white, red, green and blue (and full-range ones)."""
    codes = {  # (Y, U, V) -> BGR
        (16, 128, 128): (0, 0, 0),
        (235, 128, 128): (255, 255, 255),
        (81, 90, 240): (0, 0, 255),
        (145, 54, 34): (0, 255, 0),
        (41, 240, 110): (255, 0, 0),
    }

    def flat(y: int, u: int, v: int, full_range: bool = False) -> YuvImage:
        return YuvImage(
            np.full((2, 2), y, np.uint8),
            np.full((1, 1), u, np.uint8),
            np.full((1, 1), v, np.uint8),
            full_range,
        )

    for (y, u, v), bgr in codes.items():
        image = flat(y, u, v)
        got = image.bgr[0, 0].astype(int)
        np.testing.assert_allclose(got, bgr, atol=2, err_msg=f"YUV {(y, u, v)}")
        np.testing.assert_array_equal(image.bgr_at(np.array([1]), np.array([1]))[0], got)
    full = flat(76, 85, 255, full_range=True)
    np.testing.assert_allclose(full.bgr[0, 0].astype(int), (0, 0, 255), atol=2)
    assert full.to_gray(np.array([[76]], np.uint8))[0, 0] == 76  # full range: Y is the gray


def test_bgr_at_is_the_whole_conversion_at_those_pixels() -> None:
    rng = np.random.default_rng(1)
    h, w = 37, 51  # odd: the last chroma sample covers one row / column
    image = YuvImage(
        rng.integers(0, 256, (h, w), dtype=np.uint8),
        rng.integers(0, 256, (19, 26), dtype=np.uint8),
        rng.integers(0, 256, (19, 26), dtype=np.uint8),
    )
    rows, cols = rng.integers(0, h, 500), rng.integers(0, w, 500)
    np.testing.assert_array_equal(image.bgr_at(rows, cols), image.bgr[rows, cols])
    assert image.bgr.shape == (h, w, 3) and image.bgr is image.bgr  # converted once


def test_round_trip_through_opencv_and_gray() -> None:
    bgr = smooth_scene()
    image = yuv_of(bgr)
    diff = image.bgr.astype(int) - bgr
    assert np.abs(diff).mean() < 3  # OpenCV rounds, we truncate; 4:2:0 blurs colour edges
    gray = image.to_gray(image.y).astype(int) - cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
    assert np.abs(gray).mean() < 1.0 and np.abs(gray).max() <= 3


def test_crcb_is_opencvs_cr_and_cb_at_half_resolution() -> None:
    bgr = smooth_scene()
    image = yuv_of(bgr)
    ycrcb = cv2.cvtColor(half_resolution(bgr), cv2.COLOR_BGR2YCrCb).astype(np.float32)
    cr, cb = image.to_crcb(image.u, image.v)
    assert np.abs(cr - ycrcb[..., 1]).mean() < 2
    assert np.abs(cb - ycrcb[..., 2]).mean() < 2
    assert np.abs(cb - ycrcb[..., 1]).mean() > 10  # the two are told apart


def test_crops_of_a_yuv_picture_are_those_of_its_bgr() -> None:
    """Only the windows under the boxes are converted, to exactly what the whole picture gives."""
    image = yuv_of(smooth_scene())
    h, w = image.height, image.width
    maps = np.random.default_rng(2).normal(size=(5, h // 2, w // 2)).astype(np.float32)
    motion = MotionMaps(2, *maps)
    boxes = np.array([[60, 36, 76, 52], [-5, -5, 11, 11], [120, 80, 140, 100]], np.float32)
    polarity = np.array([1.0, 0.0, 1.0], np.float32)
    np.testing.assert_array_equal(
        motion_enhanced_crops(image, motion, boxes, polarity),
        motion_enhanced_crops(image.bgr, motion, boxes, polarity),
    )
    np.testing.assert_array_equal(
        roi_align(image, boxes, sampling_ratio=2), roi_align(image.bgr, boxes, sampling_ratio=2)
    )


def test_chroma_map_of_the_planes_finds_what_the_bgr_map_finds() -> None:
    bgr = smooth_scene()
    image = yuv_of(bgr)
    from_bgr, from_yuv = chroma_anomaly(bgr), chroma_anomaly(image)
    assert from_yuv.shape == from_bgr.shape == (96 // 8, 128 // 8)
    peak = np.unravel_index(np.argmax(from_yuv), from_yuv.shape)
    assert peak == np.unravel_index(np.argmax(from_bgr), from_bgr.shape) == (5, 8)
    assert from_yuv[peak] == pytest.approx(from_bgr[peak], rel=0.25)
    assert chroma_if_wanted(image, wanted=True).shape == from_yuv.shape
    assert chroma_if_wanted(image, wanted=False) is None


def test_thumbnails_of_the_planes_are_those_of_their_bgr() -> None:
    image = yuv_of(smooth_scene())
    for centre in ((68.0, 44.0), (3.0, 90.0), (126.5, 1.0)):  # inside, and cut by the edges
        assert crop_thumbnail(image, centre, side=32) == crop_thumbnail(image.bgr, centre, side=32)


def test_a_restamped_frame_keeps_its_planes_unconverted() -> None:
    image = yuv_of(smooth_scene())
    frame = Frame(3, 0.1, yuv=image)
    moved = frame.restamped(5.0)
    assert (moved.index, moved.timestamp_s) == (3, 5.0)
    assert moved.image is image and moved.yuv is image and "bgr" not in vars(image)
    assert moved.image_bgr is image.bgr  # converted on first use, once
    assert Frame(4, 0.2).image is None and Frame(4, 0.2).image_bgr is None
