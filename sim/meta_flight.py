"""A flight that follows a dataset's own per-frame telemetry (``meta``), for replaying footage.

:class:`MetaFlight` has the interface of :class:`sim.flight.Flight` that the MAVLink vehicle and
the telemetry model use (``mission``, ``state_at``, ``camera_pose_at``, ``survey_duration``,
``reposition``, ``set_roi``), so :class:`sim.vehicle.SimVehicle` streams the footage's recorded
flight exactly as it streams a planned one.

From the frames' :class:`~sarmission.data.coco_video.FrameTelemetry`:

- time of frame ``i``: its ``time`` minus the first frame's (when the known times increase
  strictly; missing ones are interpolated over the frame index), else ``frame_index / fps``;
- position: ``latitude``/``longitude`` -> north/east metres from home, ``down = -altitude``
  (altitude is above take-off); home is the first frame's position at altitude 0 unless given;
- vehicle yaw from ``compass_heading``, roll and pitch level (not in the data; irrelevant for an
  earth-stabilised gimbal); velocity is the slope of the piecewise-linear position;
- gimbal: pitch from ``gimbal_pitch`` read with the file's sign convention
  (:mod:`sarmission.data.meta_conventions`; a file with mixed signs is :class:`NoUsableMeta`),
  else the mission's mount pitch; roll from ``gimbal_roll``,
  yaw relative to the vehicle = ``gimbal_heading - compass_heading`` (the data gives earth-frame
  headings), reported in the ``"vehicle"`` frame like a stabilised gimbal.

A value missing on some frames is interpolated linearly in time from the frames that have it
(held before the first and after the last); headings are unwrapped first. Between frames every
quantity is interpolated linearly in time; before the first frame and after the last the flight
holds the end state (or, with ``loop``, starts over with a period of ``frame count / fps``).

``start_s`` is the sim time at which footage time 0 is shown; ``None`` holds the first frame's
state until :meth:`MetaFlight.start_at` is called (the replay starts the footage when the
controller reads its first frame, so nothing is missed while the link comes up).

Replayed footage cannot be steered: :attr:`MetaFlight.steerable` is False, and the vehicle
answers DO_REPOSITION and DO_SET_ROI_* with MAV_RESULT_DENIED (the command is known but cannot
be carried out in this state) and a log line; ``reposition``/``set_roi`` here change nothing.

The mission the flight carries (:attr:`MetaFlight.mission`) is the given one with home moved to
the footage's home, ``camera.gimbal`` set when the data has gimbal angles, and the telemetry
noise set to zero: the dataset's telemetry is already a measurement.
"""

from __future__ import annotations

import dataclasses
import logging
import math

import numpy as np

from sarmission.data.coco_video import FrameTelemetry, VideoDataset
from sarmission.data.meta_conventions import DEPRESSION, ConventionError, dataset_conventions
from sarmission.data.sequence import sequence_images
from sarmission.geo.camera import CameraPose
from sarmission.mission.config import MissionConfig, load_mission
from sim.flight import VehicleState
from sim.truth_frames import geodetic_to_ned

log = logging.getLogger(__name__)


class NoUsableMeta(ValueError):
    """The footage's telemetry cannot place the camera (no latitude, longitude or altitude)."""


def dataset_fps(dataset: VideoDataset, video_id: int | None) -> float | None:
    """The frame rate an annotation file declares for a video (video entry, then ``info``)."""
    video = next((v for v in dataset.videos if v.id == video_id), None)
    for value in (
        (video.extra.get("fps") if video is not None else None),
        dataset.info.get("fps") if isinstance(dataset.info, dict) else None,
    ):
        try:
            fps = float(value) if value is not None else 0.0
        except (TypeError, ValueError):
            continue
        if fps > 0 and math.isfinite(fps):
            return fps
    return None


def _fill(
    times: np.ndarray, values: list[float | None], period: float | None = None
) -> np.ndarray | None:
    """Values at every frame time, missing ones interpolated (None when none is known).

    With ``period`` (360 for headings in degrees) the known values are unwrapped first, so the
    result is continuous (not wrapped back into range)."""
    known = [
        (t, v) for t, v in zip(times, values, strict=True) if v is not None and math.isfinite(v)
    ]
    if not known:
        return None
    kt = np.array([k[0] for k in known])
    kv = np.array([k[1] for k in known], dtype=float)
    if period is not None:
        kv = np.unwrap(kv, period=period)
    return np.interp(times, kt, kv)


def _frame_times(
    indices: np.ndarray, meta: list[FrameTelemetry], fps: float, use_meta_time: bool
) -> tuple[np.ndarray, str]:
    """Footage time of each frame (first frame at 0) and how it was found."""
    by_index = indices / fps - indices[0] / fps
    if not use_meta_time:
        return by_index, "frame index / fps"
    known = [
        (float(i), m.time)
        for i, m in zip(indices, meta, strict=True)
        if m.time is not None and math.isfinite(m.time)
    ]
    if len(known) < 2:
        return by_index, "frame index / fps (no usable meta time)"
    ki = np.array([k[0] for k in known])
    kt = np.array([k[1] for k in known])
    if np.any(np.diff(kt) <= 0):
        return by_index, "frame index / fps (meta times do not increase frame by frame)"
    times = np.interp(indices.astype(float), ki, kt)
    # Frames outside the known range: extrapolate at the nominal rate.
    before, after = indices < ki[0], indices > ki[-1]
    times[before] = kt[0] - (ki[0] - indices[before]) / fps
    times[after] = kt[-1] + (indices[after] - ki[-1]) / fps
    return times - times[0], "meta time"


class MetaFlight:
    """The recorded flight of one video of ``dataset`` (see the module docstring).

    Args:
        dataset: the annotation file (COCO video) with per-image ``meta``.
        video_id: which video (None: all images of a file without videos).
        home: ``(lat, lon, alt_amsl)`` of the NED origin; default the first frame's position with
            the mission's home altitude (altitudes in the data are above take-off).
        mission: the mission whose telemetry latency, camera and rest are used (default: the
            built-in defaults).
        fps: frame rate for frames without a usable ``time`` and for ``loop``; default the rate the
            file declares, else 30.
        use_meta_time: time frames by their ``meta`` time (False: by ``frame_index / fps``).
        loop: repeat the footage's flight with a period of ``frame count / fps``.
        start_s: sim time at which footage time 0 is shown (None: not started yet).

    Raises :class:`NoUsableMeta` when no frame has a latitude, a longitude or an altitude.
    """

    steerable = False

    def __init__(
        self,
        dataset: VideoDataset,
        video_id: int | None = None,
        home: tuple[float, float, float] | None = None,
        mission: MissionConfig | None = None,
        fps: float | None = None,
        use_meta_time: bool = True,
        loop: bool = False,
        start_s: float | None = 0.0,
    ) -> None:
        base = mission if mission is not None else load_mission(None)
        images = sequence_images(dataset, video_id)
        if not images:
            raise NoUsableMeta(f"video {video_id}: no images in the annotation file")
        self.fps = float(fps or dataset_fps(dataset, video_id) or 30.0)
        if self.fps <= 0:
            raise ValueError(f"fps must be positive, got {fps}")
        meta = [im.telemetry for im in images]
        indices = np.array(
            [im.frame_index if im.frame_index is not None else k for k, im in enumerate(images)]
        )
        self.frame_indices = indices
        self.times, self.time_source = _frame_times(indices, meta, self.fps, use_meta_time)
        t = self.times
        lat = _fill(t, [m.latitude for m in meta])
        lon = _fill(t, [m.longitude for m in meta])
        alt = _fill(t, [m.altitude for m in meta])
        if lat is None or lon is None or alt is None:
            missing = [
                n
                for n, v in (("latitude", lat), ("longitude", lon), ("altitude", alt))
                if v is None
            ]
            raise NoUsableMeta(f"video {video_id}: no frame has {', '.join(missing)} in its meta")
        compass = _fill(t, [m.compass_heading for m in meta], 360.0)
        gimbal_heading = _fill(t, [m.gimbal_heading for m in meta], 360.0)
        try:
            conventions = dataset_conventions(dataset)
        except ConventionError as exc:
            raise NoUsableMeta(f"video {video_id}: {exc}") from exc
        sign = -1.0 if conventions.pitch == DEPRESSION else 1.0
        gimbal_pitch = _fill(
            t, [None if m.gimbal_pitch is None else sign * m.gimbal_pitch for m in meta]
        )
        gimbal_roll = _fill(t, [m.gimbal_roll for m in meta])
        if compass is None:  # no compass: face where the camera looks (else north)
            compass = gimbal_heading if gimbal_heading is not None else np.zeros(len(t))
        if gimbal_heading is None:
            gimbal_heading = compass

        takeoff = "the mission's home_alt_m" if home is None else "given"
        if home is None:
            home = (float(lat[0]), float(lon[0]), base.area.home_alt_m)
        self.home = (float(home[0]), float(home[1]), float(home[2]))
        gimbal = base.camera.gimbal or gimbal_pitch is not None
        self.mission = dataclasses.replace(
            base,
            area=dataclasses.replace(
                base.area, home_lat=self.home[0], home_lon=self.home[1], home_alt_m=self.home[2]
            ),
            camera=dataclasses.replace(base.camera, gimbal=gimbal),
            telemetry=dataclasses.replace(base.telemetry, gnss_noise_m=0.0, attitude_noise_deg=0.0),
        )
        # Full conversion (not just -altitude for down) so that position -> lat/lon round-trips.
        ned = geodetic_to_ned(lat, lon, self.home[2] + alt, *self.home)
        self.position_ned = np.column_stack([np.asarray(v, dtype=float) for v in ned])
        self._yaw = np.radians(compass)
        self._gimbal_yaw = np.radians(gimbal_heading - compass)
        mount = math.radians(base.camera.mount_pitch_deg)
        self._gimbal_pitch = (
            np.radians(gimbal_pitch) if gimbal_pitch is not None else np.full(len(t), mount)
        )
        self._gimbal_roll = np.radians(gimbal_roll) if gimbal_roll is not None else np.zeros(len(t))
        self._gimbal_frame = "vehicle" if gimbal else "body"
        self.frame_count = int(indices[-1] - indices[0]) + 1
        self.loop = loop
        self.period_s = self.frame_count / self.fps
        #: Footage time of the last frame (the flight holds its state afterwards).
        self.survey_duration = float(t[-1])
        self.start_s = start_s
        self.note = (
            f"footage telemetry: {len(images)} frames over {t[-1]:.1f} s "
            f"(timed by {self.time_source}), home {self.home[0]:.6f}, "
            f"{self.home[1]:.6f}; the footage's heights are above a take-off at "
            f"{self.home[2]:g} m above sea level ({takeoff})"
        )

    # -- replay clock ---------------------------------------------------------------------------
    def start_at(self, sim_time: float) -> None:
        """Show footage time 0 at ``sim_time`` (the state before it is the first frame's)."""
        self.start_s = float(sim_time)

    def footage_time(self, t: float) -> float:
        """Footage time (s since the first frame) at sim time ``t``."""
        if self.start_s is None:
            return 0.0
        tau = max(0.0, float(t) - self.start_s)
        if self.loop and self.period_s > 0:
            tau %= self.period_s
        return tau

    # -- the Flight interface -----------------------------------------------------------------
    def reposition(self, t: float, target_ned: np.ndarray, speed_m_s: float | None = None) -> float:
        """Recorded footage cannot fly elsewhere: nothing changes (the vehicle denies the
        command; see :attr:`steerable`). Returns ``t``."""
        log.info("replayed footage: reposition at t=%.1f s ignored", t)
        return float(t)

    def set_roi(self, t: float, target_ned: np.ndarray | None) -> None:
        """Recorded footage cannot point the camera elsewhere: nothing changes."""
        log.info("replayed footage: ROI at t=%.1f s ignored", t)

    def state_at(self, t: float) -> VehicleState:
        """The recorded state at sim time ``t``, interpolated between frames."""
        tau = self.footage_time(t)
        times = self.times
        j = int(np.searchsorted(times, tau, side="right"))
        if j <= 0 or j >= len(times):
            k = 0 if j <= 0 else len(times) - 1
            i, f, vel = k, 0.0, np.zeros(3)
            j = k
        else:
            i = j - 1
            dt = float(times[j] - times[i])
            f = (tau - float(times[i])) / dt
            vel = (self.position_ned[j] - self.position_ned[i]) / dt

        def lerp(a: np.ndarray) -> np.ndarray:
            return a[i] * (1.0 - f) + a[j] * f

        return VehicleState(
            t=float(t),
            position_ned=np.asarray(lerp(self.position_ned), dtype=float),
            velocity_ned=np.asarray(vel, dtype=float),
            acceleration_ned=np.zeros(3),
            roll=0.0,
            pitch=0.0,
            yaw=_wrap(float(lerp(self._yaw))),
            gimbal_roll=float(lerp(self._gimbal_roll)),
            gimbal_pitch=float(lerp(self._gimbal_pitch)),
            gimbal_yaw=_wrap(float(lerp(self._gimbal_yaw))),
            gimbal_frame=self._gimbal_frame,
            wind_ned=np.zeros(3),
        )

    def camera_pose_at(self, t: float) -> CameraPose:
        """Camera pose at sim time ``t``."""
        return self.state_at(t).camera_pose()


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi
