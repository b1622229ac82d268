"""``sarmission sim replay``: recorded footage through the simulated vehicle and camera.

A 20-frame 320x180 clip rendered by the simulator (exact per-frame ``meta`` telemetry and ground
truth) is replayed: the flight that follows its meta, the vehicle streaming it over real UDP, the
footage renderer against OpenCV's own decoding, and the command end to end."""

from __future__ import annotations

import copy
import math
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from conftest import free_udp_port
from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.cli import main
from sarmission.data.coco_video import FrameTelemetry, read_coco_video
from sarmission.geo.wgs84 import ned_to_geodetic
from sarmission.mavlink.connection import mavlink2_connection
from sarmission.mission.targets import distance_m
from sim.footage import EndOfFootage, FootageRenderer
from sim.generate import generate_sequence
from sim.meta_flight import MetaFlight, NoUsableMeta
from sim.scenarios import preset
from sim.vehicle import SimVehicle

FPS = 10.0
FRAMES = 20


def angle_diff_deg(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


@pytest.fixture(scope="module")
def clip(tmp_path_factory) -> Path:
    chosen = preset("maritime_val")
    out = tmp_path_factory.mktemp("clip")
    return generate_sequence(
        chosen.scenario,
        chosen.mission,
        FRAMES,
        size=(320, 180),
        seed=chosen.scenario.seed,
        out_dir=out,
        fps=FPS,
        progress=False,
        name="clip",
        start_s=5.0,
    )


@pytest.fixture(scope="module")
def dataset(clip):
    return read_coco_video(clip)


@pytest.fixture(scope="module")
def head_checkpoint(tmp_path_factory) -> Path:
    from sarmission.perception.head import MiteHead
    from sarmission.perception.runtime import save_head_checkpoint

    return save_head_checkpoint(MiteHead().eval(), tmp_path_factory.mktemp("model") / "head.pt")


def decoded_frames(path: Path) -> list[np.ndarray]:
    capture = cv2.VideoCapture(str(path))
    frames = []
    while True:
        ok, image = capture.read()
        if not ok:
            break
        frames.append(image)
    capture.release()
    return frames


def check_against_meta(flight: MetaFlight, images) -> None:
    t0 = images[0].telemetry.time
    for im in images:
        m = im.telemetry
        s = flight.state_at(m.time - t0)
        lat, lon, h = ned_to_geodetic(*s.position_ned, *flight.home)
        assert distance_m((float(lat), float(lon)), (m.latitude, m.longitude)) < 0.5
        assert abs((float(h) - flight.home[2]) - m.altitude) < 0.5
        assert angle_diff_deg(math.degrees(s.yaw), m.compass_heading) < 1.0
        # the meta's pitch is SeaDronesSee's: positive below the horizon
        assert abs(math.degrees(s.gimbal_pitch) + m.gimbal_pitch) < 1.0
        assert angle_diff_deg(math.degrees(s.yaw + s.gimbal_yaw), m.gimbal_heading) < 1.0


def test_meta_flight_reproduces_the_meta_and_interpolates_gaps(dataset):
    images = dataset.video_images(1)
    flight = MetaFlight(dataset, 1)
    assert flight.time_source == "meta time"
    assert flight.home[:2] == (images[0].telemetry.latitude, images[0].telemetry.longitude)
    assert flight.mission.area.home[:2] == flight.home[:2]
    # Meta heights are above take-off: the note names the take-off altitude it assumes.
    assert flight.home[2] == flight.mission.area.home_alt_m
    assert f"take-off at {flight.home[2]:g} m above sea level (the mission's home_alt_m)" in (
        flight.note
    )
    given = MetaFlight(dataset, 1, home=(*flight.home[:2], 812.0))
    assert "take-off at 812 m above sea level (given)" in given.note
    assert given.position_ned[0, 2] == pytest.approx(flight.position_ned[0, 2], abs=1e-6)
    assert abs(flight.survey_duration - (FRAMES - 1) / FPS) < 1e-6
    check_against_meta(flight, images)
    # The survey moves: the recorded positions are not all the same place.
    span = np.ptp(flight.position_ned[:, :2], axis=0)
    assert np.hypot(*span) > 5.0

    # Frames without some meta values: interpolated from their neighbours.
    gappy = copy.deepcopy(dataset)
    for im in gappy.video_images(1)[3:15:3]:
        im.telemetry.latitude = None
        im.telemetry.compass_heading = None
        im.telemetry.time = None
    check_against_meta(MetaFlight(gappy, 1), images)

    empty = copy.deepcopy(dataset)
    for im in empty.images:
        im.telemetry = FrameTelemetry()
    with pytest.raises(NoUsableMeta):
        MetaFlight(empty, 1)


def test_vehicle_streams_the_footage_position_and_denies_reposition(dataset):
    images = dataset.video_images(1)
    flight = MetaFlight(dataset, 1, loop=False)
    port = free_udp_port()
    vehicle = SimVehicle(f"udpin:127.0.0.1:{port}", flight=flight).start()
    conn = mavlink2_connection(f"udpout:127.0.0.1:{port}", 255, 190)
    try:
        conn.mav.heartbeat_send(
            M.MAV_TYPE_ONBOARD_CONTROLLER, M.MAV_AUTOPILOT_INVALID, 0, 0, M.MAV_STATE_ACTIVE
        )
        times = np.array([im.telemetry.time for im in images]) - images[0].telemetry.time
        lats = np.array([im.telemetry.latitude for im in images])
        lons = np.array([im.telemetry.longitude for im in images])
        heads = np.unwrap(np.array([im.telemetry.compass_heading for im in images]), period=360)
        checked = 0
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline and checked < 10:
            msg = conn.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=0.1)
            if msg is None:
                continue
            t = msg.time_boot_ms / 1000.0
            if t > times[-1]:
                break
            expected = (float(np.interp(t, times, lats)), float(np.interp(t, times, lons)))
            assert distance_m((msg.lat / 1e7, msg.lon / 1e7), expected) < 0.5, t
            assert angle_diff_deg(msg.hdg / 100.0, float(np.interp(t, times, heads))) < 1.0
            checked += 1
        assert checked >= 5
        conn.mav.command_long_send(
            1, 1, M.MAV_CMD_DO_REPOSITION, 0, -1, 1, 0, math.nan, lats[0], lons[0], 50.0
        )
        ack = conn.recv_match(type="COMMAND_ACK", blocking=True, timeout=3.0)
        assert ack is not None and ack.command == M.MAV_CMD_DO_REPOSITION
        assert ack.result == M.MAV_RESULT_DENIED
        assert vehicle.statustexts == []
    finally:
        conn.close()
        vehicle.stop()


def test_footage_renderer_matches_opencv_and_ends_or_loops(clip, dataset, tmp_path):
    video = clip.parent / "clip.mp4"
    reference = decoded_frames(video)
    assert len(reference) == FRAMES
    renderer = FootageRenderer(clip)
    assert renderer.fps == FPS and renderer.has_ground_truth
    by_index = {im.frame_index: im.id for im in dataset.images}
    boxes = dataset.annotations_by_image()
    for index in (0, 1, 1, 2, 5, 6, 13, 19):  # non-decreasing, with repeats and jumps
        image, annotations = renderer.render(index / FPS + 0.03, None)
        assert np.array_equal(image, reference[index]), index
        expected = sorted(a.track_id for a in boxes[by_index[index]])
        assert sorted(a.track_id for a in annotations) == expected
        for a, b in zip(
            sorted(annotations, key=lambda a: a.track_id),
            sorted(boxes[by_index[index]], key=lambda a: a.track_id),
            strict=True,
        ):
            x, y, w, h = b.bbox
            assert a.bbox_xyxy == pytest.approx((x, y, x + w, y + h))
            assert (a.lat, a.lon) == (b.gt_lat, b.gt_lon)
    assert any(a.is_target for anns in renderer._gt.values() for a in anns)
    with pytest.raises(EndOfFootage):
        renderer.render(FRAMES / FPS + 0.03, None)
    renderer.close()

    looped = FootageRenderer(video, loop=True, start_s=100.0)
    assert not looped.has_ground_truth
    image, annotations = looped.render(100.0 + 18 / FPS + 0.01, None)
    assert np.array_equal(image, reference[18]) and annotations == []
    image, _ = looped.render(100.0 + (FRAMES + 3) / FPS + 0.01, None)
    assert np.array_equal(image, reference[3])
    looped.close()

    folder = tmp_path / "frames"
    folder.mkdir()
    for i, frame in enumerate(reference[:5]):
        cv2.imwrite(str(folder / f"f{i}.png"), frame)
    still = FootageRenderer(folder, fps=2.0)
    assert np.array_equal(still.render(1.6, None)[0], reference[3])
    with pytest.raises(EndOfFootage):
        still.render(2.6, None)


def replay_args(footage: Path, tmp_path: Path, head: Path, *extra: str) -> list[str]:
    return [
        "sim",
        "replay",
        str(footage),
        "--connect",
        f"udp:127.0.0.1:{free_udp_port()}",
        "--model",
        str(head),
        "--alerts-db",
        str(tmp_path / "alerts.db"),
        "--connect-timeout",
        "5",
        *extra,
    ]


def frames_processed(out: str) -> int:
    line = next(ln for ln in out.splitlines() if ln.startswith("frames processed:"))
    return int(line.split(":")[1].split(",")[0])


def test_replay_command_runs_the_controller_on_the_annotated_clip(
    clip, head_checkpoint, tmp_path, capsys
):
    rrd = tmp_path / "replay.rrd"
    code = main(replay_args(clip, tmp_path, head_checkpoint, "--rerun", "save", str(rrd)))
    out = capsys.readouterr().out
    assert code == 0, out
    assert "timed by meta time" in out
    assert "frame source ended" in out
    assert frames_processed(out) >= 5, out
    assert "people in view" in out  # ground truth scored the run
    assert rrd.is_file() and rrd.stat().st_size > 0
    assert (tmp_path / "alerts.db").is_file()


def test_plain_video_replays_with_the_synthetic_flight(clip, head_checkpoint, tmp_path, capsys):
    code = main(replay_args(clip.parent / "clip.mp4", tmp_path, head_checkpoint))
    out = capsys.readouterr().out
    assert code == 0, out
    assert "synthetic flight" in out
    assert "frame source ended" in out
    assert frames_processed(out) >= 5, out
    assert "people in view" not in out
