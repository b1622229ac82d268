"""rerun logging of a mission: what the camera saw, what MITE-Net proposed and detected, the tracks
and locks, the telemetry, and the targets on the map.

Entity paths mirror the data flow::

    camera/frame          the frame (JPEG, scaled to ``image_width``)
    camera/proposals      TTM-RPN boxes
    camera/detections     head detections, labelled "class score"
    camera/tracks         Kalman tracks, labelled by id; locked ones in red
    telemetry/...         altitude, attitude, stage timings (time series)
    map/drone, map/targets  positions on the globe (GeoPoints)

All 2-D entities share the frame's pixel space; boxes given in full-resolution pixels are scaled
with the image.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from sarmission.yuv import YuvImage, picture_size

if TYPE_CHECKING:
    import rerun as rr

log = logging.getLogger(__name__)

PROPOSAL_COLOUR = (80, 160, 255)
DETECTION_COLOUR = (255, 200, 0)
TRACK_COLOUR = (0, 220, 120)
LOCKED_COLOUR = (255, 40, 40)


def _rerun():  # noqa: ANN202 - the rerun module
    """rerun, imported on first use: a session that records nothing does not pay its memory."""
    import rerun

    return rerun


class Recorder:
    """Log a mission to a rerun recording: ``save`` to an ``.rrd`` file or ``spawn`` a viewer.

    Args:
        mode: "save" (write ``path``), "spawn" (start the viewer and stream to it) or "off".
        path: the ``.rrd`` file for "save".
        image_width: frames are logged scaled to this width (4K frames are 25 MB raw each).
        frame_every: log one frame image in this many (overlays are logged every frame).
        jpeg_quality: JPEG quality of the logged frames.
    """

    def __init__(
        self,
        mode: str,
        path: str | Path | None = None,
        image_width: int = 1280,
        frame_every: int = 5,
        jpeg_quality: int = 80,
        application_id: str = "sarmission",
    ) -> None:
        if mode not in ("save", "spawn", "off"):
            raise ValueError(f"rerun mode must be 'save', 'spawn' or 'off', got {mode!r}")
        if mode == "save" and not path:
            raise ValueError("rerun mode 'save' needs a file path")
        if frame_every < 1 or image_width < 16:
            raise ValueError("frame_every must be >= 1 and image_width >= 16")
        self.mode = mode
        self.path = Path(path) if path else None
        self.image_width = image_width
        self.frame_every = frame_every
        self.jpeg_quality = jpeg_quality
        self._scale = 1.0
        self._stream: rr.RecordingStream | None = None
        if mode == "off":
            return
        self._stream = _rerun().RecordingStream(application_id)
        if mode == "save":
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._stream.save(str(self.path))
        else:
            self._stream.spawn()

    @property
    def enabled(self) -> bool:
        """Whether anything is recorded."""
        return self._stream is not None

    def set_time(self, frame_index: int, timestamp_s: float) -> None:
        """Set the timelines (``frame`` sequence and ``time`` in seconds) for the next logs."""
        if self._stream is None:
            return
        self._stream.set_time("frame", sequence=int(frame_index))
        self._stream.set_time("time", duration=float(timestamp_s))

    def frame(self, frame_index: int, image_bgr: np.ndarray | YuvImage) -> None:
        """Log the camera frame (every ``frame_every``-th call's frame index) as a JPEG (a
        :class:`~sarmission.yuv.YuvImage` is converted to BGR for the frames logged only)."""
        if self._stream is None:
            return
        height, width = picture_size(image_bgr)
        self._scale = min(1.0, self.image_width / width)
        if frame_index % self.frame_every:
            return
        if isinstance(image_bgr, YuvImage):
            image_bgr = image_bgr.bgr
        small = (
            image_bgr
            if self._scale == 1.0
            else cv2.resize(
                image_bgr,
                (round(width * self._scale), round(height * self._scale)),
                interpolation=cv2.INTER_AREA,
            )
        )
        ok, jpeg = cv2.imencode(".jpg", small, [cv2.IMWRITE_JPEG_QUALITY, self.jpeg_quality])
        if ok:
            image = _rerun().EncodedImage(contents=jpeg.tobytes(), media_type="image/jpeg")
            self._stream.log("camera/frame", image)

    def boxes(
        self,
        entity: str,
        boxes_xyxy: np.ndarray,
        labels: list[str] | None = None,
        colours: list[tuple[int, int, int]] | tuple[int, int, int] | None = None,
    ) -> None:
        """Log full-resolution ``[N, 4]`` boxes under ``camera/<entity>`` in the frame's space."""
        if self._stream is None:
            return
        b = np.asarray(boxes_xyxy, dtype=np.float32).reshape(-1, 4) * self._scale
        self._stream.log(
            f"camera/{entity}",
            _rerun().Boxes2D(
                mins=b[:, :2],
                sizes=b[:, 2:] - b[:, :2],
                labels=labels,
                colors=colours,
                show_labels=labels is not None,
            ),
        )

    def scalar(self, name: str, value: float | None) -> None:
        """Log one time-series value under ``telemetry/<name>`` (skipped when None)."""
        if self._stream is None or value is None or not np.isfinite(value):
            return
        self._stream.log(f"telemetry/{name}", _rerun().Scalars(float(value)))

    def geo_points(
        self,
        entity: str,
        lat_lon: np.ndarray,
        radius_m: float = 5.0,
        colour: tuple[int, int, int] = LOCKED_COLOUR,
    ) -> None:
        """Log ``[N, 2]`` latitude/longitude points under ``map/<entity>`` (radius in metres)."""
        if self._stream is None:
            return
        points = np.asarray(lat_lon, dtype=np.float64).reshape(-1, 2)
        self._stream.log(
            f"map/{entity}",
            _rerun().GeoPoints(
                lat_lon=points, radii=np.full(len(points), radius_m, np.float32), colors=[colour]
            ),
        )

    def text(self, entity: str, message: str, level: str = "INFO") -> None:
        """Log a line of text (alerts, skipped frames) under ``log/<entity>``."""
        if self._stream is None:
            return
        self._stream.log(f"log/{entity}", _rerun().TextLog(message, level=level))

    def close(self) -> None:
        """Flush and close the recording (the ``.rrd`` file is complete after this)."""
        if self._stream is None:
            return
        self._stream.flush()
        self._stream.disconnect()
        self._stream = None
