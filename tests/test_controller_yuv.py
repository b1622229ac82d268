"""The mission controller on frames given as YUV planes: searched as BGR frames are, the alert's
thumbnail converted from the planes around the target alone."""

from __future__ import annotations

import numpy as np
import pytest
from scripted_detector import ScriptedDetector
from test_controller_integrity import DRONE, HFOV_DEG, H, W, hover, nadir_pixel, script
from test_yuv import yuv_of

from sarmission.alerts.store import AlertStore
from sarmission.mavlink.telemetry import TelemetryBuffer
from sarmission.mission.config import load_mission
from sarmission.mission.controller import MissionController


@pytest.fixture
def mission():
    overrides = {"camera.width": W, "camera.height": H, "camera.hfov_deg": HFOV_DEG}
    return load_mission(overrides={**overrides, "name": "yuv"})


def scene() -> np.ndarray:
    """A grey-blue sea with an orange patch where the scripted target is."""
    frame = np.empty((H, W, 3), np.uint8)
    frame[:] = (120, 100, 60)
    u, v = (int(c) for c in nadir_pixel(60.0))
    frame[v - 4 : v + 4, u - 4 : u + 4] = (0, 128, 255)
    return frame


def alerts_of(tmp_path, mission, frame) -> tuple[list, MissionController]:
    buf = TelemetryBuffer(stale_after_s=mission.telemetry.stale_after_s)
    buf.set_home(*DRONE, 2.0)
    hover(buf, 3.0, 60.0)
    with AlertStore(tmp_path / f"{type(frame).__name__}.db") as store:
        ctl = MissionController(mission, ScriptedDetector(script(10, 60.0)), buf, store)
        for i in range(10):
            ctl.process(i, i / 10.0, frame)
    return ctl.stats.candidates, ctl


def test_yuv_frames_are_searched_and_thumbnailed_as_their_bgr(tmp_path, mission):
    planes = yuv_of(scene())
    from_yuv, ctl = alerts_of(tmp_path, mission, planes)
    assert ctl.stats.frames == 10 and not ctl.stats.skipped
    assert "bgr" not in vars(planes)  # never converted whole
    from_bgr, _ = alerts_of(tmp_path, mission, planes.bgr.copy())
    assert len(from_yuv) == len(from_bgr) == 1
    assert from_yuv[0].thumbnail == from_bgr[0].thumbnail


def test_a_yuv_frame_of_another_size_is_skipped(tmp_path, mission):
    buf = TelemetryBuffer(stale_after_s=mission.telemetry.stale_after_s)
    with AlertStore(tmp_path / "a.db") as store:
        ctl = MissionController(mission, ScriptedDetector(script(2, 60.0)), buf, store)
        ctl.process(0, 0.0, yuv_of(scene()))
        ctl.process(1, 0.1, yuv_of(scene()[:, : W // 2]))
    assert ctl.stats.frames == 1 and sum(ctl.stats.skipped.values()) == 1
