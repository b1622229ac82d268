"""Frame sources on real files written by OpenCV: video, image folder, corrupt frames, errors."""

import logging
import subprocess

import cv2
import numpy as np
import pytest
from stream_sender import FFMPEG, needs_ffmpeg

from sarmission.data import Frame, FrameSourceError, open_frame_source

W, H = 64, 48


def image(i):
    return np.full((H, W, 3), (10 * i, 255 - 10 * i, 100), np.uint8)


def noise(i):
    return np.random.default_rng(i).integers(0, 256, (H, W, 3), dtype=np.uint8)


def write_video(path, fourcc, n, fps=10.0, make=image):
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), fps, (W, H))
    assert writer.isOpened()
    for i in range(n):
        writer.write(make(i))
    writer.release()


def test_mp4_video(tmp_path):
    path = tmp_path / "clip.mp4"
    write_video(path, "mp4v", 7, fps=10.0)
    source = open_frame_source(path)
    assert len(source) == 7 and source.fps == pytest.approx(10.0)
    frames = list(source)
    assert [f.index for f in frames] == list(range(7))
    assert frames[3].timestamp_s == pytest.approx(0.3)
    assert all(
        isinstance(f, Frame) and f.image_bgr.dtype == np.uint8 and f.image_bgr.shape == (H, W, 3)
        for f in frames
    )
    assert np.abs(frames[5].image_bgr.astype(int) - image(5)).mean() < 8  # lossy codec
    assert source.skipped == 0
    assert len(list(source)) == 7  # iterable again


def test_a_video_whose_container_states_no_frame_count_is_still_a_source(tmp_path):
    """Matroska and MPEG-TS (stream recordings) do not state a frame count: the source says
    ``length`` None, and is still true in a condition (``if source`` once called ``len()``,
    which raises for an unknown count, and ended a replay after its last frame)."""
    path = tmp_path / "clip.mkv"
    write_video(path, "MJPG", 5)
    source = open_frame_source(path, yuv=True)
    assert source.length is None
    with pytest.raises(TypeError, match="frame count unknown"):
        len(source)
    assert source and bool(source) is True
    assert [f.index for f in source] == list(range(5))


def test_video_with_corrupt_frame_is_skipped(tmp_path, caplog):
    path = tmp_path / "clip.avi"
    write_video(path, "MJPG", 6, make=noise)  # noise: each JPEG is a few kB
    data = bytearray(path.read_bytes())
    starts = [i for i in range(len(data) - 1) if data[i] == 0xFF and data[i + 1] == 0xD8]
    assert len(starts) == 6 and starts[3] - starts[2] > 1000  # one JPEG per frame
    data[starts[2] : starts[2] + 400] = bytes(400)  # destroy the header of frame 2
    path.write_bytes(bytes(data))
    source = open_frame_source(path)
    with caplog.at_level(logging.WARNING):
        indices = [f.index for f in source]
    assert indices == [0, 1, 3, 4, 5]
    assert source.skipped == 1 and "frame 2 skipped" in caplog.text


def test_png_folder_natural_order_and_corrupt_file(tmp_path, caplog):
    for i in (1, 2, 10):
        cv2.imwrite(str(tmp_path / f"frame{i}.png"), image(i))
    cv2.imwrite(str(tmp_path / "frame3.jpg"), image(3))
    (tmp_path / "frame5.png").write_bytes(b"\x89PNG\r\n\x1a\n garbage")  # corrupt
    (tmp_path / "notes.txt").write_text("not an image")
    source = open_frame_source(tmp_path, fps=5.0)
    assert len(source) == 5 and source.fps == 5.0
    with caplog.at_level(logging.WARNING):
        frames = list(source)
    assert [f.index for f in frames] == [0, 1, 2, 4]  # frame1, frame2, frame3, (5 bad), frame10
    assert [f.timestamp_s for f in frames] == [0.0, 0.2, 0.4, 0.8]
    np.testing.assert_array_equal(frames[3].image_bgr, image(10))  # PNG is lossless
    assert source.skipped == 1 and "frame5.png" in caplog.text


def test_errors(tmp_path):
    with pytest.raises(FrameSourceError, match="no such file"):
        open_frame_source(tmp_path / "missing.mp4")
    text = tmp_path / "notes.txt"
    text.write_text("hello")
    with pytest.raises(FrameSourceError, match="cannot open|unreadable"):
        open_frame_source(text)
    fake = tmp_path / "fake.mp4"
    fake.write_bytes(b"\x00" * 1000)
    with pytest.raises(FrameSourceError):
        open_frame_source(fake)
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(FrameSourceError, match="no images"):
        open_frame_source(empty)
    cv2.imwrite(str(tmp_path / "one.png"), image(0))
    with pytest.raises(FrameSourceError, match="single image"):
        open_frame_source(tmp_path / "one.png")
    with pytest.raises(FrameSourceError, match="fps"):
        open_frame_source(tmp_path, fps=0)
    assert issubclass(FrameSourceError, ValueError)


@needs_ffmpeg
def test_variable_frame_rate_video_keeps_its_presentation_times(tmp_path):
    """Frames are stamped with their times in the file, not index / fps: a camera recording at
    a varying rate (or a stream saved with gaps) keeps the real time between its frames."""
    durations = [0.1, 0.3, 0.05, 0.2, 0.1, 0.1]
    lines = []
    for i, duration in enumerate(durations):
        cv2.imwrite(str(tmp_path / f"f{i}.png"), image(i))
        lines += [f"file 'f{i}.png'", f"duration {duration}"]
    (tmp_path / "list.txt").write_text("\n".join(lines + [f"file 'f{len(durations) - 1}.png'"]))
    path = tmp_path / "vfr.mkv"
    subprocess.run(
        [
            FFMPEG,
            "-loglevel",
            "error",
            "-f",
            "concat",
            "-i",
            str(tmp_path / "list.txt"),
            "-fps_mode",
            "vfr",
            "-c:v",
            "libx264",
            "-preset",
            "ultrafast",
            "-pix_fmt",
            "yuv420p",
            str(path),
        ],
        check=True,
        timeout=120,
    )
    probe = subprocess.run(
        [
            FFMPEG.replace("ffmpeg", "ffprobe"),
            "-v",
            "error",
            "-select_streams",
            "v",
            "-show_entries",
            "frame=pts_time",
            "-of",
            "csv=p=0",
            str(path),
        ],
        check=True,
        capture_output=True,
        text=True,
        timeout=60,
    )
    expected = [float(v.strip(",")) for v in probe.stdout.split()]
    assert np.diff(expected).std() > 0.02  # the file's frame rate really varies
    source = open_frame_source(path)
    frames = list(source)
    assert [f.timestamp_s for f in frames] == pytest.approx(expected, abs=1e-6)
    assert [f.index for f in frames] == list(range(len(expected)))
    assert source.skipped == 0  # an estimated frame count past the end is no skipped frame


@pytest.mark.parametrize("yuv", [False, True])
def test_a_video_cut_short_says_so_in_one_line(tmp_path, caplog, yuv):
    path = tmp_path / "clip.avi"
    write_video(path, "MJPG", 8, make=noise)
    data = path.read_bytes()
    starts = [i for i in range(len(data) - 1) if data[i] == 0xFF and data[i + 1] == 0xD8]
    path.write_bytes(data[: starts[5]])  # frames 5..7 gone, the header still says 8
    source = open_frame_source(path, yuv=yuv)
    with caplog.at_level(logging.INFO):
        indices = [f.index for f in source]
    assert indices == [0, 1, 2, 3, 4] and source.skipped == 0
    lines = [r.getMessage() for r in caplog.records if "clip.avi" in r.getMessage()]
    assert lines == [f"{path}: the video ends at frame 5 of the 8 its header announces"]


def write_ts(path, seconds=1, offset_s=0.0, size="320x240", rate=10, fmt="mpegts"):
    """An H.264 clip of a test pattern (MPEG-TS unless ``fmt`` says otherwise) whose
    timestamps start at ``offset_s``."""
    subprocess.run(
        [
            FFMPEG, "-hide_banner", "-loglevel", "error", "-y",
            "-f", "lavfi", "-i", f"testsrc=size={size}:rate={rate}", "-t", str(seconds),
            "-c:v", "libx264", "-preset", "ultrafast", "-g", str(rate), "-pix_fmt", "yuv420p",
            "-output_ts_offset", str(offset_s), "-f", fmt, str(path),
        ],
        check=True,
        timeout=120,
    )  # fmt: skip
    return path


def write_rotated(folder, degrees=90):
    """An MP4 clip (moov first, so that it can be streamed) tagged to be shown turned by
    ``degrees`` counter-clockwise, as a phone records one held upright."""
    plain = write_ts(folder / "plain.mp4", fmt="mp4")
    path = folder / f"rotated{degrees}.mp4"
    subprocess.run(
        [
            FFMPEG, "-hide_banner", "-loglevel", "error", "-y", "-i", str(plain), "-c", "copy",
            "-metadata:s:v:0", f"rotate={degrees}", "-movflags", "+faststart", str(path),
        ],
        check=True,
        timeout=120,
    )  # fmt: skip
    return path


def write_jump(folder, offset_s=3600.0):
    """Two recordings joined end to end, the second's timestamps ``offset_s`` later."""
    first = write_ts(folder / "a.ts").read_bytes()
    second = write_ts(folder / "b.ts", offset_s=offset_s).read_bytes()
    path = folder / "jump.ts"
    path.write_bytes(first + second)
    return path


@needs_ffmpeg
@pytest.mark.parametrize("yuv", [True, False])
def test_a_jump_in_timestamps_is_a_discontinuity_not_an_hour_of_time(tmp_path, caplog, yuv):
    """Joined recordings once stamped the second half an hour later (and a live replay of the
    file slept that hour); the clock now goes on at the frame period, with one warning."""
    path = write_jump(tmp_path)
    source = open_frame_source(path, yuv=yuv)
    frames = list(source)
    times = [f.timestamp_s for f in frames]
    assert len(frames) == 20 and source.skipped == 0
    assert np.diff(times) == pytest.approx([0.1] * 19, abs=1e-3)
    jumps = [r for r in caplog.records if "timestamps jump" in r.getMessage()]
    assert len(jumps) == 1 and str(path) in jumps[0].getMessage()


def test_skipped_frames_are_all_counted_but_warned_about_at_most_every_few_seconds(
    tmp_path, caplog
):
    """A folder of damaged images once logged one warning per frame."""
    cv2.imwrite(str(tmp_path / "f00.png"), image(0))
    for i in range(1, 11):
        (tmp_path / f"f{i:02d}.png").write_bytes(b"not a png")
    source = open_frame_source(tmp_path)
    with caplog.at_level(logging.WARNING):
        assert len(list(source)) == 1
    assert source.skipped == 10
    assert len([r for r in caplog.records if "skipped" in r.getMessage()]) == 1


@pytest.mark.parametrize("fps", [float("nan"), float("inf"), 1e-300, 0.0, -1.0, 1e6])
def test_a_frame_rate_that_makes_no_sense_is_refused(tmp_path, fps):
    cv2.imwrite(str(tmp_path / "f0.png"), image(0))
    with pytest.raises(FrameSourceError, match="fps must be from 0.001 to 1000"):
        open_frame_source(tmp_path, fps)
