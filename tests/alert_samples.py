"""Sample alerts for the alert store, export and feed tests."""

from __future__ import annotations

import time

import numpy as np

from sarmission.alerts.model import Alert
from sarmission.alerts.thumbnail import crop_thumbnail


def sample_frame(seed: int = 0) -> np.ndarray:
    """A small sea-like BGR frame with one bright blob (a swimmer) at (160, 120)."""
    rng = np.random.default_rng(seed)
    frame = np.empty((240, 320, 3), np.uint8)
    frame[:] = (110, 80, 30)
    frame += rng.integers(0, 25, frame.shape, dtype=np.uint8)
    frame[116:125, 156:165] = (40, 120, 235)
    frame[117:120, 158:162] = (170, 200, 230)
    return frame


def make_alert(target_id: int = 1, positioned: bool = True, **changes: object) -> Alert:
    """An alert near Canberra with a thumbnail; ``positioned=False`` for stale telemetry."""
    fields: dict[str, object] = dict(
        mission_id="test-mission",
        target_id=target_id,
        class_name="swimmer",
        score=0.91,
        lock_time=time.time(),
        frame_index=100 + target_id,
        position=(-35.362912345678 + target_id * 1e-4, 149.165234567891) if positioned else None,
        position_note="" if positioned else "telemetry stale (2.4 s)",
        error_m=4.2 if positioned else None,
        drone_position=(-35.3630, 149.1650, 60.0),
        track=[(time.time() - 1.0, -35.3629, 149.1652)],
        pixel_track=[(99, 1920.5, 1080.25), (100, 1921.0, 1080.75)],
        thumbnail=crop_thumbnail(sample_frame(target_id), (160, 120), side=48, out_size=192),
    )
    fields.update(changes)
    return Alert(**fields)  # type: ignore[arg-type]
