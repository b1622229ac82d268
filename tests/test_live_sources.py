"""Live frame sources: a camera's frames are stamped with their capture time on the clock the
telemetry is mapped to (``time.monotonic()``), and a camera that cannot be opened says why."""

from __future__ import annotations

import threading
import time

import cv2
import numpy as np
import pytest
from stream_sender import needs_ffmpeg
from test_frames import write_jump

from sarmission.mission import live_sources
from sarmission.mission.live_sources import CameraSource, FileSource, capture_time


class FakeCapture:
    """Stands in for ``cv2.VideoCapture``: grabs succeed per ``grabs``; ``driver_ms`` is what
    the backend reports as ``CAP_PROP_POS_MSEC`` after each grab (None: the grab time)."""

    def __init__(self, grabs: list[bool], driver_ms: list[float | None]) -> None:
        self.grabs = list(grabs)
        self.driver_ms = list(driver_ms)
        self.settings: dict[int, float] = {}
        self.grabbed_at: list[float] = []
        self.released = False

    def isOpened(self) -> bool:  # noqa: N802 - OpenCV's name
        return True

    def set(self, prop: int, value: float) -> bool:
        self.settings[prop] = value
        return True

    def grab(self) -> bool:
        time.sleep(0.01)  # the frame arrives ...
        self.grabbed_at.append(time.monotonic())
        return self.grabs.pop(0)

    def get(self, prop: int) -> float:
        assert prop == cv2.CAP_PROP_POS_MSEC
        ms = self.driver_ms.pop(0)
        return self.grabbed_at[-1] * 1000.0 if ms is None else ms

    def retrieve(self) -> tuple[bool, np.ndarray]:
        time.sleep(0.05)  # ... and takes a while to decode
        return True, np.zeros((4, 4, 3), np.uint8)

    def release(self) -> None:
        self.released = True


def camera_with(monkeypatch: pytest.MonkeyPatch, capture: FakeCapture) -> CameraSource:
    monkeypatch.setattr(live_sources.cv2, "VideoCapture", lambda index: capture)
    return CameraSource(0)


def test_frames_are_stamped_at_the_grab_not_after_decoding(monkeypatch):
    capture = FakeCapture([True, True], [12.5, None])  # 12.5 ms: a stream position, not a time
    camera = camera_with(monkeypatch, capture)
    assert capture.settings[cv2.CAP_PROP_BUFFERSIZE] == 1  # the newest frame, not a queued one
    first, second = camera.read(), camera.read()
    # within 20 ms of the grab, not 50 ms later when the image is decoded
    assert first.timestamp_s == pytest.approx(capture.grabbed_at[0], abs=0.02)
    assert second.timestamp_s == pytest.approx(capture.grabbed_at[1], abs=0.02)
    assert (first.index, second.index) == (0, 1) and first.image_bgr is not None


def test_the_drivers_capture_time_is_used_when_it_is_on_our_clock(monkeypatch):
    exposure = time.monotonic() + 0.005  # during the next grab, before it returns
    capture = FakeCapture([True, False], [exposure * 1000.0, None])
    camera = camera_with(monkeypatch, capture)
    frame = camera.read()
    assert frame.timestamp_s == pytest.approx(exposure, abs=1e-6)
    failed = camera.read()
    assert failed.image_bgr is None and failed.index == 1 and camera.skipped == 1
    camera.close()
    assert capture.released


@pytest.mark.parametrize(
    ("driver_ms", "expected"),
    [
        (99_800.0, 99.8),  # 0.2 s before the grab returned: the driver's time
        (100_000.0, 100.0),
        (98_500.0, 100.0),  # 1.5 s old: not believable, the grab's time
        (100_300.0, 100.0),  # in the future: another clock
        (0.0, 100.0),  # the first frame's stream position
    ],
)
def test_capture_time(driver_ms, expected):
    assert capture_time(driver_ms, 100.0) == pytest.approx(expected)


def test_a_camera_that_cannot_be_opened_says_why(monkeypatch):
    class Closed(FakeCapture):
        def isOpened(self) -> bool:  # noqa: N802
            return False

    capture = Closed([], [])
    monkeypatch.setattr(live_sources.cv2, "VideoCapture", lambda index: capture)
    monkeypatch.setattr(live_sources.sys, "platform", "linux")
    with pytest.raises(
        OSError,
        match=r"^cannot open camera 97: no such device "
        r"\(/dev/video97 does not exist\)$",
    ):
        CameraSource(97)
    assert capture.released


def in_thread(call, timeout_s: float = 60.0):
    """``call()`` run in a thread; its result, or a failed test when it hangs."""
    result: list[object] = []
    thread = threading.Thread(target=lambda: result.append(call()), daemon=True)
    thread.start()
    thread.join(timeout_s)
    assert not thread.is_alive(), "hung"
    return result[0]


@needs_ffmpeg
def test_a_file_played_as_a_camera_goes_across_a_jump_in_its_timestamps(tmp_path):
    """Two recordings joined, the second stamped an hour later: the file once slept that hour in
    one wait that no stop could end."""
    source = FileSource(write_jump(tmp_path), realtime=True)
    try:
        frames = in_thread(lambda: list(iter(source.read, None)))
    finally:
        source.close()
    assert len(frames) == 20
    assert all(f.image is not None for f in frames)


def test_a_stop_request_ends_the_wait_for_a_frame(tmp_path):
    """An image folder at 0.01 frames/s waits 100 s for its second frame; a stop (Ctrl-C,
    --duration) ends that wait and the frame comes at once."""
    for i in range(2):
        cv2.imwrite(str(tmp_path / f"f{i}.png"), np.full((48, 64, 3), 40 * i, np.uint8))
    source = FileSource(tmp_path, fps=0.01)
    stop = threading.Event()
    source.watch(stop)
    try:
        assert source.read().index == 0
        threading.Timer(0.2, stop.set).start()
        assert in_thread(source.read).index == 1
    finally:
        source.close()


def test_a_deadline_ends_the_wait_for_a_frame(tmp_path):
    for i in range(2):
        cv2.imwrite(str(tmp_path / f"f{i}.png"), np.full((48, 64, 3), 40 * i, np.uint8))
    source = FileSource(tmp_path, fps=0.01)
    source.watch(deadline=time.monotonic() + 0.2)
    try:
        assert source.read().index == 0
        assert in_thread(source.read).index == 1
    finally:
        source.close()
