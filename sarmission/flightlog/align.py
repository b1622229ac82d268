"""Frames onto the flight log's clock: which log time each frame was captured at.

For a video, ``log time = video time + offset``, the offset from, in this order:

1. ``--time-offset S`` (the log time, in the log's clock, at which the video starts);
2. a subtitle sidecar (DJI SRT): the log is in the video's own clock, offset 0;
3. a camera trigger of the log (CAM/TRIG, CAMERA_FEEDBACK, camera_capture): the camera
   started recording on it. The first one, or, where the video's creation time is on the
   log's UTC clock, the one nearest it; when none lies within :data:`TRIGGER_SLACK_S` of the
   creation time the two disagree and there is no alignment (a wrong one would misplace
   every alert by the aircraft's travel in the gap);
4. the video's creation time (MP4 ``mvhd``) on the log's UTC clock, when it falls inside the
   log.

For an image folder each image gets its own time: its capture time where the log is the
images' own EXIF, else the n-th camera trigger for the n-th image (the counts must agree),
else ``--time-offset`` plus the folder's nominal frame times.

Whatever the method, a video whose creation time lies more than
:data:`CLOCK_SLACK_S` (a time zone's worth) outside the log was not recorded on that flight
(another day): :class:`AlignmentError`. So is a video that would lie wholly outside the log.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from datetime import UTC, datetime

import numpy as np

from sarmission.flightlog.model import FlightLog

#: How far a camera clock may be from UTC (local time stored as UTC): 14 hours.
CLOCK_SLACK_S = 14 * 3600.0
#: How far a camera trigger may be from the video's creation time (on the log's UTC clock)
#: to be taken as the recording's start: creation times have whole seconds, and some cameras
#: stamp the file a few seconds after recording began.
TRIGGER_SLACK_S = 10.0


class AlignmentError(ValueError):
    """The frames cannot be put on the log's clock (one line for the operator)."""


@dataclass(frozen=True)
class Alignment:
    """How frame times map onto the log's clock; ``method`` is printed.

    ``image_times`` maps image file names to log times (every image of the folder: the
    ones the log does not place are interpolated over their order, for the frame's timestamp
    only); ``placed`` names the images the log itself places.
    """

    method: str
    offset_s: float = 0.0
    image_times: dict[str, float] | None = None
    placed: frozenset[str] = field(default_factory=frozenset)

    def log_time(self, frame_t: float, name: str | None = None) -> float:
        """The log time of a frame at ``frame_t`` (its file ``name`` for an image folder)."""
        if self.image_times is not None and name is not None and name in self.image_times:
            return self.image_times[name]
        return frame_t + self.offset_s


def _utc(t: float) -> str:
    return datetime.fromtimestamp(t, UTC).strftime("%Y-%m-%d %H:%M:%S UTC")


def _check_day(log: FlightLog, created: float | None) -> None:
    span = log.utc_span()
    if created is None or span is None:
        return
    if created < span[0] - CLOCK_SLACK_S or created > span[1] + CLOCK_SLACK_S:
        raise AlignmentError(
            f"the video was recorded {_utc(created)} but the log {log.path.name} covers "
            f"{_utc(span[0])} to {_utc(span[1])}: not the same flight; no positions"
        )


def _check_overlap(log: FlightLog, start: float, duration_s: float | None) -> None:
    t0, t1 = log.span
    end = start + (duration_s or 0.0)
    if end < t0 or start > t1:
        raise AlignmentError(
            f"the video lies outside the log {log.path.name} (video at log time {start:.1f}"
            f" to {end:.1f} s, positions {t0:.1f} to {t1:.1f} s); no positions"
        )


def align_video(
    log: FlightLog,
    *,
    created: float | None,
    duration_s: float | None,
    offset_s: float | None = None,
) -> Alignment:
    """The alignment of a video (see the module docstring); :class:`AlignmentError` when
    there is none or it contradicts the log."""
    if offset_s is None:
        _check_day(log, created)
    if offset_s is not None:
        result = Alignment(f"given offset: the video starts at log time {offset_s:.3f} s", offset_s)
    elif log.per_frame:
        stated = log.stated_start_posix
        if created is not None and stated is not None and abs(created - stated) > CLOCK_SLACK_S:
            raise AlignmentError(
                f"the video was recorded {_utc(created)} but its subtitle file "
                f"{log.path.name} was written {_utc(stated)[:-4]} (its own clock): not the "
                "same recording; no positions"
            )
        result = Alignment("the subtitle file's own times (the video's clock)", 0.0)
    elif log.triggers:
        result = _trigger_alignment(log, created)
    elif created is not None and log.utc_offset_s is not None:
        t = created - log.utc_offset_s
        t0, t1 = log.span
        if not t0 - 1.0 <= t <= t1:
            raise AlignmentError(
                f"the video's creation time {_utc(created)} is not inside the log "
                f"{log.path.name} (positions from {_utc(t0 + log.utc_offset_s)} to "
                f"{_utc(t1 + log.utc_offset_s)}; cameras often store local time): give "
                "--time-offset; no positions"
            )
        result = Alignment(f"the video's creation time {_utc(created)} = log time {t:.3f} s", t)
    else:
        why = "no camera trigger in the log, " + (
            "no creation time in the video" if created is None else "no UTC in the log"
        )
        raise AlignmentError(
            f"cannot align the video with {log.path.name}: {why}; give --time-offset; no positions"
        )
    _check_overlap(log, result.offset_s, duration_s)
    return result


def _trigger_alignment(log: FlightLog, created: float | None) -> Alignment:
    """The camera trigger the recording started on (module docstring, 3)."""
    if created is None or log.utc_offset_s is None:
        t = log.triggers[0]
        return Alignment(
            f"camera trigger 1 of {len(log.triggers)} at log time {t:.3f} s "
            "(the recording started on it)",
            t,
        )
    at = created - log.utc_offset_s
    k = int(np.argmin([abs(t - at) for t in log.triggers]))
    t = log.triggers[k]
    if abs(t - at) > TRIGGER_SLACK_S:
        raise AlignmentError(
            f"the video's creation time {_utc(created)} (log time {at:.1f} s) and the camera "
            f"triggers of {log.path.name} disagree: the nearest, at {t:.1f} s, is "
            f"{abs(t - at):.0f} s away; give --time-offset; no positions"
        )
    return Alignment(
        f"camera trigger {k + 1} of {len(log.triggers)} at log time {t:.3f} s (the recording "
        f"started on it; {t - at:+.1f} s from the video's creation time)",
        t,
    )


def align_images(
    log: FlightLog, names: list[str], fps: float, offset_s: float | None = None
) -> Alignment:
    """The alignment of an image folder whose files, in frame order, are ``names``."""
    if offset_s is not None:
        return Alignment(
            f"given offset: image 1 at log time {offset_s:.3f} s, then 1/{fps:g} s apart", offset_s
        )
    if log.image_times:
        known = {n: t for n, t in log.image_times.items() if n in names}
        if not known:
            raise AlignmentError(
                f"{log.path.name}: none of its images is in the replayed folder; no positions"
            )
        return _images(names, known, "each image's own EXIF/XMP")
    if log.triggers:
        if len(log.triggers) != len(names):
            raise AlignmentError(
                f"{len(names)} images but {len(log.triggers)} camera triggers in "
                f"{log.path.name}: cannot pair them; give --time-offset; no positions"
            )
        return _images(
            names,
            dict(zip(names, log.triggers, strict=True)),
            f"image n = camera trigger n ({len(names)} triggers)",
        )
    raise AlignmentError(
        f"cannot align the images with {log.path.name}: no camera trigger "
        "in the log; give --time-offset; no positions"
    )


def _images(names: list[str], known: dict[str, float], method: str) -> Alignment:
    idx = np.array([k for k, n in enumerate(names) if n in known], dtype=float)
    times = np.array([known[n] for n in names if n in known], dtype=float)
    every = np.interp(np.arange(len(names), dtype=float), idx, times)
    if len(idx) > 1:  # beyond the ends: the mean spacing
        step = float(np.diff(times).mean() / np.diff(idx).mean())
        for k in range(len(names)):
            if k < idx[0] or k > idx[-1]:
                every[k] = (
                    times[0] + (k - idx[0]) * step
                    if k < idx[0]
                    else times[-1] + (k - idx[-1]) * step
                )
    full = {n: float(every[k]) for k, n in enumerate(names) if math.isfinite(every[k])}
    return Alignment(method, float(every[0]) if len(every) else 0.0, full, frozenset(known))
