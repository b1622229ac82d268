"""Small flight logs written here in the real formats, for the flight-log tests.

- tlog: pymavlink's MAVLink encoder into a ``mavutil`` log file, each packet after its 8-byte
  big-endian microsecond timestamp (what QGroundControl and MAVProxy write);
- ULog: the binary format of the PX4 ULog specification (header, flag bits, formats, add-logged
  and data messages), written by :func:`write_ulog` and read back with pyulog;
- DJI SRT: text as the aircraft writes it; DJI JPEG: EXIF by piexif, XMP as an APP1 packet;
- MP4: OpenCV's writer, then the movie header's creation time set.
The DataFlash fixture is a real recording: ``fixtures/flightlogs/sitl_gimbal_cam.BIN``.
"""

from __future__ import annotations

import io
import math
import struct
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as M

FIXTURES = Path(__file__).resolve().parent / "fixtures" / "flightlogs"
SITL_BIN = FIXTURES / "sitl_gimbal_cam.BIN"
START_UTC = 1_714_557_600.0  # 2024-05-01 10:00:00 UTC
LAT0, LON0 = 43.0, 10.0


class TlogWriter:
    """A tlog written packet by packet with pymavlink (``mavutil`` log file)."""

    def __init__(self, path: Path, system: int = 1, component: int = 1) -> None:
        self.conn = mavutil.mavlogfile(str(path), write=True)
        self.mav = M.MAVLink(self.conn, srcSystem=system, srcComponent=component)

    def send(self, utc_s: float, msg: object) -> None:
        self.conn.write(struct.pack(">Q", int(utc_s * 1e6)))
        self.mav.send(msg)

    def close(self) -> None:
        self.conn.close()


def write_tlog(
    path: Path,
    *,
    seconds: float = 20.0,
    rate_hz: float = 10.0,
    gps_fix: int = 3,
    pitch_deg: float = -45.0,
    gimbal_yaw_deg: float = 90.0,
    yaw_deg: float = 30.0,
    h_acc_mm: int = 1500,
    trigger_at: float | None = 5.0,
    boot0: float = 100.0,
    utc0: float = START_UTC,
) -> None:
    """A hover 50 m above home at (LAT0, LON0) drifting north at 1 m/s: HEARTBEAT, GPS_RAW_INT,
    GLOBAL_POSITION_INT, ATTITUDE (yaw ``yaw_deg``), MOUNT_ORIENTATION (earth-frame pitch and
    absolute yaw), HOME_POSITION, SYSTEM_TIME and a CAMERA_FEEDBACK ``trigger_at`` s in."""
    w = TlogWriter(path)
    n = int(seconds * rate_hz)
    for k in range(n):
        t = k / rate_hz
        boot_ms = int((boot0 + t) * 1000)
        utc = utc0 + t
        w.send(
            utc,
            M.MAVLink_heartbeat_message(
                M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 4, 3
            ),
        )
        w.send(
            utc,
            M.MAVLink_gps_raw_int_message(
                int(utc * 1e6),
                gps_fix,
                int(LAT0 * 1e7),
                int(LON0 * 1e7),
                50000,
                100,
                100,
                0,
                0,
                10,
                0,
                h_acc_mm,
                0,
                0,
                0,
                0,
            ),
        )
        lat = LAT0 + t / 111_111.0
        w.send(
            utc,
            M.MAVLink_global_position_int_message(
                boot_ms, int(round(lat * 1e7)), int(LON0 * 1e7), 170_000, 50_000, 100, 0, 0, 0
            ),
        )
        w.send(utc, M.MAVLink_attitude_message(boot_ms, 0.0, 0.0, math.radians(yaw_deg), 0, 0, 0))
        w.send(
            utc,
            M.MAVLink_mount_orientation_message(
                boot_ms, 0.0, pitch_deg, gimbal_yaw_deg - yaw_deg, gimbal_yaw_deg
            ),
        )
        if k % 10 == 0:
            w.send(
                utc,
                M.MAVLink_home_position_message(
                    int(LAT0 * 1e7), int(LON0 * 1e7), 120_000, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0
                ),
            )
            w.send(utc, M.MAVLink_system_time_message(int(utc * 1e6), boot_ms))
        if trigger_at is not None and abs(t - trigger_at) < 0.5 / rate_hz:
            w.send(
                utc,
                M.MAVLink_camera_feedback_message(
                    int(utc * 1e6), 1, 0, 1, 0, 0, 0.0, 50.0, 0, 0, 0, 0, 0, 0
                ),
            )
    w.close()


# -- ULog ----------------------------------------------------------------------------------
_ULOG_TYPES = {
    "uint64_t": "Q",
    "uint32_t": "I",
    "uint16_t": "H",
    "uint8_t": "B",
    "float": "f",
    "double": "d",
}


def _ulog_msg(kind: bytes, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), kind[0]) + payload


def write_ulog(
    path: Path, topics: dict[str, tuple[str, list[Sequence[float]]]], start_us: int = 0
) -> None:
    """A ULog with ``topics``: name -> (format "uint64_t timestamp;double lat;...", rows of
    values in field order, array fields flattened)."""
    out = bytearray(b"ULog" + bytes([0x01, 0x12, 0x35]) + bytes([1]) + struct.pack("<Q", start_us))
    out += _ulog_msg(b"B", bytes(16) + struct.pack("<3Q", 0, 0, 0))
    codes: dict[str, str] = {}
    for name, (fmt, _) in topics.items():
        out += _ulog_msg(b"F", f"{name}:{fmt}".encode())
        code = "<"
        for field in filter(None, fmt.split(";")):
            ftype = field.split(" ")[0]
            base, _, count = ftype.partition("[")
            code += _ULOG_TYPES[base] * (int(count[:-1]) if count else 1)
        codes[name] = code
    key = b"char[4] ver_sw"
    out += _ulog_msg(b"I", bytes([len(key)]) + key + b"test")
    rows: list[tuple[int, int, bytes]] = []
    for msg_id, (name, (_, data)) in enumerate(topics.items()):
        out += _ulog_msg(b"A", struct.pack("<BH", 0, msg_id) + name.encode())
        for row in data:
            rows.append((int(row[0]), msg_id, struct.pack(codes[name], *row)))
    for _, msg_id, payload in sorted(rows, key=lambda r: r[0]):
        out += _ulog_msg(b"D", struct.pack("<H", msg_id) + payload)
    path.write_bytes(bytes(out))


def px4_ulog(
    path: Path,
    *,
    seconds: float = 10.0,
    gimbal_pitch_deg: float = -30.0,
    yaw_deg: float = 90.0,
    fix: int = 3,
    with_home: bool = True,
    homes: Sequence[tuple[int, float, float, float]] = ((0, LAT0, LON0, 100.0),),
) -> None:
    """A PX4 hover 40 m above a home 100 m AMSL, yaw ``yaw_deg``, gimbal in the vehicle frame
    pitched ``gimbal_pitch_deg``, a camera capture at 2 s, GNSS UTC from START_UTC.
    ``homes``: home_position rows as (sample index, lat, lon, alt)."""
    from sarmission.geo.frames import euler_to_quaternion

    n = int(seconds * 10)
    ts = [int(1e6 * (20.0 + k / 10)) for k in range(n)]
    att = euler_to_quaternion(0.0, 0.0, math.radians(yaw_deg))
    gim = euler_to_quaternion(0.0, math.radians(gimbal_pitch_deg), 0.0)
    topics: dict[str, tuple[str, list[Sequence[float]]]] = {
        "vehicle_global_position": (
            "uint64_t timestamp;double lat;double lon;float alt;float eph;",
            [(t, LAT0, LON0, 140.0, 0.8) for t in ts],
        ),
        "sensor_gps": (
            "uint64_t timestamp;uint64_t time_utc_usec;uint8_t fix_type;",
            [(t, int((START_UTC + t / 1e6) * 1e6), fix) for t in ts],
        ),
        "vehicle_attitude": ("uint64_t timestamp;float[4] q;", [(t, *att) for t in ts]),
        "gimbal_device_attitude_status": (
            "uint64_t timestamp;float[4] q;uint16_t device_flags;",
            [(t, *gim, 32) for t in ts],
        ),
        "camera_capture": ("uint64_t timestamp;uint32_t seq;", [(ts[20], 1)]),
    }
    if with_home:
        topics["home_position"] = (
            "uint64_t timestamp;double lat;double lon;float alt;",
            [(ts[k], lat, lon, alt) for k, lat, lon, alt in homes],
        )
    write_ulog(path, topics)


# -- DJI -----------------------------------------------------------------------------------
def dji_srt_text(
    frames: int = 30, fps: float = 30.0, gimbal: bool = True, drop: Sequence[int] = ()
) -> str:
    """A DJI SRT (Mavic 3 layout) of ``frames`` blocks; ``drop`` blocks lose their position."""
    blocks = []
    for k in range(frames):
        t0, t1 = k / fps, (k + 1) / fps

        def stamp(t: float) -> str:
            ms = int(round(t * 1000))
            return (
                f"{ms // 3_600_000:02d}:{ms // 60_000 % 60:02d}:{ms // 1000 % 60:02d},"
                f"{ms % 1000:03d}"
            )

        place = "" if k in drop else (f"[latitude: {LAT0 + k * 1e-6:.6f}] [longitude: {LON0:.6f}] ")
        gb = "[gb_yaw: 180.0 gb_pitch: -60.0 gb_roll: 0.0] " if gimbal else ""
        blocks.append(
            f"{k + 1}\n{stamp(t0)} --> {stamp(t1)}\n"
            f'<font size="28">FrameCnt: {k + 1}, DiffTime: 33ms\n'
            f"2024-05-01 12:00:00.{k:03d}\n"
            f"[iso: 100] [shutter: 1/1000.0] [fnum: 2.8] [ev: 0] [focal_len: 24.00] "
            f"{place}[rel_alt: 60.000 abs_alt: 180.000] {gb}</font>\n"
        )
    return "\n".join(blocks)


def _dms(value: float) -> tuple[tuple[int, int], ...]:
    value = abs(value)
    d = int(value)
    m = int((value - d) * 60)
    s = round(((value - d) * 60 - m) * 60 * 10000)
    return ((d, 1), (m, 1), (s, 10000))


def write_dji_jpeg(
    path: Path,
    *,
    lat: float | None,
    lon: float | None,
    rel_alt: float | None = 50.0,
    gimbal_pitch: float = -90.0,
    gimbal_yaw: float = 0.0,
    flight_yaw: float = 0.0,
    when: str = "2024:05:01 12:00:00",
    exif: bool = True,
) -> None:
    """A small JPEG with DJI-style EXIF GPS (piexif) and ``drone-dji`` XMP."""
    import piexif

    ok, buf = cv2.imencode(".jpg", np.full((64, 96, 3), 120, np.uint8))
    assert ok
    data = buf.tobytes()
    if exif:
        gps = {}
        if lat is not None and lon is not None:
            gps = {
                piexif.GPSIFD.GPSLatitudeRef: b"N" if lat >= 0 else b"S",
                piexif.GPSIFD.GPSLatitude: _dms(lat),
                piexif.GPSIFD.GPSLongitudeRef: b"E" if lon >= 0 else b"W",
                piexif.GPSIFD.GPSLongitude: _dms(lon),
                piexif.GPSIFD.GPSAltitude: (int(170 * 100), 100),
            }
        exif_bytes = piexif.dump(
            {
                "0th": {piexif.ImageIFD.Make: b"DJI"},
                "Exif": {piexif.ExifIFD.DateTimeOriginal: when.encode()},
                "GPS": gps,
            }
        )
        out = io.BytesIO()
        piexif.insert(exif_bytes, data, out)
        data = out.getvalue()
        rel = f' drone-dji:RelativeAltitude="+{rel_alt:.2f}"' if rel_alt is not None else ""
        xmp = (
            '<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF xmlns:rdf="http://www.w3.org/1999/'
            '02/22-rdf-syntax-ns#"><rdf:Description xmlns:drone-dji="http://www.dji.com/'
            f'drone-dji/1.0/" drone-dji:AbsoluteAltitude="+170.00"{rel} '
            f'drone-dji:GimbalRollDegree="+0.00" drone-dji:GimbalPitchDegree='
            f'"{gimbal_pitch:+.2f}" drone-dji:GimbalYawDegree="{gimbal_yaw:+.2f}" '
            f'drone-dji:FlightYawDegree="{flight_yaw:+.2f}" drone-dji:FlightPitchDegree='
            '"+0.00" drone-dji:FlightRollDegree="+0.00"/></rdf:RDF></x:xmpmeta>'
        )
        payload = b"http://ns.adobe.com/xap/1.0/\x00" + xmp.encode()
        segment = b"\xff\xe1" + struct.pack(">H", len(payload) + 2) + payload
        data = data[:2] + segment + data[2:]
    path.write_bytes(data)


def write_mp4(
    path: Path, frames: int = 10, fps: float = 10.0, created: float | None = None
) -> None:
    """A small MP4 (OpenCV's writer); ``created`` sets its movie header's creation time."""
    from sarmission.flightlog.video_time import set_creation_time

    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (96, 64))
    for k in range(frames):
        writer.write(np.full((64, 96, 3), 10 * k % 255, np.uint8))
    writer.release()
    if created is not None:
        set_creation_time(path, created)
