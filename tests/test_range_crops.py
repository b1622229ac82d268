"""Crops sized to the person from the camera's pose: the geometry, the detector, a dataset."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from conftest import render_narrow_sea

from sarmission.data.coco_video import FrameTelemetry, ImageRecord, Video, VideoDataset
from sarmission.geo.camera import CameraIntrinsics
from sarmission.geo.geolocate import PlatformPose
from sarmission.geo.person_pixels import person_pixels
from sarmission.mission.range_crops import dataset_person_px, pose_person_px
from sarmission.perception.crops import motion_enhanced_crops
from sarmission.perception.mitenet import (
    MAX_RANGE_FACTOR,
    MiteNet,
    build_head_runtime,
    scaled_boxes,
)

LENS = CameraIntrinsics.from_hfov(3840, 2160, 75.0)


def _nadir(height_m: float = 50.0) -> PlatformPose:
    return PlatformPose(lat=54.0, lon=10.0, rel_alt_m=height_m, roll=0.0, pitch=0.0, yaw=0.3)


def test_a_person_spans_focal_times_size_over_the_slant_range():
    centre = np.array([[LENS.cx, LENS.cy]])
    np.testing.assert_allclose(
        person_pixels(centre, LENS, _nadir(50.0), 0.45), 0.45 * LENS.fx / 50.0, rtol=1e-9
    )
    # halfway to the corner: the ray is longer by 1 / cos of its angle from the axis
    u, v = LENS.cx + 900.0, LENS.cy - 500.0
    x, y = (u - LENS.cx) / LENS.fx, (v - LENS.cy) / LENS.fy
    slant = 50.0 * math.sqrt(1.0 + x * x + y * y)
    np.testing.assert_allclose(
        person_pixels(np.array([[u, v]]), LENS, _nadir(50.0), 0.45),
        0.45 * LENS.fx / slant,
        rtol=1e-9,
    )
    # the ground plane 20 m below home: 70 m of range
    np.testing.assert_allclose(
        person_pixels(centre, LENS, _nadir(50.0), 0.45, ground_below_home_m=20.0),
        0.45 * LENS.fx / 70.0,
        rtol=1e-9,
    )


def test_no_size_where_the_pixel_sees_no_ground():
    level = PlatformPose(
        lat=54.0,
        lon=10.0,
        rel_alt_m=50.0,
        roll=0.0,
        pitch=0.0,
        yaw=0.0,
        gimbal_rpy=(0.0, math.radians(-10.0), 0.0),
    )
    rows = np.array([[LENS.cx, 0.0], [LENS.cx, LENS.height - 1.0]])
    sky, sea = person_pixels(rows, LENS, level, 0.45)
    assert math.isnan(sky) and sea > 0.0  # top row above the horizon, bottom row on the sea
    for pose, below in ((_nadir(0.0), 0.0), (_nadir(10.0), -12.0), (_nadir(math.nan), 0.0)):
        assert np.isnan(person_pixels(rows, LENS, pose, 0.45, below)).all()
    assert person_pixels(np.zeros((0, 2)), LENS, _nadir(), 0.45).shape == (0,)


def test_only_a_current_pose_sizes_crops():
    assert pose_person_px(LENS, _nadir(), 0.0) is None  # off
    assert pose_person_px(LENS, None, 0.45) is None
    assert pose_person_px(LENS, "stale", 0.45) is None
    assert pose_person_px(LENS, _nadir(), 0.45, ground_below_home_m=None) is None
    sized = pose_person_px(LENS, _nadir(40.0), 0.45)
    assert sized is not None
    np.testing.assert_allclose(
        sized(np.array([[LENS.cx, LENS.cy]])), 0.45 * LENS.fx / 40.0, rtol=1e-9
    )


@pytest.fixture(scope="module")
def sea_frames(tmp_path_factory: pytest.TempPathFactory) -> list[np.ndarray]:
    folder = render_narrow_sea(tmp_path_factory.mktemp("sea"), frames=8)
    return [cv2.imread(str(path)) for path in sorted(folder.glob("*.jpg"))]


def _scores(net: MiteNet, frame: np.ndarray, result, factor: float, shift: float) -> np.ndarray:
    """Best-class probability of every proposal's crop grown by ``factor``, logits less
    ``shift``."""
    boxes = scaled_boxes(result.proposals.boxes, factor)
    logits, _ = net.head.predict(
        motion_enhanced_crops(frame, result.motion, boxes, result.proposals.polarity)
    )
    return (1.0 / (1.0 + np.exp(-(logits.astype(np.float64) - shift)))).max(axis=1)


def test_sized_crops_are_the_grown_boxes_scored_with_their_shift(sea_frames):
    """Every proposal where a person spans 2 S is cropped at 2 S and scored with its logits
    lowered by one doubling's shift; where they span less than S, or nothing is known, the
    crop is the proposal's box and its score the head's."""
    options = {"ds": 2, "topn": 25, "score_threshold": 0.0, "nms_iou": None, "fit_boxes": False}
    shipped = build_head_runtime(None, "onnx")
    net = MiteNet(shipped, crop_scales=(1.0,), range_shift_per_octave=0.5, **options)

    def twice(centres: np.ndarray) -> np.ndarray:
        return np.full(len(centres), 2.0 * net.box_size)

    def mixed(centres: np.ndarray) -> np.ndarray:  # unknown on the left half, small on the right
        return np.where(centres[:, 0] < 480.0, np.nan, 0.5 * net.box_size)

    grown_seen = 0
    for people, factor, shift in ((twice, 2.0, 0.5), (mixed, 1.0, 0.0), (None, 1.0, 0.0)):
        net.reset()
        for i, frame in enumerate(sea_frames):
            result = net.process(frame, i / 30.0, person_px=people)
            if i < 3:
                continue
            expected = _scores(net, frame, result, factor, shift)
            np.testing.assert_allclose(result.detections.scores, expected, atol=1e-5)
            side = result.detections.boxes[:, 2:] - result.detections.boxes[:, :2]
            grown_seen += int(factor == 2.0 and (side.max(axis=1) > net.box_size).any())
    assert grown_seen  # the grown crops box what they hold, larger than S somewhere


def test_crop_factors_are_bounded_and_checked():
    net = MiteNet(build_head_runtime(None, "onnx"), crop_scales=(1.0,))
    boxes = np.array([[0, 0, 16, 16], [10, 10, 26, 26], [5, 5, 21, 21], [0, 0, 16, 16]], float)
    sizes = np.array([4.0, 48.0, 1e6, np.inf])
    np.testing.assert_allclose(
        net.range_factors(boxes, lambda c: sizes), [1.0, 3.0, MAX_RANGE_FACTOR, 1.0]
    )
    np.testing.assert_allclose(net.range_factors(boxes, None), 1.0)
    with pytest.raises(ValueError, match="person_px gave 2 sizes for 4 centres"):
        net.range_factors(boxes, lambda c: sizes[:2])
    for bad in (-0.1, math.nan, math.inf):
        with pytest.raises(ValueError, match="range_shift_per_octave"):
            MiteNet(build_head_runtime(None, "onnx"), range_shift_per_octave=bad)


def _dataset(meta: list[dict | None], hfov: float | None) -> VideoDataset:
    extra = {} if hfov is None else {"hfov_deg": hfov}
    images = []
    for i, m in enumerate(meta):
        telemetry = FrameTelemetry() if m is None else FrameTelemetry(**m)
        images.append(
            ImageRecord(
                id=i + 1,
                file_name=f"{i}.jpg",
                height=2160,
                width=3840,
                video_id=1,
                frame_index=i,
                meta=m,
                telemetry=telemetry,
            )
        )
    return VideoDataset(
        images=images, annotations=[], categories=[], videos=[Video(1, "clip", extra)]
    )


def test_a_dataset_frame_sizes_crops_from_its_meta_and_lens():
    down = {
        "latitude": 54.0,
        "longitude": 10.0,
        "altitude": 40.0,
        "gimbal_pitch": 90.0,  # SeaDronesSee's depression: straight down
        "compass_heading": 30.0,
    }
    data = _dataset([down, None, {**down, "altitude": 0.0}], hfov=75.0)
    of = dataset_person_px(data, 0.45)
    sized = of(data.images[0])
    assert sized is not None
    np.testing.assert_allclose(
        sized(np.array([[LENS.cx, LENS.cy]])), 0.45 * LENS.fx / 40.0, rtol=1e-6
    )
    assert of(data.images[1]) is None  # no meta
    assert of(data.images[2]) is None  # not in the air
    assert dataset_person_px(data, 0.0)(data.images[0]) is None  # off
    no_lens = _dataset([down], hfov=None)
    assert dataset_person_px(no_lens, 0.45)(no_lens.images[0]) is None
    given = dataset_person_px(no_lens, 0.45, hfov_deg=75.0)(no_lens.images[0])
    assert given is not None


class _RecordingDetector:
    """A detector that finds nothing and keeps the person sizes it was asked to crop for."""

    classes = ("swimmer",)

    def __init__(self) -> None:
        self.asked: list[float | None] = []
        self.per_stage_ms: dict[str, float] = {}

    def process(self, frame, timestamp: float, person_px=None):
        from sarmission.perception.types import Detections, FrameResult, Proposals

        size = None if person_px is None else float(person_px(np.array([[480.0, 270.0]]))[0])
        self.asked.append(size)
        return FrameResult(timestamp, Detections(), Proposals(), None)

    def reset(self) -> None:
        pass


@pytest.mark.parametrize("person_m", [0.0, 0.45])
def test_live_crops_are_sized_from_the_adopted_autopilot_s_current_pose(tmp_path, person_m):
    """With ``[detector] person_m`` the controller hands the detector the person's size at the
    camera's current pose (a nadir camera 60 m up: ``person_m * f / 60`` at the centre); before
    home and position are known, once telemetry is stale, or with it off: nothing."""
    from sarmission.alerts.store import AlertStore
    from sarmission.mavlink.telemetry import TelemetryBuffer
    from sarmission.mission.config import load_mission
    from sarmission.mission.controller import MissionController

    mission = load_mission(
        overrides={
            "camera.width": 960,
            "camera.height": 540,
            "camera.hfov_deg": 30.0,
            "detector.person_m": person_m,
            "name": "sized",
        }
    )
    buffer = TelemetryBuffer(stale_after_s=mission.telemetry.stale_after_s)
    detector = _RecordingDetector()
    ctl = MissionController(
        mission, detector, buffer, AlertStore(tmp_path / "a.db"), console=lambda s: None
    )
    frame = np.full((540, 960, 3), 90, np.uint8)
    ctl.process(0, 0.0, frame)  # no home, no position
    buffer.set_home(*mission.area.home)
    for t in np.arange(0.0, 2.0, 0.05):
        buffer.push_position(float(t), *mission.area.home[:2], 60.0)
        buffer.push_attitude(float(t), 0.0, 0.0, 0.0)
    ctl.process(1, 1.0, frame)
    ctl.process(2, 1.0 + 10.0 * mission.telemetry.stale_after_s, frame)  # stale by then
    if not person_m:
        assert detector.asked == [None, None, None]
        return
    focal = mission.camera.intrinsics().fx
    assert detector.asked[0] is None and detector.asked[2] is None
    assert detector.asked[1] == pytest.approx(person_m * focal / 60.0, rel=1e-3)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--person-m", "-1"], "--person-m must be in"),
        (["--person-m", "nan"], "--person-m must be in"),
        (["--person-m", "0.45", "--range-shift", "-0.5"], "--range-shift must be in"),
        (["--person-m", "0.45", "--hfov", "180"], "--hfov must be in"),
        (["--person-m", "0.45", "--detections", "d.json"], "--person-m sizes the detector"),
        (["--person-m", "0.45", "--sweep"], "--person-m sizes the detector"),
    ],
)
def test_eval_refuses_sizing_options_it_cannot_honour(extra, message):
    from sarmission.cli import build_parser
    from sarmission.commands.eval import _check_args

    args = build_parser().parse_args(["eval", "--annotations", "a.json", *extra])
    with pytest.raises(ValueError, match=message):
        _check_args(args)


def test_eval_sizes_crops_from_the_meta_of_frames_that_have_it(tmp_path, monkeypatch, capsys):
    """``sarmission eval --person-m``: frames of a video with meta and a lens are run with the
    person's size from their pose (40 m straight down: ``0.45 f / 40`` at the centre); frames
    without meta as before; the settings are in the report."""
    import json

    from sarmission.cli import build_parser
    from sarmission.commands import eval as eval_cmd
    from sarmission.data.coco_video import Category, write_coco_video
    from sarmission.evaluation import run_model

    rng = np.random.default_rng(3)
    down = {
        "latitude": 54.0,
        "longitude": 10.0,
        "altitude": 40.0,
        "gimbal_pitch": 90.0,
        "compass_heading": 0.0,
    }
    images = []
    for i in range(6):
        name = f"{i}.png"
        cv2.imwrite(str(tmp_path / name), rng.integers(0, 255, (240, 320, 3), dtype=np.uint8))
        meta = down if i < 3 else None
        images.append(
            ImageRecord(
                id=i + 1,
                file_name=name,
                height=240,
                width=320,
                video_id=1 if i < 3 else 2,
                frame_index=i % 3,
                meta=meta,
            )
        )
    dataset = VideoDataset(
        videos=[Video(1, "low", {"hfov_deg": 60.0}), Video(2, "no meta")],
        images=images,
        annotations=[],
        categories=[Category(1, "swimmer")],
    )
    path = tmp_path / "a.json"
    write_coco_video(dataset, path)
    asked: dict[str, float | None] = {}
    real = run_model.run_mitenet

    def spy(net, data, *args, person_px_of=None, **kwargs):
        for image in data.images:
            sized = None if person_px_of is None else person_px_of(image)
            asked[image.file_name] = (
                None if sized is None else float(sized(np.array([[160, 120]]))[0])
            )
        return real(net, data, *args, person_px_of=person_px_of, **kwargs)

    monkeypatch.setattr(run_model, "run_mitenet", spy)
    argv = ["eval", "--annotations", str(path), "--json", "--no-progress", "--topn", "5"]
    args = build_parser().parse_args([*argv, "--person-m", "0.45", "--range-shift", "0.5"])
    assert eval_cmd.run(args) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["detector"]["person_m"] == 0.45 and report["detector"]["range_shift"] == 0.5
    focal = CameraIntrinsics.from_hfov(320, 240, 60.0).fx
    for i in range(3):
        assert asked[f"{i}.png"] == pytest.approx(0.45 * focal / 40.0, rel=1e-4)
    assert [asked[f"{i}.png"] for i in range(3, 6)] == [None, None, None]
