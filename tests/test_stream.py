"""Live streams on 127.0.0.1: ffmpeg sends H.264 in MPEG-TS over UDP, or as RTP through a small
RTSP server; the stream source decodes it in its own thread and hands out the newest frame;
drops, loss and reconnection, corrupt datagrams, silence and bad URLs; ``detect`` and ``run``
reading a stream URL."""

from __future__ import annotations

import json
import logging
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import free_udp_port, wait_until
from rtsp_server import RtspServer
from stream_sender import (
    FFMPEG,
    CorruptingRelay,
    StallingRelay,
    TcpFiles,
    UdpStream,
    needs_ffmpeg,
)
from test_frames import write_rotated, write_ts

from sarmission.data.frames import FrameSourceError, open_frame_source
from sarmission.data.stream import (
    CatchUp,
    FramePeriod,
    StreamClock,
    StreamSource,
    check_stream_url,
    redact,
    with_udp_defaults,
)
from sarmission.mission.live_sources import open_video_source


def test_clock_keeps_the_cameras_spacing_anchored_to_the_least_delay():
    clock = StreamClock(drift=0.0)
    # pts every 40 ms; the second frame arrives 50 ms late, the third with less delay than the
    # first (it moves the anchor), the fourth on time.
    assert clock.stamp(0.00, 100.010) == pytest.approx(100.010)
    assert clock.stamp(0.04, 100.100) == pytest.approx(100.050)  # not made younger: pts spacing
    assert clock.stamp(0.08, 100.085) == pytest.approx(100.085)  # 5 ms less delay: new anchor
    assert clock.stamp(0.12, 100.130) == pytest.approx(100.125)
    # never later than the arrival
    assert clock.stamp(0.16, 100.140) == pytest.approx(100.140)


def test_clock_follows_a_slow_camera_clock_and_restarts_on_jumps():
    clock = StreamClock(drift=1e-3, max_gap_s=5.0)
    clock.stamp(0.0, 10.0)
    # the camera's clock runs 0.5 % slow: arrival - pts grows 5 ms per second of pts
    stamps = [clock.stamp(t, 10.0 + t * 1.005) for t in (1.0, 2.0, 3.0)]
    assert stamps == pytest.approx([11.001, 12.002, 13.003])  # followed at the drift allowance
    assert clock.stamp(2.5, 20.0) == pytest.approx(20.0)  # back in time: a new stream
    assert clock.stamp(2.54, 20.04) == pytest.approx(20.04)
    assert clock.stamp(60.0, 21.0) == pytest.approx(21.0)  # a jump of a minute: restart
    assert clock.stamp(None, 22.0) == pytest.approx(22.0)  # no pts: the arrival


@pytest.mark.parametrize(
    ("url", "phrase"),
    [
        ("file:///etc/passwd", "unsupported stream URL scheme 'file'"),
        ("udp://127.0.0.1", "needs a port"),
        ("rtsp:///live", "names no host"),
        ("udp://127.0.0.1:99999", "malformed stream URL"),
        ("rtsp://cam/live\nX-Injected: 1", "control characters"),
    ],
)
def test_bad_stream_urls_are_refused_in_one_line(url: str, phrase: str):
    with pytest.raises(FrameSourceError) as info:
        open_frame_source(url)
    assert phrase in str(info.value) and "\n" not in str(info.value)


def test_passwords_stay_out_of_messages():
    url = "rtsp://pilot:s3cret@10.0.0.5:8554/live"
    assert redact(url) == "rtsp://pilot:***@10.0.0.5:8554/live"
    assert check_stream_url(url) == url
    with pytest.raises(FrameSourceError) as info:
        check_stream_url("ftp://pilot:s3cret@host/x")
    assert "s3cret" not in str(info.value)


def test_missing_frames_are_counted_from_the_streams_own_frame_period():
    period = FramePeriod()
    # the first steps teach the period (a stream announcing 60 frames/s may send 30)
    assert [period.missing(1 / 30) for _ in range(5)] == [0] * 5
    assert period.missing(1 / 30) == 0
    assert period.missing(4 / 30) == 3  # three frames never arrived
    assert period.missing(1.2 / 30) == 0  # jitter is no loss
    assert period.missing(0.0) == 0 and period.missing(-1.0) == 0
    assert period.missing(30.0) == 0  # a restart, not a loss


def test_frames_left_out_on_purpose_do_not_change_the_frame_period():
    period = FramePeriod()
    for _ in range(6):
        period.missing(0.04)
    assert period.missing(0.08, learn=False) == 1  # B-frames skipped: counted, not learnt
    assert all(step == 0.04 for step in period.steps)


def test_the_reader_skips_work_only_while_it_is_late():
    catch_up = CatchUp(max_lag_s=1.0)
    assert catch_up.update(0.2, now=0.0) == "DEFAULT" and catch_up.decoding_all
    assert catch_up.update(0.6, now=0.1) == "NONREF" and not catch_up.decoding_all
    assert catch_up.update(0.3, now=0.2) == "NONREF"  # not yet back under a quarter
    assert catch_up.update(0.2, now=0.3) == "DEFAULT"
    assert not catch_up.skip(keyframe=False, now=0.4)
    catch_up.update(1.5, now=10.0)  # a second and a half late: drop to the next keyframe
    assert catch_up.skip(keyframe=False, now=10.1) and catch_up.skip(keyframe=False, now=11.0)
    assert not catch_up.skip(keyframe=True, now=11.1)
    assert not catch_up.skip(keyframe=False, now=11.2)  # decoding again after the keyframe
    catch_up.update(1.5, now=20.0)
    assert catch_up.skip(keyframe=False, now=21.9)
    assert not catch_up.skip(keyframe=False, now=22.0)  # no keyframe for 2 x max_lag_s: go on


def test_udp_streams_survive_a_full_receive_buffer_unless_told_otherwise():
    assert with_udp_defaults("udp://127.0.0.1:5600") == "udp://127.0.0.1:5600?overrun_nonfatal=1"
    assert (
        with_udp_defaults("udp://@239.0.0.1:5600?fifo_size=9000")
        == "udp://@239.0.0.1:5600?fifo_size=9000&overrun_nonfatal=1"
    )
    assert (
        with_udp_defaults("udp://127.0.0.1:5600?overrun_nonfatal=0")
        == "udp://127.0.0.1:5600?overrun_nonfatal=0"
    )
    assert with_udp_defaults("rtsp://cam/live") == "rtsp://cam/live"


def test_silence_is_a_one_line_error_after_the_connect_timeout():
    port = free_udp_port()
    with pytest.raises(FrameSourceError) as info:
        StreamSource(f"udp://127.0.0.1:{port}", connect_timeout_s=1.0)
    message = str(info.value)
    assert f"udp://127.0.0.1:{port}: no video within 1 s" in message and "\n" not in message


def test_datagrams_that_are_not_video_are_a_clear_error():
    import socket
    import threading

    port = free_udp_port()
    stop = threading.Event()

    def noise() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            n = 0
            while not stop.is_set():
                s.sendto(bytes((n * 131 + i) % 251 for i in range(1316)), ("127.0.0.1", port))
                n += 1
                time.sleep(0.005)

    sender = threading.Thread(target=noise, daemon=True)
    sender.start()
    try:
        with pytest.raises(FrameSourceError, match="no video within"):
            StreamSource(f"udp://127.0.0.1:{port}", connect_timeout_s=4.0)
    finally:
        stop.set()
        sender.join(5)


@needs_ffmpeg
def test_newest_frame_wins_and_every_frame_not_read_is_counted():
    port = free_udp_port()
    with UdpStream(port):
        source = StreamSource(f"udp://127.0.0.1:{port}", connect_timeout_s=30.0)
        try:
            assert source.fps == pytest.approx(25.0)
            frames = []
            for _ in range(8):
                frame = source.read()
                assert frame is not None and frame.image_bgr is not None
                assert frame.image_bgr.shape == (240, 320, 3)
                assert frame.timestamp_s <= time.monotonic()  # stamped on the local clock
                frames.append(frame)
                time.sleep(0.2)  # a busy detector: about 5 frames arrive meanwhile
        finally:
            source.close()
    indices = [f.index for f in frames]
    stamps = [f.timestamp_s for f in frames]
    assert indices == sorted(set(indices)) and stamps == sorted(set(stamps))
    positions = [f.stream_time_s for f in frames]  # the stream's own clock, kept
    assert None not in positions and positions == sorted(set(positions))
    assert max(b - a for a, b in zip(indices, indices[1:], strict=False)) > 1  # newest, not next
    assert source.dropped > 0
    assert source.received >= indices[-1] + 1
    assert source.read() is None  # closed


@needs_ffmpeg
@pytest.mark.parametrize("max_lag_s", [0.5, 60.0])
def test_a_burst_of_old_video_is_thrown_away_undecoded_to_the_next_keyframe(max_lag_s: float):
    # the link holds 2.5 s of video (keyframes every second), then delivers it all at once
    port = free_udp_port()
    relay = StallingRelay(port, stall_at=2.0, stall_s=2.5)
    try:
        with UdpStream(relay.port, seconds=12.0):
            source = StreamSource(
                f"udp://127.0.0.1:{port}", connect_timeout_s=30.0, max_lag_s=max_lag_s
            )
            try:
                assert wait_until(lambda: relay.released_at is not None, 30.0)
                after: list[float] = []  # age of each frame read in the 3 s after the burst
                while time.monotonic() < relay.released_at + 3.0:
                    frame = source.read()
                    if frame is not None and frame.image is not None:
                        after.append(time.monotonic() - frame.timestamp_s)
            finally:
                source.close()
    finally:
        relay.close()
    assert relay.held >= 40 and after
    assert source.lost == 0  # what the reader threw away is not lost on the way
    if max_lag_s < 1.0:
        assert source.behind >= 20  # most of the 62 frames held back, never decoded
    else:
        assert source.behind == 0  # every frame decoded, however late
    assert after[-1] < 0.5  # live again either way: small frames decode fast


@needs_ffmpeg
def test_a_lost_stream_is_reported_and_picked_up_again(caplog):
    port = free_udp_port()
    url = f"udp://127.0.0.1:{port}"
    caplog.set_level(logging.INFO, logger="sarmission.data.stream")
    first = UdpStream(port)
    source = StreamSource(url, connect_timeout_s=30.0, read_timeout_s=1.0)
    try:
        assert source.read().image_bgr is not None
        first.stop()
        seen = []  # what read() returns meanwhile: the last decoded frames, then none

        def read_until(condition) -> bool:
            return (f := source.read()) is not None and not seen.append(f) and condition()

        assert wait_until(lambda: read_until(lambda: "stream lost" in caplog.text), 30.0, 0.0)
        assert read_until(lambda: True) and seen[-1].image_bgr is None  # an outage frame
        outage_at = seen[-1].timestamp_s
        assert source.skipped >= 1 and source.reconnects == 0
        with UdpStream(port):
            assert wait_until(lambda: read_until(lambda: source.reconnects == 1), 60.0, 0.0)
            assert "stream back after" in caplog.text
            assert wait_until(lambda: read_until(lambda: seen[-1].image_bgr is not None), 30.0, 0.0)
            assert seen[-1].timestamp_s > outage_at
    finally:
        first.stop()
        source.close()
    assert f"{url}: " in caplog.text and "1 reconnection(s)" in caplog.text  # closing summary


@needs_ffmpeg
def test_corrupt_and_missing_datagrams_never_stop_the_stream(caplog):
    caplog.set_level(logging.WARNING, logger="sarmission.data.stream")
    port = free_udp_port()
    relay = CorruptingRelay(port)
    try:
        with UdpStream(relay.port, seconds=8.0):
            source = StreamSource(f"udp://127.0.0.1:{port}", connect_timeout_s=30.0)
            try:
                images = []
                assert wait_until(
                    lambda: (
                        (f := source.read()) is not None
                        and (f.image_bgr is None or not images.append(f))
                        and len(images) >= 40
                    ),
                    60.0,
                    step=0.0,
                )
            finally:
                source.close()
    finally:
        relay.close()
    assert relay.corrupted > 0 and relay.dropped > 0
    assert all(f.image_bgr.shape == (240, 320, 3) for f in images)
    assert source.lost > 0  # frames whose packets were damaged or dropped are counted
    warnings = [r for r in caplog.records if "missing from the stream" in r.getMessage()]
    assert len(warnings) == 1  # one warning, not one per damaged packet


@needs_ffmpeg
def test_detect_reads_a_udp_stream(tmp_path: Path):
    port = free_udp_port()
    out = tmp_path / "dets.json"
    with UdpStream(port):
        done = subprocess.run(
            [
                sys.executable,
                "-m",
                "sarmission.cli",
                "detect",
                f"udp://127.0.0.1:{port}",
                "--max-frames",
                "6",
                "--conf",
                "0",
                "--out",
                str(out),
            ],
            capture_output=True,
            text=True,
            timeout=180,
        )
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("6 frames, ")
    assert f"udp://127.0.0.1:{port}: " in done.stderr and "frames received" in done.stderr
    records = json.loads(out.read_text())
    assert {r["frame_index"] for r in records} and all(
        set(r) == {"image_id", "frame_index", "bbox", "score", "category_id"} for r in records
    )
    assert "\r" not in done.stderr  # no progress bar redraws into a pipe


@needs_ffmpeg
def test_run_takes_a_stream_url_as_its_camera(tmp_path: Path):
    port = free_udp_port()
    url = f"udp://127.0.0.1:{port}"
    with UdpStream(port):
        source = open_video_source(url)
        try:
            assert isinstance(source, StreamSource) and source.read().image_bgr is not None
        finally:
            source.close()
        done = subprocess.run(
            [
                sys.executable,
                "-m",
                "sarmission.cli",
                "run",
                "--connect",
                f"udpin:127.0.0.1:{free_udp_port()}",
                "--connect-timeout",
                "0.5",
                "--video",
                url,
                "--max-frames",
                "8",
                "--alerts-db",
                str(tmp_path / "alerts.db"),
            ],
            capture_output=True,
            text=True,
            timeout=180,
        )
    assert done.returncode == 0, done.stderr
    assert "frames received" in done.stderr  # the stream's summary when the run closes it


@needs_ffmpeg
def test_an_rtsp_camera_is_read_and_reopened_when_its_server_restarts(tmp_path: Path, caplog):
    caplog.set_level(logging.INFO, logger="sarmission.data.stream")
    server = RtspServer(tmp_path)
    port, url = server.port, server.url
    source = StreamSource(url, connect_timeout_s=30.0, read_timeout_s=1.0)
    try:
        frame = source.read()
        assert frame.image_bgr.shape == (240, 320, 3)
        if frame.stream_time_s is None:  # RTP's first packet may come before its timing
            frame = source.read()
        assert frame.stream_time_s is not None
        assert server.requests[:4] == ["OPTIONS", "DESCRIBE", "SETUP", "PLAY"]
        server.close()  # the camera reboots
        assert wait_until(lambda: "stream lost" in caplog.text, 30.0)
        server = RtspServer(tmp_path, port=port)
        back: list = []
        assert wait_until(
            lambda: (
                (f := source.read()) is not None
                and f.image_bgr is not None
                and source.reconnects == 1
                and not back.append(f)
            ),
            60.0,
            0.0,
        )
        assert "stream back after" in caplog.text and back[0].index > frame.index
    finally:
        source.close()
        server.close()


def flip_one_pid(data: bytes) -> bytes:
    """``data`` (MPEG-TS) with one video packet 3/4 of the way through moved to an unused PID,
    as a single bit error would: PyAV's demuxer then raised IndexError."""
    out = bytearray(data)
    count = len(out) // 188
    for k in range(3 * count // 4, count):
        p = k * 188
        pid = (out[p + 1] & 0x1F) << 8 | out[p + 2]
        if out[p] == 0x47 and out[p + 1] & 0x40 and pid == 0x100:
            out[p + 1], out[p + 2] = (out[p + 1] & 0xE0) | 0x01, 0xDA
            return bytes(out)
    raise AssertionError("no video packet to damage")


def write_latin1_title(path: Path) -> Path:
    """A Matroska clip whose title is not UTF-8 (PyAV's strict decoding raised on opening)."""
    assert FFMPEG is not None
    subprocess.run(
        [
            FFMPEG, "-hide_banner", "-loglevel", "error", "-y",
            "-f", "lavfi", "-i", "testsrc=size=320x240:rate=10", "-t", "1",
            "-c:v", "libx264", "-preset", "ultrafast", "-pix_fmt", "yuv420p",
            "-metadata", b"title=caf\xe9", str(path),
        ],
        check=True,
        timeout=120,
    )  # fmt: skip
    return path


@needs_ffmpeg
@pytest.mark.parametrize("damage", ["pid", "title"])
def test_data_that_breaks_the_demuxer_is_a_lost_stream_not_a_dead_reader(tmp_path, damage):
    """A corrupt packet (IndexError in PyAV) or a non-UTF-8 title (UnicodeDecodeError) once
    killed the reader thread: the mission stayed blind. Now it reconnects and reads on."""
    good = write_ts(tmp_path / "good.ts", seconds=3).read_bytes()
    if damage == "pid":  # past the demuxer's first look at the file (4 s and more)
        first = flip_one_pid(write_ts(tmp_path / "long.ts", seconds=6).read_bytes())
    else:
        first = write_latin1_title(tmp_path / "title.mkv").read_bytes()
    with TcpFiles([first, good]) as server:
        source = StreamSource(server.url, connect_timeout_s=30.0, read_timeout_s=1.0)
        try:
            assert wait_until(lambda: server.connections >= 2 and source.reconnects >= 1, 60.0)
            assert source._thread.is_alive()
        finally:
            source.close()


@needs_ffmpeg
def test_a_stream_that_ends_is_reconnected_with_a_growing_wait(tmp_path, caplog):
    """A URL whose stream ends (a file over HTTP, a TCP sender closing) was reopened in a tight
    loop: the clip replayed hundreds of times, 'stream back after 0.0 s' each time."""
    caplog.set_level(logging.WARNING, logger="sarmission.data.stream")
    clip = write_ts(tmp_path / "clip.ts", seconds=1).read_bytes()
    with TcpFiles([clip]) as server:
        source = StreamSource(server.url, connect_timeout_s=30.0, read_timeout_s=1.0)
        try:
            assert wait_until(lambda: source.reconnects >= 2, 60.0)
            time.sleep(6.0)
            connections = server.connections
        finally:
            source.close()
    # waits of 0.5 + 1 + 2 + 4 + 4 ... s: at most a handful of connections in those seconds
    assert connections <= 8
    lost = [r.getMessage() for r in caplog.records if "stream lost" in r.getMessage()]
    back = [r.getMessage() for r in caplog.records if "stream back after" in r.getMessage()]
    assert len(lost) == 1 and len(back) == 1  # rate-limited


@needs_ffmpeg
def test_an_outage_is_measured_from_the_last_frame(tmp_path, caplog):
    """The outage was measured from when the loss was noticed, so a stream that fell silent
    and came back was always 'back after 0.0 s'."""
    caplog.set_level(logging.WARNING, logger="sarmission.data.stream")
    # long enough that opening it does not read it all: the reader then waits on the silence
    # (Matroska: MPEG-TS holds its last frame back until the read fails)
    clip = write_ts(tmp_path / "clip.mkv", seconds=20, fmt="matroska").read_bytes()
    with TcpFiles([clip], hold_s=3.0) as server:  # silent for 3 s before each close
        source = StreamSource(server.url, connect_timeout_s=30.0, read_timeout_s=1.0)
        try:
            assert wait_until(lambda: source.reconnects >= 1, 60.0)
        finally:
            source.close()
    back = [r.getMessage() for r in caplog.records if "stream back after" in r.getMessage()]
    # at least the read timeout (1 s) of silence and the first wait (0.5 s) before reopening
    assert float(back[0].split("back after ")[1].split(" s")[0]) >= 1.4


@needs_ffmpeg
def test_a_rotated_stream_is_read_as_displayed(tmp_path):
    """A camera's display rotation was ignored: frames came on their side."""
    with TcpFiles([write_rotated(tmp_path, 90).read_bytes()]) as server:
        source = StreamSource(server.url, connect_timeout_s=30.0, read_timeout_s=1.0)
        try:
            frame = source.read()
        finally:
            source.close()
    assert (frame.yuv.height, frame.yuv.width) == (320, 240)
