"""Detectors with MITE-Net's ``process`` interface for controller tests, where the detector is
not what is under test: one replays a per-frame script, the other finds bright blobs.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from sarmission.perception.types import Detections, FrameResult, Proposals

CLASSES = ("swimmer", "swimmer_with_life_jacket")


def _result(timestamp: float, boxes: list, scores: list, classes: list) -> FrameResult:
    det = Detections(
        np.asarray(boxes, np.float32).reshape(-1, 4),
        np.asarray(scores, np.float32).reshape(-1),
        np.asarray(classes, np.int64).reshape(-1),
    )
    return FrameResult(timestamp, det, Proposals(boxes=det.boxes.copy()), None)


class ScriptedDetector:
    """Returns ``script[n]`` (a list of ``(box_xyxy, score, class_id)``) on its n-th call.
    ``resets`` holds the number of calls made before each :meth:`reset`."""

    classes = CLASSES

    def __init__(self, script: list[list[tuple[tuple[float, ...], float, int]]]) -> None:
        self.script = script
        self.calls = 0
        self.resets: list[int] = []
        self.per_stage_ms: dict[str, float] = {}

    def process(
        self,
        frame_bgr: np.ndarray,
        timestamp: float,
        shift_px: tuple[float, float] | None = None,
        person_px: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> FrameResult:
        items = self.script[self.calls] if self.calls < len(self.script) else []
        self.calls += 1
        return _result(
            timestamp, [b for b, _, _ in items], [s for _, s, _ in items], [c for _, _, c in items]
        )

    def reset(self) -> None:
        """Recorded (when, in calls) so that tests see it; the script goes on with the next
        call."""
        self.resets.append(self.calls)


class BlobDetector:
    """Boxes around connected regions brighter than ``threshold`` (grey level) in the frame."""

    classes = CLASSES

    def __init__(self, threshold: int = 200, min_area: int = 2) -> None:
        self.threshold = threshold
        self.min_area = min_area
        self.per_stage_ms: dict[str, float] = {}

    def process(
        self,
        frame_bgr: np.ndarray,
        timestamp: float,
        shift_px: tuple[float, float] | None = None,
        person_px: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> FrameResult:
        grey = cv2.cvtColor(frame_bgr, cv2.COLOR_BGR2GRAY)
        n, _, stats, _ = cv2.connectedComponentsWithStats(
            (grey > self.threshold).astype(np.uint8), connectivity=8
        )
        boxes = [(x, y, x + w, y + h) for x, y, w, h, area in stats[1:n] if area >= self.min_area]
        return _result(timestamp, boxes, [0.9] * len(boxes), [0] * len(boxes))

    def reset(self) -> None:
        """Stateless: nothing to forget."""
