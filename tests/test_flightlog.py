"""Flight logs read with their ecosystem's libraries (pymavlink, pyulog, exifread), from fixtures
in the real formats: values, each format's angle conventions (checked as the camera's optical
axis in NED once the log is in a TelemetryBuffer), alignment, and bad input."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from flightlog_fixtures import (
    LAT0,
    LON0,
    SITL_BIN,
    START_UTC,
    TlogWriter,
    dji_srt_text,
    px4_ulog,
    write_dji_jpeg,
    write_tlog,
)

from sarmission.flightlog.align import AlignmentError, align_images, align_video
from sarmission.flightlog.detect import open_flight_log, sniff
from sarmission.flightlog.feed import LogFeeder
from sarmission.flightlog.model import ACCURACY, FlightLog, FlightLogError, LogBuilder
from sarmission.geo.frames import rotation_ned_from_camera
from sarmission.geo.geolocate import PlatformPose
from sarmission.mavlink.telemetry import TelemetryBuffer


def optical_axis(log: FlightLog, t: float) -> np.ndarray:
    """The camera's optical axis (unit NED) at log time ``t``, through a TelemetryBuffer."""
    buffer = TelemetryBuffer()
    feeder = LogFeeder(log, buffer)
    feeder.advance(t)
    pose = buffer.lookup(t)
    assert isinstance(pose, PlatformPose), pose
    r = rotation_ned_from_camera(pose.vehicle_rpy, pose.gimbal_rpy, pose.gimbal_frame)
    return r @ np.array([0.0, 0.0, 1.0])


def test_tlog_positions_home_accuracy_trigger_and_mount_signs(tmp_path: Path) -> None:
    path = tmp_path / "flight.tlog"
    write_tlog(path, pitch_deg=-45.0, gimbal_yaw_deg=90.0, yaw_deg=30.0, h_acc_mm=1500)
    log = open_flight_log(path)
    assert log.fmt == "MAVLink tlog" and len(log.positions) == 200
    assert log.home == (LAT0, LON0, 120.0) and log.positions[0].rel_alt_m == 50.0
    assert log.positions[0].gnss_sigma_m == pytest.approx(1.5)
    assert log.utc_offset_s == pytest.approx(START_UTC - 100.0)
    assert log.triggers == [pytest.approx(105.0)]
    # MOUNT_ORIENTATION pitch -45 (below the horizon), yaw_absolute 90 (east)
    axis = optical_axis(log, 110.0)
    assert axis == pytest.approx([0.0, math.sqrt(0.5), math.sqrt(0.5)], abs=1e-6)


def test_tlog_takes_no_camera_for_the_autopilot_and_reads_its_gimbal(tmp_path: Path) -> None:
    """A camera's HEARTBEAT (MAV_AUTOPILOT_GENERIC) heard first was adopted as the autopilot,
    and the log had 'no usable GNSS position'. The live link's rule now decides, and the
    gimbal component of the autopilot's system gives the camera's angles, as live."""
    from pymavlink.dialects.v20 import ardupilotmega as M

    from sarmission.geo.frames import euler_to_quaternion

    flight = tmp_path / "flight.tlog"
    write_tlog(flight, seconds=5.0, pitch_deg=-45.0, gimbal_yaw_deg=90.0, yaw_deg=30.0)
    camera = TlogWriter(tmp_path / "camera.tlog", component=M.MAV_COMP_ID_CAMERA)
    camera.send(
        START_UTC - 1.0,
        M.MAVLink_heartbeat_message(M.MAV_TYPE_CAMERA, M.MAV_AUTOPILOT_GENERIC, 0, 0, 4, 3),
    )
    camera.close()
    gimbal = TlogWriter(tmp_path / "gimbal.tlog", component=M.MAV_COMP_ID_GIMBAL)
    q = euler_to_quaternion(0.0, math.radians(-70.0), math.radians(180.0))
    for k in range(50):  # later than the flight's mount angles: the newest sample wins
        gimbal.send(
            START_UTC + 4.0 + k / 100,
            M.MAVLink_gimbal_device_attitude_status_message(
                0, 0, int((104.0 + k / 100) * 1000), 8 | 16, q, 0.0, 0.0, 0.0, 0
            ),
        )
    gimbal.close()
    path = tmp_path / "camera_first.tlog"
    path.write_bytes(
        (tmp_path / "camera.tlog").read_bytes()
        + flight.read_bytes()
        + (tmp_path / "gimbal.tlog").read_bytes()
    )
    log = open_flight_log(path)
    assert len(log.positions) == 50 and log.home == (LAT0, LON0, 120.0)
    axis = optical_axis(log, 104.3)  # 70 deg below the horizon, looking south
    expected = [-math.cos(math.radians(70)), 0.0, math.sin(math.radians(70))]
    assert axis == pytest.approx(expected, abs=1e-3)


def test_dataflash_from_sitl_servo_mount_is_in_the_body_frame() -> None:
    """The real ArduCopter SITL log: a servo mount asked for -60 deg (earth frame) logs its
    servo angle (-48 deg) while the copter flies 12 deg nose down; the camera looks 60 deg
    below the horizon, not 48."""
    log = open_flight_log(SITL_BIN)
    assert log.fmt == "ArduPilot DataFlash log"
    assert log.home is not None and log.home[2] == pytest.approx(120.08, abs=0.01)
    assert len(log.triggers) == 1 and log.utc_offset_s is not None
    cam = log.triggers[0]
    axis = optical_axis(log, cam)
    assert math.degrees(math.asin(axis[2])) == pytest.approx(60.0, abs=2.0)
    assert axis[0] > 0.4  # flying north, camera forward of the nadir
    gps_position = min(log.positions, key=lambda p: abs(p.t - cam))
    assert gps_position.rel_alt_m == pytest.approx(40.0, abs=0.5)
    assert gps_position.gnss_sigma_m == pytest.approx(0.3)


def test_dataflash_without_the_mount_type_says_how_unsure_its_pointing_is(tmp_path: Path) -> None:
    """Without MNT1_TYPE the servo mount's -48 deg (airframe) was read as earth-frame with the
    format's 1 deg error: a fix 12.6 m off at an error of 1.8 m. The angles are still read
    as earth-frame, but the pointing error widens to cover the vehicle's tilt."""
    path = tmp_path / "no_mount_type.BIN"
    raw = SITL_BIN.read_bytes()
    assert raw.count(b"MNT1_TYPE") == 1
    path.write_bytes(raw.replace(b"MNT1_TYPE", b"MNT9_TYPE"))
    log = open_flight_log(path)
    axis = optical_axis(log, log.triggers[0])
    assert math.degrees(math.asin(axis[2])) == pytest.approx(48.0, abs=2.0)  # as logged
    assert log.accuracy.attitude_sigma_deg >= 6.0  # twice it covers the 12 deg nose-down
    assert any("no MNT1_TYPE parameter" in n for n in log.notes)
    assert open_flight_log(SITL_BIN).accuracy.attitude_sigma_deg == 1.0


def test_a_log_is_read_by_its_content_whatever_its_name(tmp_path: Path) -> None:
    """pymavlink picks its reader by the file name: a DataFlash log saved as .tlog read as
    'without a usable GNSS position', a tlog saved as .BIN printed 'bad header' lines."""
    write_tlog(tmp_path / "flight.tlog", seconds=3.0)
    renamed = {
        tmp_path / "flight.BIN": (tmp_path / "flight.tlog").read_bytes(),
        tmp_path / "sitl.tlog": SITL_BIN.read_bytes(),
        tmp_path / "sitl:copy.dat": SITL_BIN.read_bytes(),  # a colon once meant a UDP socket
    }
    for path, data in renamed.items():
        path.write_bytes(data)
    assert open_flight_log(tmp_path / "flight.BIN").fmt == "MAVLink tlog"
    assert len(open_flight_log(tmp_path / "flight.BIN").positions) == 30
    for name in ("sitl.tlog", "sitl:copy.dat"):
        log = open_flight_log(tmp_path / name)
        assert log.fmt == "ArduPilot DataFlash log"
        assert len(log.positions) == len(open_flight_log(SITL_BIN).positions) > 0


def test_ulog_attitude_quaternion_and_vehicle_frame_gimbal(tmp_path: Path) -> None:
    path = tmp_path / "flight.ulg"
    px4_ulog(path, gimbal_pitch_deg=-30.0, yaw_deg=90.0)
    log = open_flight_log(path)
    assert log.fmt == "PX4 ULog" and log.home == (LAT0, LON0, 100.0)
    assert log.positions[0].rel_alt_m == pytest.approx(40.0)
    assert log.positions[0].gnss_sigma_m == pytest.approx(0.8)
    assert log.utc_offset_s == pytest.approx(START_UTC)
    assert log.triggers == [pytest.approx(22.0)]
    axis = optical_axis(log, 25.0)  # heading east, camera 30 deg down
    assert axis == pytest.approx([0.0, math.cos(math.radians(30)), 0.5], abs=1e-6)


def test_ulog_without_home_or_fix_gives_no_positions(tmp_path: Path) -> None:
    px4_ulog(tmp_path / "a.ulg", with_home=False)
    with pytest.raises(FlightLogError, match="without a usable GNSS position"):
        open_flight_log(tmp_path / "a.ulg")
    px4_ulog(tmp_path / "b.ulg", fix=2)
    with pytest.raises(FlightLogError, match="3D GNSS fix"):
        open_flight_log(tmp_path / "b.ulg")


def test_ulog_home_at_zero_is_no_home_and_a_home_set_again_counts_from_its_time(
    tmp_path: Path,
) -> None:
    """A home_position row at 0, 0 (sent before the estimator had one) was believed as the
    last row: the ground 100 m off and fixes 240 m from the drone instead of 70."""
    path = tmp_path / "zero.ulg"
    px4_ulog(path, homes=[(0, LAT0, LON0, 100.0), (5, 0.0, 0.0, 0.0)])
    log = open_flight_log(path)
    assert log.home == (LAT0, LON0, pytest.approx(100.0))
    assert [p.rel_alt_m for p in log.positions] == pytest.approx([40.0] * 100)
    assert log.rejected["home_position not a place (0, 0 or not finite)"] == 1
    path = tmp_path / "again.ulg"
    px4_ulog(path, homes=[(0, LAT0, LON0, 100.0), (50, LAT0, LON0, 135.0)])
    log = open_flight_log(path)
    heights = [round(p.rel_alt_m, 3) for p in log.positions]
    assert heights == [40.0] * 50 + [5.0] * 50
    assert any("moved 35.0 m in height" in n for n in log.notes)


def test_dji_srt_positions_gimbal_signs_and_missing_lines(tmp_path: Path) -> None:
    path = tmp_path / "DJI_0001.SRT"
    path.write_text(dji_srt_text(frames=30, drop=(3, 4)))
    log = open_flight_log(path)
    assert log.per_frame and len(log.positions) == 28
    assert log.rejected["subtitle block without a time or position"] == 2
    assert log.home == (LAT0, LON0, pytest.approx(120.0))
    axis = optical_axis(log, 0.5)  # gb_yaw 180 (south), gb_pitch -60
    assert axis == pytest.approx([-0.5, 0.0, math.sin(math.radians(60))], abs=1e-6)


def test_dji_srt_in_the_firmwares_own_spelling_and_without_colons(tmp_path: Path) -> None:
    """DJI firmwares write ``longtitude`` (sic) and, on older models, pairs without a colon;
    a reader of ``longitude:`` alone found no position in any of their blocks."""
    text = dji_srt_text(frames=6).replace("[longitude:", "[longtitude:")
    text = text.replace("[rel_alt: 60.000 abs_alt: 180.000]", "[rel_alt 60.000 abs_alt 180.000]")
    path = tmp_path / "DJI_0003.SRT"
    path.write_text(text)
    log = open_flight_log(path)
    assert len(log.positions) == 6 and not log.rejected
    assert log.home == (LAT0, LON0, pytest.approx(120.0))
    assert [p.lon for p in log.positions] == pytest.approx([LON0] * 6)
    assert log.gimbal


def _track(glitches: dict[int, tuple[float, float]], n: int = 60) -> FlightLog:
    """``n`` positions a second apart along a line at 10 m/s; ``glitches`` replaces samples
    by index with (lat, lon) far away."""
    builder = LogBuilder("test", Path("t.log"), "test clock", ACCURACY["autopilot"])
    for i in range(n):
        lat, lon = glitches.get(i, (LAT0 + i * 10 / 111_320, LON0))
        builder.position(float(i), lat, lon, 50.0, 150.0)
    return builder.build()


@pytest.mark.parametrize(
    ("glitches", "kept"),
    [
        ({0: (LAT0 + 0.27, LON0)}, 59),  # a stale first fix 30 km away
        ({i: (LAT0 + 0.27, LON0 + 0.01 * (i % 3)) for i in range(30)}, 30),  # 30 stale fixes
        ({25: (0.5, 0.5)}, 59),  # one glitch in flight
        ({i: (LAT0 - 0.5, LON0) for i in range(10, 20)}, 50),  # a burst of ten in flight
        ({}, 60),
    ],
)
def test_positions_are_judged_by_the_track_most_of_them_agree_on(glitches, kept) -> None:
    """A fix is a jump against the track the log's other fixes make, not against the previous
    believed one: a stale first fix once made every true position after it a jump, and the
    log's one 'believed' position was 30 km from the aircraft."""
    log = _track(glitches)
    assert len(log.positions) == kept
    assert all(abs(p.lat - LAT0) < 0.01 and p.lon == LON0 for p in log.positions)
    assert log.rejected["position jump faster than an aircraft"] == 60 - kept
    assert log.home == (pytest.approx(log.positions[0].lat), LON0, pytest.approx(100.0))


def test_an_srt_whose_first_block_is_stale_keeps_the_flight_and_its_home(tmp_path: Path) -> None:
    text = dji_srt_text(frames=20)
    first = f"[latitude: {LAT0:.6f}]"
    assert first in text
    text = text.replace(first, f"[latitude: {LAT0 + 0.27:.6f}]", 1)
    path = tmp_path / "DJI_0004.SRT"
    path.write_text(text)
    log = open_flight_log(path)
    assert len(log.positions) == 19
    assert log.home == (pytest.approx(LAT0 + 1e-6), LON0, pytest.approx(120.0))
    assert log.home_note == "home altitude from the first block (abs_alt - rel_alt)"


@pytest.mark.parametrize(("height", "believed"), [(55.0, True), (1429.7, False)])
def test_dji_srt_altitude_without_rel_alt_is_believed_only_as_a_flying_height(
    tmp_path: Path, height: float, believed: bool
) -> None:
    """``[altitude: x]`` is above take-off on some firmwares and above sea level on others
    (1429.7 m over Kigali): taken as a height above take-off it put alerts 1.6 km off."""
    text = dji_srt_text(frames=5).replace(
        "[rel_alt: 60.000 abs_alt: 180.000]", f"[altitude: {height}]"
    )
    path = tmp_path / "DJI_0005.SRT"
    path.write_text(text)
    if believed:
        log = open_flight_log(path)
        assert [p.rel_alt_m for p in log.positions] == [height] * 5
        assert any("above sea level" in n for n in log.notes)
    else:
        with pytest.raises(FlightLogError, match="reach 1430 m: above sea level"):
            open_flight_log(path)


@pytest.mark.parametrize(
    ("name", "encode"),
    [
        ("no blank lines", lambda t: t.replace("\n\n", "\n").encode()),
        ("CR line ends", lambda t: t.replace("\n", "\r").encode()),
        ("UTF-16", lambda t: t.encode("utf-16")),
        ("BOM and CRLF", lambda t: t.replace("\n", "\r\n").encode("utf-8-sig")),
    ],
)
def test_dji_srt_as_editors_and_converters_save_it(tmp_path: Path, name, encode) -> None:
    """Without blank lines or with CR-only line ends the whole file was one block (one
    position, nothing said); UTF-16 was 'not a flight log'."""
    path = tmp_path / "DJI_0006.SRT"
    path.write_bytes(encode(dji_srt_text(frames=12)))
    log = open_flight_log(path)
    assert len(log.positions) == 12 and not log.rejected, name
    assert [p.t for p in log.positions] == pytest.approx([k / 30 for k in range(12)], abs=1e-3)


def test_an_srt_of_another_day_is_not_paired_with_the_video(tmp_path: Path) -> None:
    """The SRT's date lines (the drone's clock, 2024-05-01 12:00 local) were ignored, so a
    video recorded days later was placed with its positions."""
    path = tmp_path / "DJI_0007.SRT"
    path.write_text(dji_srt_text(frames=10))
    log = open_flight_log(path)
    assert log.stated_start_posix == pytest.approx(START_UTC + 2 * 3600)  # local, as UTC
    same = align_video(log, created=START_UTC + 5.0, duration_s=0.3)  # UTC+2: within a zone
    assert same.offset_s == 0.0
    with pytest.raises(AlignmentError, match="not the same recording"):
        align_video(log, created=START_UTC + 3 * 86400, duration_s=0.3)


def test_dji_srt_without_gimbal_angles_places_no_pixel(tmp_path: Path) -> None:
    path = tmp_path / "DJI_0002.SRT"
    path.write_text(dji_srt_text(frames=10, gimbal=False))
    log = open_flight_log(path)
    assert log.positions and not log.gimbal and not log.attitudes
    assert any("pointing is unknown" in n for n in log.notes)


def test_dji_images_exif_xmp_and_images_without_exif(tmp_path: Path) -> None:
    folder = tmp_path / "photos"
    folder.mkdir()
    write_dji_jpeg(
        folder / "DJI_0001.JPG",
        lat=LAT0,
        lon=LON0,
        gimbal_pitch=-45.0,
        gimbal_yaw=270.0,
        flight_yaw=265.0,
        when="2024:05:01 12:00:00",
    )
    write_dji_jpeg(folder / "DJI_0002.JPG", lat=LAT0 + 1e-4, lon=LON0, when="2024:05:01 12:00:02")
    write_dji_jpeg(folder / "DJI_0003.JPG", lat=None, lon=None, exif=False)
    log = open_flight_log(folder)
    assert sorted(log.image_times) == ["DJI_0001.JPG", "DJI_0002.JPG"]
    assert log.image_times["DJI_0002.JPG"] - log.image_times["DJI_0001.JPG"] == 2.0
    assert log.rejected["image without EXIF"] == 1
    axis = optical_axis(log, log.image_times["DJI_0001.JPG"])
    assert axis == pytest.approx([0.0, -math.sqrt(0.5), math.sqrt(0.5)], abs=1e-6)
    chile = tmp_path / "chile"
    chile.mkdir()
    write_dji_jpeg(chile / "DJI_0001.JPG", lat=-33.5, lon=-70.25)
    south = open_flight_log(chile).positions[0]
    assert (south.lat, south.lon) == (pytest.approx(-33.5), pytest.approx(-70.25))
    empty = tmp_path / "empty"
    empty.mkdir()
    write_dji_jpeg(empty / "a.jpg", lat=None, lon=None, exif=False)
    with pytest.raises(FlightLogError, match="no JPEG with EXIF GPS"):
        open_flight_log(empty)


def test_format_found_from_content_not_the_extension(tmp_path: Path) -> None:
    write_tlog(tmp_path / "flight.tlog", seconds=2.0)
    disguised = tmp_path / "flight.bin"
    disguised.write_bytes((tmp_path / "flight.tlog").read_bytes())
    assert sniff(disguised) == "tlog"
    assert sniff(SITL_BIN) == "dataflash"
    (tmp_path / "noise.tlog").write_bytes(np.random.default_rng(0).bytes(5000))
    with pytest.raises(FlightLogError, match="not a flight log"):
        open_flight_log(tmp_path / "noise.tlog")
    (tmp_path / "empty.ulg").write_bytes(b"")
    with pytest.raises(FlightLogError, match="empty"):
        open_flight_log(tmp_path / "empty.ulg")


def test_truncated_and_corrupt_logs_read_what_is_there(tmp_path: Path) -> None:
    write_tlog(tmp_path / "full.tlog")
    data = (tmp_path / "full.tlog").read_bytes()
    (tmp_path / "cut.tlog").write_bytes(data[: len(data) // 2 + 7])
    cut = open_flight_log(tmp_path / "cut.tlog")
    assert 50 < len(cut.positions) < 200
    raw = bytearray(SITL_BIN.read_bytes())
    raw[30_000:30_400] = bytes(400)  # a hole in the middle
    (tmp_path / "hole.BIN").write_bytes(bytes(raw[:45_000]))
    holed = open_flight_log(tmp_path / "hole.BIN")
    assert 0 < len(holed.positions) < len(open_flight_log(SITL_BIN).positions)
    ulog = tmp_path / "a.ulg"
    px4_ulog(ulog)
    (tmp_path / "cut.ulg").write_bytes(ulog.read_bytes()[:40])
    with pytest.raises(FlightLogError):
        open_flight_log(tmp_path / "cut.ulg")


def test_log_without_gps_fix_gives_no_positions(tmp_path: Path) -> None:
    write_tlog(tmp_path / "nofix.tlog", gps_fix=1)
    with pytest.raises(FlightLogError, match="without a usable GNSS position.*3D GPS fix"):
        open_flight_log(tmp_path / "nofix.tlog")


def test_video_alignment_order_and_refusals(tmp_path: Path) -> None:
    write_tlog(tmp_path / "t.tlog", trigger_at=5.0)
    log = open_flight_log(tmp_path / "t.tlog")
    by_trigger = align_video(log, created=None, duration_s=5.0)
    assert by_trigger.offset_s == pytest.approx(105.0) and "camera trigger" in by_trigger.method
    given = align_video(log, created=None, duration_s=5.0, offset_s=101.5)
    assert given.log_time(2.0) == pytest.approx(103.5)
    write_tlog(tmp_path / "n.tlog", trigger_at=None)
    plain = open_flight_log(tmp_path / "n.tlog")
    by_clock = align_video(plain, created=START_UTC + 3.0, duration_s=5.0)
    assert by_clock.offset_s == pytest.approx(103.0) and "creation time" in by_clock.method
    with pytest.raises(AlignmentError, match="not the same flight"):
        align_video(log, created=START_UTC + 3 * 86400, duration_s=5.0)
    with pytest.raises(AlignmentError, match="give --time-offset"):
        align_video(plain, created=None, duration_s=5.0)
    with pytest.raises(AlignmentError, match="cameras often store local time"):
        align_video(plain, created=START_UTC + 3600, duration_s=5.0)
    with pytest.raises(AlignmentError, match="outside the log"):
        align_video(plain, created=None, duration_s=5.0, offset_s=500.0)
    # a trigger and a creation time that agree (whole seconds, stamped late) align on it;
    # 10 s or more apart they contradict each other: no alignment rather than a silent one
    near = align_video(log, created=START_UTC + 6.0, duration_s=5.0)
    assert near.offset_s == pytest.approx(105.0) and "-1.0 s from the video's" in near.method
    with pytest.raises(AlignmentError, match="the nearest, at 105.0 s, is 13 s away"):
        align_video(log, created=START_UTC + 18.0, duration_s=2.0)


def test_image_alignment_pairs_triggers_one_to_one(tmp_path: Path) -> None:
    write_tlog(tmp_path / "t.tlog", trigger_at=5.0)
    log = open_flight_log(tmp_path / "t.tlog")
    paired = align_images(log, ["a.jpg"], fps=1.0)
    assert paired.log_time(0.0, "a.jpg") == pytest.approx(105.0)
    with pytest.raises(AlignmentError, match="2 images but 1 camera triggers"):
        align_images(log, ["a.jpg", "b.jpg"], fps=1.0)


def test_per_image_log_gives_no_pose_to_an_image_it_does_not_place(tmp_path: Path) -> None:
    folder = tmp_path / "photos"
    folder.mkdir()
    for k, when in ((1, "12:00:00"), (3, "12:00:02")):
        write_dji_jpeg(folder / f"DJI_{k}.JPG", lat=LAT0, lon=LON0, when=f"2024:05:01 {when}")
    write_dji_jpeg(folder / "DJI_2.JPG", lat=None, lon=None, exif=False)
    log = open_flight_log(folder)
    alignment = align_images(log, ["DJI_1.JPG", "DJI_2.JPG", "DJI_3.JPG"], fps=1.0)
    buffer = TelemetryBuffer()
    LogFeeder(log, buffer).advance(alignment.log_time(0.0, "DJI_3.JPG"))
    middle = alignment.log_time(1.0, "DJI_2.JPG")
    assert alignment.log_time(0.0, "DJI_1.JPG") < middle < alignment.log_time(0.0, "DJI_3.JPG")
    assert not isinstance(buffer.lookup(middle), PlatformPose)
    assert isinstance(buffer.lookup(alignment.log_time(0.0, "DJI_3.JPG")), PlatformPose)
