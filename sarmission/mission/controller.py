"""The mission controller: one frame in, confirmed targets out (alerts, autopilot actions).

Per frame (:meth:`MissionController.process`)::

    frame + capture time
      -> detector (MITE-Net)                 detections, proposals, image shift
      -> tracker (camera shift from vSTMD)   tracks; m-of-k lock
      -> for each locked track seen this frame:
           telemetry pose at the capture time -> geolocate the box centre -> target registry
           (box in scene pixels: the image shifts since the first frame taken out)
      -> each sighting of a target: fix, size across the line of sight, head score -> its evidence
      -> for each new target: a *candidate* alert -> store.add (durable) -> console line
         (the operator sees it; nobody else), unless it lies in a zone the operator dismissed
      -> each candidate whose evidence over seconds confirms it (or that the operator
         confirmed): store.promote (durable) -> ALERT console line -> action policy;
         one that clearly is no person: store.discard (the reason kept)
      -> for a target alerted without a position that now has one (seen again, or its
         earlier sightings placed from buffered telemetry once the autopilot's state is known):
           store.attach_position (durable) -> console line -> action policy (now with a place)
      -> for a placed alert whose target (a fit of its recent fixes) has moved or whose error
         changed
         (at its confirmation, then at most every few seconds; :mod:`~sarmission.mission.
         refinement`): store.refine_position (durable) -> console line -> the action policy's
         queued visit moves
      -> recorder (frame, proposals, detections, tracks, telemetry, map)

A fix is computed only from the autopilot's own state (the telemetry buffer's pose, which needs
its HOME_POSITION, a GPS fix and fresh, plausible samples) with the drone as the origin, and
only while the drone is at least ``[geolocation] min_height_m`` above the ground; otherwise the
alert says "position unknown" and why. The mission file's home is never a geolocation origin.

Only locked tracks cost more than tracking; the alert (thumbnail, geolocated history) is built
once per new target. The same controller runs live (frames stamped with ``time.monotonic()``,
the clock the MAVLink telemetry is mapped to) and in replay (any clock the telemetry buffer was
filled in). A frame that is not a BGR ``uint8 [H, W, 3]`` image or a
:class:`~sarmission.yuv.YuvImage` of the stream's size is skipped, counted by reason and logged
(the YUV planes go to the detector as they are; the thumbnail and the recording convert what
they show); a new size that lasts a few frames in a row is the stream's from then on.
"""

from __future__ import annotations

import bisect
import dataclasses
import logging
import math
import re
import time
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from sarmission.alerts.model import Alert
from sarmission.alerts.store import AlertStore
from sarmission.alerts.thumbnail import crop_thumbnail
from sarmission.class_roles import class_name, role_of_id
from sarmission.geo.camera import CameraIntrinsics
from sarmission.geo.geolocate import FixLimits, GeoFix, PlatformPose, geolocate
from sarmission.geo.ground_size import apparent_size_m
from sarmission.geo.wgs84 import ned_to_geodetic
from sarmission.mavlink.telemetry import StaleTelemetry, TelemetryBuffer
from sarmission.mission import continuity
from sarmission.mission.actions import ActionPolicy
from sarmission.mission.candidates import CandidateBook, Promotion
from sarmission.mission.confidence import ConfidenceModel, confidence_of_head
from sarmission.mission.config import MissionConfig
from sarmission.mission.position_estimate import WINDOW_S, latest_position
from sarmission.mission.range_crops import PersonPixels, pose_person_px
from sarmission.mission.refinement import PositionRefiner, Refinement
from sarmission.mission.targets import KnownTarget, Target, TargetRegistry
from sarmission.perception import extent as object_extents
from sarmission.perception.extent import object_extent
from sarmission.perception.look import LookMemory, grey_patch
from sarmission.perception.types import FrameResult
from sarmission.ratelimit import RateLimitedLog
from sarmission.tracking.tracker import Tracker, TrackState
from sarmission.viz.recorder import LOCKED_COLOUR, TRACK_COLOUR, Recorder
from sarmission.yuv import YuvImage

log = logging.getLogger(__name__)

#: Frames whose capture times are kept to find the frame a refined position is of (the
#: refinement window's span at 100 frames/s).
FRAME_TIMES_KEPT = int(WINDOW_S * 100)

#: Geolocated history entries put in an alert (the newest ones).
ALERT_TRACK_POINTS = 10
#: Seconds between two aircraft positions stored for the operator's map.
DRONE_TRACK_PERIOD_S = 1.0
DRONE_COLOUR = (60, 140, 255)
#: Frames in a row of a new size after which the stream is taken to have changed size (a
#: sender restarted at another resolution); a lone frame of another size is skipped.
SIZE_CHANGE_FRAMES = 3


class Detector(Protocol):
    """What the controller needs of a detector (:class:`~sarmission.perception.mitenet.MiteNet`);
    its :class:`FrameResult` carries the frame's camera shift."""

    per_stage_ms: dict[str, float]

    @property
    def classes(self) -> tuple[str, ...]: ...

    def process(
        self,
        frame_bgr: np.ndarray | YuvImage,
        timestamp: float,
        shift_px: tuple[float, float] | None = None,
        person_px: PersonPixels | None = None,
    ) -> FrameResult: ...

    def reset(self) -> None: ...


@dataclass
class ControllerStats:
    """Counters of one run."""

    frames: int = 0
    skipped: Counter[str] = field(default_factory=Counter)
    detections: int = 0
    locks: int = 0
    candidates: list[Alert] = field(default_factory=list)  # every lock of a new target
    alerts: list[Alert] = field(default_factory=list)  # confirmed: the team was told
    # each confirmed alert as it was confirmed (a copy: later refinements change the alert,
    # not it), with the frame and capture time it was confirmed at
    confirmed: list[tuple[Alert, int, float]] = field(default_factory=list)
    suppressed: int = 0  # new targets inside a zone the operator dismissed
    objects: int = 0  # locked targets the head calls an object (boat, buoy): never alerted
    located_later: int = 0
    refined: int = 0  # placed alerts moved to their target's better position
    # alert id -> the frame its stored position is of (its lock or placement; a refinement's
    # latest fix), now and as the alert was confirmed
    position_frames: dict[str, int] = field(default_factory=dict)
    confirmed_position_frames: dict[str, int] = field(default_factory=dict)
    unplaced: Counter[str] = field(default_factory=Counter)  # alerts without a position, by why
    merged_tracks: int = 0
    paused: int = 0  # frames not searched: the camera was pointed at a target
    stage_ms: Counter[str] = field(default_factory=Counter)
    busy_s: float = 0.0

    @property
    def skipped_total(self) -> int:
        return sum(self.skipped.values())


def monotonic_to_posix() -> Callable[[float], float]:
    """Map ``time.monotonic()`` stamps to POSIX seconds (offset taken now)."""
    offset = time.time() - time.monotonic()
    return lambda t: t + offset


class MissionController:
    """Runs one mission's frames through detection, tracking, geolocation, alerting and actions.

    Args:
        mission: the mission configuration (camera intrinsics, lock m/k, ground plane).
        detector: MITE-Net or anything with its ``process`` interface.
        telemetry: the buffer the frame times are looked up in.
        store: the durable alert store; its known targets for ``mission_id`` seed the registry.
        actions: the action policy (None: no autopilot, e.g. replay).
        recorder: rerun recorder (None: nothing recorded).
        mission_id: the id alerts are stored under (default: the mission's name).
        to_posix: maps a frame timestamp to POSIX seconds for the alert's lock time.
        merge_radius_m: target registry merge radius.
        console: receives one line per new alert.
        confidence: turns a confirmed target's evidence into the probability that a person is
            there (:mod:`sarmission.mission.confidence`); default: the model kept beside the
            detector's head file, if any (none: alerts carry the head's score only).
        ground_model: places pixels instead of the flat plane at home altitude (anything with
            :meth:`~sarmission.geo.terrain.TerrainGround.locate`, e.g. a DEM).
    """

    def __init__(
        self,
        mission: MissionConfig,
        detector: Detector,
        telemetry: TelemetryBuffer,
        store: AlertStore,
        actions: ActionPolicy | None = None,
        recorder: Recorder | None = None,
        mission_id: str | None = None,
        to_posix: Callable[[float], float] | None = None,
        merge_radius_m: float = 8.0,
        console: Callable[[str], None] = print,
        ground_model: Any = None,
        confidence: ConfidenceModel | None = None,
    ) -> None:
        self.mission = mission
        self.ground_model = ground_model
        self.detector = detector
        self.telemetry = telemetry
        self.store = store
        self.actions = actions
        self.recorder = recorder if recorder is not None and recorder.enabled else None
        self.mission_id = mission_id or mission.name
        self.to_posix = to_posix or monotonic_to_posix()
        self.tracker = Tracker(
            lock_m=mission.lock.m, lock_k=mission.lock.k, lock_min_score=mission.lock.min_score
        )
        self.registry = TargetRegistry(merge_radius_m)
        self.registry.seed(
            {
                target_id: KnownTarget(
                    None if fix is None else (fix[0], fix[1]), None if fix is None else fix[2]
                )
                for target_id, fix in store.known_fixes(self.mission_id).items()
            }
        )
        self.known_at_start = len(self.registry)
        if confidence is None:
            found = confidence_of_head(getattr(detector, "head", None))
            (log.warning if found.refused else log.info)("%s", found.note)
            confidence = found.model
        self.candidates = CandidateBook(store, self.mission_id, mission.confirm, confidence)
        if mission.confirm.max_extent_m > 0:
            object_extents.prepare()  # not a stall at the first candidate's measurement
        self._looks = LookMemory()  # cheap (a 16 px patch a sighting): always measured
        self.console = console
        self.stats = ControllerStats()
        self.ground_alt = mission.area.ground_alt_m
        self.min_height_m = mission.geolocation.min_height_m
        self.fix_limits = FixLimits(
            max_off_nadir_deg=mission.geolocation.max_off_nadir_deg,
            max_error_m=mission.geolocation.max_error_m,
        )
        self._camera = mission.camera.intrinsics()
        self._intrinsics: CameraIntrinsics | None = None
        self._shape: tuple[int, int] | None = None
        self._new_shape: tuple[tuple[int, int], int] | None = None  # another size, frames seen
        self._skip_log = RateLimitedLog(log)
        self._t0: float | None = None
        self._scene_offset = np.zeros(2)
        self._unplaced: dict[int, Alert] = {}  # target id -> its alert stored without position
        # target id -> its alert stored with a position (candidate, then confirmed), refined
        # as the target's fixes come in; an earlier run's go on being followed (the latest
        # per target)
        self._placed: dict[int, Alert] = {
            a.target_id: a for a in store.followed_alerts(self.mission_id)
        }
        self.refiner = PositionRefiner()
        self._objects: set[int] = set()  # targets locked but called an object (not alerted)
        self._pending_locks: set[int] = set()  # tracks locked while the registry was unsure
        # target id -> (capture time, box centre) of its sightings, to place it from buffered
        # telemetry once the autopilot's state allows a fix
        self._unplaced_sightings: dict[int, list[tuple[float, float, float]]] = {}
        self._paused = False  # the last frame was not searched (camera on a target)
        # (capture time, frame index) of the latest frames run: the frame a refined position,
        # as of its latest fix, is of
        self._frame_times: deque[tuple[float, int]] = deque(maxlen=FRAME_TIMES_KEPT)
        self._drone_recorded = -math.inf
        self._store_area(mission)

    def _store_area(self, mission: MissionConfig) -> None:
        """The mission's search area (planned around the mission file's home) for the map."""
        lat0, lon0, h0 = mission.area.home
        ne = mission.area.polygon_ne()
        lat, lon, _ = ned_to_geodetic([p[0] for p in ne], [p[1] for p in ne], 0.0, lat0, lon0, h0)
        self.store.set_mission_area(
            self.mission_id, [(float(a), float(b)) for a, b in zip(lat, lon, strict=True)]
        )

    # -- per frame -------------------------------------------------------------------------------
    def process(self, frame_index: int, timestamp: float, frame: Any) -> list[Alert]:
        """Run one frame captured at ``timestamp`` (telemetry clock); returns its new alerts."""
        reason = self._check(frame)
        if reason:
            self._skip(frame_index, reason)
            return []
        if self._search_paused():
            return []
        started = time.perf_counter()
        self._frame_times.append((timestamp, frame_index))
        result, tracks, scene = self._detect_and_track(frame, frame_index, timestamp)
        pose, changed = self._observe_locked(tracks, frame, frame_index, timestamp, scene)
        self._place_from_buffer(frame_index)
        self._record_drone(timestamp, pose)
        promotions = (
            self.candidates.review(
                timestamp,
                self.to_posix(timestamp),
                prepare=lambda alert: self._refine(alert, frame_index, timestamp, force=True),
            )
            + self.candidates.operator_decisions()
        )
        alerts = [self._confirm(promotion, frame_index, timestamp) for promotion in promotions]
        self._refine_changed(changed, frame_index, timestamp)
        self.stats.busy_s += time.perf_counter() - started
        if self.recorder is not None:
            if pose is None:
                pose = self.telemetry.lookup(timestamp)
            self._record(frame_index, timestamp, frame, result, tracks, pose, changed)
        return alerts

    def _search_paused(self) -> bool:
        """Whether the search is paused while the camera holds an ROI; when it resumes, motion
        and tracks start afresh."""
        if self.actions is not None:
            self.actions.tick()  # camera back to the survey view once an ROI has been held
            if self.actions.search_paused():
                self.stats.paused += 1
                self._paused = True
                return True
        if self._paused:  # the camera is back: motion and tracks start afresh
            self.detector.reset()
            self.tracker.drop_tracks()
            self._paused = False
        return False

    def _detect_and_track(
        self, frame: Any, frame_index: int, timestamp: float
    ) -> tuple[FrameResult, list[TrackState], np.ndarray]:
        """Detections of the frame, the tracks they update, and the scene offset (the camera's
        accumulated shift, as a box offset)."""
        result = self.detector.process(frame, timestamp, person_px=self._person_px(timestamp))
        shift = result.camera_shift
        tracks = self.tracker.update(result.detections, frame_index, timestamp, camera_shift=shift)
        if shift is not None:
            self._scene_offset += shift
        self._looks.forget_before(timestamp)
        self.stats.frames += 1
        self.stats.detections += len(result.detections)
        self.stats.stage_ms.update(self.detector.per_stage_ms)
        return result, tracks, np.tile(self._scene_offset, 2)

    def _person_px(self, timestamp: float) -> PersonPixels | None:
        """The pixels a person spans at image points, from the adopted autopilot's current
        pose, for crops sized to the person (``[detector] person_m``); None when that is off or
        the pose, home or lens is not known (crops as at the survey's ranges)."""
        person_m = self.mission.detector.person_m
        if not person_m or self._intrinsics is None:
            return None
        pose = self.telemetry.lookup(timestamp)
        return pose_person_px(self._intrinsics, pose, person_m, self._ground_below_home())

    def _observe_locked(
        self,
        tracks: list[TrackState],
        frame: Any,
        frame_index: int,
        timestamp: float,
        scene: np.ndarray,
    ) -> tuple[PlatformPose | StaleTelemetry | None, list[Target]]:
        """Locate every locked track seen in this frame and update its target; returns the pose
        (looked up only when a track needs it) and the targets changed."""
        pose: PlatformPose | StaleTelemetry | None = None
        changed: list[Target] = []
        seen = [t for t in tracks if t.locked and not t.misses]
        # tracks with a target first: a new track is compared with their boxes of this frame
        seen.sort(key=lambda t: self.registry.target_of(t.track_id) is None)
        for track in seen:
            if pose is None:
                pose = self.telemetry.lookup(timestamp)
            target = self._observe_track(track, frame, frame_index, timestamp, pose, scene)
            if target is not None:
                changed.append(target)
        alive = {t.track_id for t in tracks}
        self._pending_locks.intersection_update(alive)
        if self.registry.detached:  # tracks taken out of a target that died unseen since
            for gone in set(self.registry.detached) - alive:
                del self.registry.detached[gone]
        return pose, changed

    def _observe_track(
        self,
        track: TrackState,
        frame: Any,
        frame_index: int,
        timestamp: float,
        pose: PlatformPose | StaleTelemetry,
        scene: np.ndarray,
    ) -> Target | None:
        fix, note = self._locate(track, pose)
        former = self.registry.detached.pop(track.track_id, None)
        if former is not None:  # taken back out of a target: its evidence goes, a new lock
            self.candidates.forget(former, track.track_id)
            self._pending_locks.add(track.track_id)
        target, is_new = self.registry.observe(
            track.track_id, track.class_id, track.score, timestamp, fix, note, box=track.box - scene
        )
        if target is None:  # unsure yet whose: the registry decides on a later frame
            if track.just_locked:
                self._pending_locks.add(track.track_id)
            return None
        self._sighting(target, track, frame, timestamp, pose, fix)
        self._check_continuity(target, track.track_id)
        if track.just_locked or track.track_id in self._pending_locks:
            self._pending_locks.discard(track.track_id)
            self.stats.locks += 1
            if is_new:
                self._candidate(target, track, frame, frame_index, pose, fix)
            else:
                self.stats.merged_tracks += 1
                log.info("track %d joined target %d", track.track_id, target.target_id)
        elif target.target_id in self._objects:  # called an object so far: is it still?
            self._candidate(target, track, frame, frame_index, pose, fix)
        if target.position is None and target.target_id in self._unplaced:
            self._remember_sighting(target.target_id, track)
        if target.position is not None and target.target_id in self._unplaced:
            self._attach_position(target, track.track_id, frame_index)
        return target

    def skip(self, frame_index: int, reason: str) -> None:
        """Count a frame the source could not deliver (e.g. a read failure)."""
        self._skip(frame_index, reason)

    def _check(self, frame: Any) -> str:
        if frame is None:
            return "no image"
        if isinstance(frame, YuvImage):
            shape = (frame.height, frame.width)
        elif not isinstance(frame, np.ndarray):
            return f"not an image ({type(frame).__name__})"
        elif frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3:
            return f"not a BGR uint8 image (dtype {frame.dtype}, shape {list(frame.shape)})"
        else:
            shape = (int(frame.shape[0]), int(frame.shape[1]))
        if self._shape is None:
            if min(shape) < 16:
                return f"image too small ({shape[1]}x{shape[0]})"
            self._shape = shape
            self._intrinsics = self._camera.for_frames(shape[1], shape[0])
            if not self._camera.same_shape(shape[1], shape[0]):
                self._warn_frame_shape(shape)
        elif shape != self._shape:
            if min(shape) < 16:
                return f"image too small ({shape[1]}x{shape[0]})"
            seen = self._new_shape[1] + 1 if self._new_shape and self._new_shape[0] == shape else 1
            self._new_shape = (shape, seen)
            if seen < SIZE_CHANGE_FRAMES:
                return (
                    f"size {shape[1]}x{shape[0]} differs from the stream's "
                    f"{self._shape[1]}x{self._shape[0]}"
                )
            self._adopt_shape(shape)
        else:
            self._new_shape = None
        return ""

    def _adopt_shape(self, shape: tuple[int, int]) -> None:
        """Go on with frames of another size (a sender restarted at another resolution, joined
        recordings): the lens re-derived for it, motion and tracks started afresh (their
        boxes are of the old size), with one warning."""
        old = self._shape
        assert old is not None
        self._shape, self._new_shape = shape, None
        self._intrinsics = self._camera.for_frames(shape[1], shape[0])
        self.detector.reset()
        self.tracker.drop_tracks()
        line = (
            f"frame size changed from {old[1]}x{old[0]} to {shape[1]}x{shape[0]}: "
            "detection and tracks start afresh"
        )
        log.warning(line)
        if self.recorder is not None:
            self.recorder.text("camera", line, level="WARN")
        if not self._camera.same_shape(shape[1], shape[0]):
            self._warn_frame_shape(shape)

    def _warn_frame_shape(self, shape: tuple[int, int]) -> None:
        camera = self._camera
        line = (
            f"frames are {shape[1]}x{shape[0]}, not the shape of the camera's "
            f"{camera.width}x{camera.height}: positions assume its horizontal field of view "
            "with the height cropped or extended; set [camera] to this footage's lens"
        )
        log.warning(line)
        if self.recorder is not None:
            self.recorder.text("camera", line, level="WARN")

    def _skip(self, frame_index: int, reason: str) -> None:
        key = reason.split(" (")[0]
        self.stats.skipped[key] += 1
        self._skip_log.event(  # every one counted; a warning at most every few seconds
            key,
            "frame %d skipped: %s (%d skipped so far)",
            frame_index,
            reason,
            self.stats.skipped_total,
        )
        if self.recorder is not None:
            self.recorder.text("skipped", f"frame {frame_index}: {reason}", level="WARN")

    # -- geolocation -----------------------------------------------------------------------------
    def _ground_below_home(self) -> float | None:
        """Metres from the autopilot's home down to the ground plane (None: home unknown)."""
        home = self.telemetry.home
        if home is None:
            return None
        return 0.0 if self.ground_alt is None else home[2] - self.ground_alt

    def _fix(self, centre: tuple[float, float], pose: PlatformPose) -> GeoFix:
        ground = self._ground_below_home()
        if ground is None:
            return GeoFix(
                None, None, None, None, math.nan, "no home position from the autopilot yet"
            )
        assert self._intrinsics is not None
        if self.ground_model is not None:
            home = self.telemetry.home
            assert home is not None
            return self.ground_model.locate(
                centre, self._intrinsics, pose, home, self.min_height_m, limits=self.fix_limits
            )
        return geolocate(
            centre,
            self._intrinsics,
            pose,
            ground,
            min_height_m=self.min_height_m,
            limits=self.fix_limits,
        )

    def _locate(
        self,
        track: TrackState,
        pose: PlatformPose | StaleTelemetry,
    ) -> tuple[GeoFix | None, str]:
        if isinstance(pose, StaleTelemetry):
            return None, pose.reason
        box = track.box
        fix = self._fix(((box[0] + box[2]) / 2.0, (box[1] + box[3]) / 2.0), pose)
        return fix, "" if fix.ok else f"no ground fix: {fix.note}"

    def _history_fixes(self, track: TrackState) -> list[tuple[float, float, float]]:
        """``(POSIX t, lat, lon)`` of the track's newest centres, where telemetry allows."""
        points = []
        for _, t, cx, cy in track.history[-ALERT_TRACK_POINTS:]:
            pose = self.telemetry.lookup(t)
            if isinstance(pose, StaleTelemetry):
                continue
            fix = self._fix((cx, cy), pose)
            if fix.ok:
                points.append((self.to_posix(t), fix.lat, fix.lon))
        return points

    def _remember_sighting(self, target_id: int, track: TrackState) -> None:
        _, t, cx, cy = track.history[-1]
        sightings = self._unplaced_sightings.setdefault(target_id, [])
        if not sightings or sightings[-1][0] != t:
            sightings.append((t, cx, cy))
            del sightings[:-ALERT_TRACK_POINTS]

    def _place_from_buffer(self, frame_index: int) -> None:
        """Targets alerted without a position whose sightings buffered telemetry can now place
        (e.g. HOME_POSITION arrived after the lock): their position goes out now."""
        for target_id in list(self._unplaced):
            target = self.registry.targets.get(target_id)
            sightings = self._unplaced_sightings.get(target_id, [])
            if target is None or target.position is not None or not sightings:
                continue
            for t, cx, cy in sightings:
                pose = self.telemetry.lookup(t)
                if isinstance(pose, PlatformPose):
                    fix = self._fix((cx, cy), pose)
                    if fix.ok:
                        target.add_fix(fix)
            if target.position is not None:
                self._unplaced_sightings.pop(target_id, None)
                self._attach_position(target, None, frame_index)

    def _record_drone(self, timestamp: float, pose: PlatformPose | StaleTelemetry | None) -> None:
        """The aircraft's position into the store about once a second (the operator's map)."""
        if timestamp - self._drone_recorded < DRONE_TRACK_PERIOD_S:
            return
        if pose is None:
            pose = self.telemetry.lookup(timestamp)
        if isinstance(pose, PlatformPose):
            self.store.record_drone(
                self.mission_id, self.to_posix(timestamp), pose.lat, pose.lon, pose.rel_alt_m
            )
            self._drone_recorded = timestamp

    # -- candidates and alerts ---------------------------------------------------------------
    def _sighting(
        self,
        target: Target,
        track: TrackState,
        frame: np.ndarray | YuvImage,
        timestamp: float,
        pose: PlatformPose | StaleTelemetry,
        fix: GeoFix | None,
    ) -> None:
        """This frame's evidence of ``target``: the track's fix, the size of its box and of
        the object under it, how much its look changed over a second (while undecided),
        the head's score of the detection it took and the track's class."""
        if fix is None or not fix.ok or not isinstance(pose, PlatformPose):
            self.candidates.sighting(
                target.target_id, timestamp, None, None, None, None, track.last_score
            )
            return
        ground = self._ground_below_home()
        assert self._intrinsics is not None and ground is not None
        size = apparent_size_m(track.raw_box, self._intrinsics, pose, ground)
        extent = None
        if self.mission.confirm.max_extent_m > 0 and self.candidates.wants_extent(target.target_id):
            started = time.perf_counter()
            box = object_extent(frame, track.raw_box)
            self.stats.stage_ms["extent"] += (time.perf_counter() - started) * 1e3
            if box is not None:
                extent = apparent_size_m(box, self._intrinsics, pose, ground)
        look = None
        if target.target_id not in self.candidates.decided:
            started = time.perf_counter()
            patch = grey_patch(frame, track.raw_box) if track.misses == 0 else None
            look = self._looks.change(target.target_id, timestamp, patch)
            self.stats.stage_ms["look"] += (time.perf_counter() - started) * 1e3
        label = class_name(self.detector.classes, track.class_id)
        self.candidates.sighting(
            target.target_id,
            timestamp,
            fix.lat,
            fix.lon,
            fix.error_m,
            size,
            track.last_score,
            label,
            track.track_id,
            extent,
            look,
        )

    def _check_continuity(self, target: Target, track_id: int) -> None:
        """Compare a track that joined ``target`` after it was out of sight with the target's
        earlier fixes, once it has a confirmation's evidence (:mod:`continuity`)."""
        evidence = self.candidates.evidence.get(target.target_id)
        if evidence is None:
            return
        rule = self.mission.confirm
        jump = continuity.check(
            target, track_id, evidence.sightings, rule.min_sightings, rule.min_seen_s
        )
        if jump:
            log.info(
                "track %d's fixes lie %.1f m from target %d's before it joined: the same "
                "person moved, or another is there; its positions carry that in their error",
                track_id,
                jump,
                target.target_id,
            )

    def _candidate(
        self,
        target: Target,
        track: TrackState,
        frame: np.ndarray,
        frame_index: int,
        pose: PlatformPose | StaleTelemetry,
        fix: GeoFix | None,
    ) -> None:
        """A new target's lock: a candidate alert for the operator (not the autopilot). A target
        the head calls an object (its majority class: boat, buoy) waits in ``_objects`` and
        becomes a candidate only once its majority class is a person or an appliance."""
        if role_of_id(self.detector.classes, target.class_id) == "object":
            if target.target_id not in self._objects:
                self._objects.add(target.target_id)
                self.stats.objects += 1
                log.info(
                    "target %d is a %s: not alerted",
                    target.target_id,
                    self.detector.classes[target.class_id],
                )
            return
        self._objects.discard(target.target_id)
        target.announced = True
        zone = self.candidates.suppressing(target.position)
        if zone is not None:
            self.stats.suppressed += 1
            log.info(
                "target %d lies in a dismissed zone (%.6f, %.6f, %.0f m): not alerted",
                target.target_id,
                *zone,
            )
            return
        alert = self._new_alert(target, track, frame, frame_index, pose, fix)
        self.store.add(alert)  # durable before anyone is told
        self.candidates.add(target.target_id, alert)
        self.stats.candidates.append(alert)
        if alert.position is not None:
            self._placed[target.target_id] = alert
            self.refiner.done(alert.alert_id, track.history[-1][1])
            self.stats.position_frames[alert.alert_id] = frame_index
        else:
            self._unplaced[target.target_id] = alert
            self._remember_sighting(target.target_id, track)
            self.stats.unplaced[re.sub(r"\d+(\.\d+)?", "N", alert.position_note)] += 1
        line = format_alert(alert, track.track_id)
        self.console(line)
        if self.recorder is not None:
            self.recorder.text("alerts", line, level="INFO")

    def _confirm(self, promotion: Promotion, frame_index: int, timestamp: float) -> Alert:
        """A candidate confirmed (stored already, placed at its target's position just before:
        the mean of the fixes that confirmed it, not the lock's one fix; an operator's
        confirmation is placed here), then told to the console, the autopilot, the team."""
        alert = promotion.alert
        if alert.target_id in self._unplaced:  # its position, once found, goes to this one
            self._unplaced[alert.target_id] = alert
        elif alert.position is not None:
            self._placed[alert.target_id] = alert
            if promotion.assessment is None:  # the evidence's were placed in review's prepare
                self._refine(alert, frame_index, timestamp, force=True)
        self.stats.alerts.append(alert)
        self.stats.confirmed.append((dataclasses.replace(alert), frame_index, timestamp))
        self.stats.confirmed_position_frames[alert.alert_id] = self.stats.position_frames.get(
            alert.alert_id, alert.frame_index
        )
        line = format_alert(alert)
        self.console(line)
        if self.recorder is not None:
            self.recorder.text("alerts", line, level="WARN")
        if self.actions is not None:
            self.actions.announce(alert)
        return alert

    def _new_alert(
        self,
        target: Target,
        track: TrackState,
        frame: np.ndarray,
        frame_index: int,
        pose: PlatformPose | StaleTelemetry,
        fix: GeoFix | None,
    ) -> Alert:
        box = track.box
        centre = ((box[0] + box[2]) / 2.0, (box[1] + box[3]) / 2.0)
        class_id = target.class_id if target.class_id >= 0 else track.class_id
        name = class_name(self.detector.classes, class_id, "target")
        placed = fix is not None and fix.ok
        return Alert(
            mission_id=self.mission_id,
            target_id=target.target_id,
            class_name=name,
            score=float(track.score),
            lock_time=self.to_posix(track.history[-1][1]),
            frame_index=frame_index,
            position=target.position if placed else None,
            position_note=target.note if placed else (target.note or "no position"),
            position_time=self.to_posix(track.history[-1][1]) if placed else None,
            error_m=target.error_m if placed else None,
            target_hae_m=self._target_hae(),
            drone_position=(
                None if isinstance(pose, StaleTelemetry) else (pose.lat, pose.lon, pose.rel_alt_m)
            ),
            track=self._history_fixes(track),
            pixel_track=[(int(i), float(x), float(y)) for i, _, x, y in track.history],
            thumbnail=crop_thumbnail(frame, centre),
            tier="candidate",
        )

    def _target_hae(self) -> float | None:
        """The ground plane's altitude (AMSL), None while the autopilot's home is unknown."""
        if self.ground_alt is not None:
            return self.ground_alt
        home = self.telemetry.home
        return None if home is None or not math.isfinite(home[2]) else home[2]

    def _attach_position(self, target: Target, track_id: int | None, frame_index: int) -> None:
        """The first position of a target alerted without one: into its stored alert, then told."""
        alert = self._unplaced.pop(target.target_id)
        self._unplaced_sightings.pop(target.target_id, None)
        assert target.position is not None
        fixed = None if target.last_fix is None else self.to_posix(target.last_fix[3])
        if not self.store.attach_position(
            alert.alert_id, target.position, target.error_m, target.note, fixed
        ):  # durable before anyone is told
            return
        alert.position, alert.error_m, alert.position_note, alert.position_time = (
            target.position,
            target.error_m,
            target.note,
            fixed,
        )
        self.stats.located_later += 1
        self._placed[target.target_id] = alert
        self.refiner.done(alert.alert_id, target.last_seen)
        self.stats.position_frames[alert.alert_id] = frame_index
        line = format_located(alert, frame_index, track_id)
        self.console(line)
        if self.recorder is not None:
            self.recorder.text("alerts", line, level="WARN")
        if self.actions is not None and alert.tier == "confirmed":  # told before: tell again
            self.actions.announce(alert)

    def _refine_changed(self, changed: list[Target], frame_index: int, timestamp: float) -> None:
        """Refine the placed alerts of the targets seen this frame, where due."""
        for target in changed:
            alert = self._placed.get(target.target_id)
            if alert is not None:
                self._refine(alert, frame_index, timestamp)

    def _refine(
        self, alert: Alert, frame_index: int, timestamp: float, force: bool = False
    ) -> None:
        """Move ``alert`` to where its target is as of its latest fix (a fit of its recent
        fixes, :func:`~sarmission.mission.position_estimate.latest_position`, from the tracks
        that joined it within the registry's statistical gate, when they are as many and as
        long as a confirmation needs) when :class:`PositionRefiner` says so: durably first,
        then the console, the recording and (confirmed) the queued visit. An alert the store
        no longer refines (dismissed, discarded) is forgotten."""
        target = self.registry.targets.get(alert.target_id)
        evidence = self.candidates.evidence.get(alert.target_id)
        if target is None or evidence is None:
            return
        if not evidence.sightings:
            return
        if not force and not self.refiner.worth_a_look(alert.alert_id, timestamp):
            return  # before the fit: it costs a window of fixes
        # only the tracks that continue the target (:mod:`continuity`): one that joined only
        # by the re-find radius, or after a gap with too little evidence of its own, may be
        # something else near where the person was; one taken back out of the target (its
        # sightings leave the evidence at its next sighting) is something else
        since = evidence.sightings[-1].t - WINDOW_S
        start = bisect.bisect_left(evidence.sightings, since, key=_time)
        sure = continuity.placing(target, evidence.sightings[start:])
        rule = self.mission.confirm
        estimate = latest_position(sure, min_fixes=rule.min_sightings, min_span_s=rule.min_seen_s)
        if estimate is None:
            return
        apart = continuity.ambiguity_m(target)
        error = math.hypot(estimate.error_m, apart)
        due = self.refiner.due(
            alert, estimate.position, error, timestamp, force, estimate.velocity_ne, apart
        )
        if due is None:
            return
        fixed = self.to_posix(estimate.t)
        if not self.store.refine_position(
            alert.alert_id,
            due.position,
            due.error_m,
            target.note,
            due.detail(),
            fixed,
            due.drift_ne,
        ):
            self._placed.pop(alert.target_id, None)
            self.refiner.forget(alert.alert_id)
            return
        alert.position, alert.error_m, alert.position_note = due.position, due.error_m, target.note
        alert.position_time, alert.drift_ne = fixed, due.drift_ne
        self.refiner.done(alert.alert_id, timestamp)
        self.stats.refined += 1
        self.stats.position_frames[alert.alert_id] = self._frame_at(estimate.t, frame_index)
        if force:  # the confirmation's own line follows with the position
            return
        line = format_refined(alert, due, frame_index)
        self.console(line)
        if self.recorder is not None:
            self.recorder.text("alerts", line, level="INFO")
        if self.actions is not None and alert.tier == "confirmed":
            self.actions.refine(alert)

    def _frame_at(self, t: float, default: int) -> int:
        """The index of the latest frame run captured at or before ``t`` (``default``: none
        kept)."""
        for captured, index in reversed(self._frame_times):
            if captured <= t:
                return index
        return default

    # -- recording -------------------------------------------------------------------------------
    def _record(
        self,
        frame_index: int,
        timestamp: float,
        frame: np.ndarray,
        result: FrameResult,
        tracks: list[TrackState],
        pose: PlatformPose | StaleTelemetry,
        changed: list[Target],
    ) -> None:
        rec = self.recorder
        assert rec is not None
        if self._t0 is None:
            self._t0 = timestamp
        rec.set_time(frame_index, timestamp - self._t0)
        rec.frame(frame_index, frame)
        rec.boxes("proposals", result.proposals.boxes)
        classes = self.detector.classes
        det = result.detections
        rec.boxes(
            "detections",
            det.boxes,
            labels=[
                f"{classes[c] if 0 <= c < len(classes) else c} {s:.2f}"
                for c, s in zip(det.class_ids.tolist(), det.scores.tolist(), strict=True)
            ],
        )
        rec.boxes(
            "tracks",
            np.array([t.box for t in tracks]).reshape(-1, 4),
            labels=[f"{t.track_id}{' LOCK' if t.locked else ''}" for t in tracks],
            colours=[LOCKED_COLOUR if t.locked else TRACK_COLOUR for t in tracks],
        )
        for stage, ms in self.detector.per_stage_ms.items():
            rec.scalar(f"stage_ms/{stage}", ms)
        if isinstance(pose, PlatformPose):
            rec.scalar("altitude_m", pose.rel_alt_m)
            rec.scalar("attitude/roll_deg", math.degrees(pose.roll))
            rec.scalar("attitude/pitch_deg", math.degrees(pose.pitch))
            rec.scalar("attitude/yaw_deg", math.degrees(pose.yaw))
            rec.geo_points(
                "drone", np.array([[pose.lat, pose.lon]]), radius_m=3.0, colour=DRONE_COLOUR
            )
        if changed:
            placed = [t.position for t in self.registry.targets.values() if t.position]
            if placed:
                rec.geo_points("targets", np.array(placed))

    # -- summary ---------------------------------------------------------------------------------
    def summary(self, wall_s: float | None = None) -> str:
        """A few lines: frames, skipped, rate, locks, alerts, stage times, targets."""
        s = self.stats
        lines = [
            f"frames processed: {s.frames}"
            + (
                f", skipped: {s.skipped_total} ("
                + ", ".join(f"{k}: {n}" for k, n in s.skipped.items())
                + ")"
                if s.skipped_total
                else ", skipped: 0"
            )
        ]
        if s.frames:
            rate = f"{s.frames / s.busy_s:.1f} fps processing" if s.busy_s > 0 else ""
            if wall_s:
                rate += f", {s.frames / wall_s:.1f} fps overall"
            lines.append(rate)
            lines.append(
                "mean stage ms: "
                + ", ".join(f"{k} {v / s.frames:.1f}" for k, v in s.stage_ms.items())
            )
        lines.append(
            f"detections: {s.detections}, locks: {s.locks}, "
            f"tracks merged into known targets: {s.merged_tracks}"
        )
        lines.append(
            f"targets: {len(self.registry)} ({self.known_at_start} known at start), "
            f"candidates: {len(s.candidates)}, confirmed alerts: {len(s.alerts)}"
            + (f", positions found after the alert: {s.located_later}" if s.located_later else "")
            + (f", positions refined: {s.refined}" if s.refined else "")
        )
        book = self.candidates
        if book.discarded or s.suppressed or book.candidates:
            lines.append(
                "candidates discarded: "
                + (", ".join(f"{n} ({why})" for why, n in book.discarded.most_common()) or "0")
                + f"; still unconfirmed: {len(book.candidates)}"
                + (f"; in dismissed zones: {s.suppressed}" if s.suppressed else "")
            )
        if s.objects:
            lines.append(f"locked targets the head calls an object (never alerted): {s.objects}")
        if s.unplaced:
            lines.append(
                "alerted without a position: "
                + ", ".join(f"{n} ({why})" for why, n in s.unplaced.most_common())
            )
        if s.paused:
            lines.append(f"frames not searched while the camera was on a target: {s.paused}")
        if self.actions is not None:
            lines.append(self.actions.summary())
        return "\n".join(lines)


def format_alert(alert: Alert, track_id: int | None = None) -> str:
    """One console line for a new candidate, or for an alert confirmed (with its evidence)."""
    where = (
        f"at {alert.format_position(6)} {alert.format_error()}".rstrip()
        if alert.position is not None
        else f"- position unknown: {alert.position_note}"
    )
    track = f", track {track_id}" if track_id is not None else ""
    if alert.tier == "candidate":
        return (
            f"CANDIDATE target {alert.target_id}: {alert.class_name} {alert.score:.2f} "
            f"{where} (frame {alert.frame_index}{track}; unconfirmed)"
        )
    evidence = f"; {alert.evidence}" if alert.evidence else ""
    drift = f"; {alert.format_drift()}" if alert.drift_ne is not None else ""
    return (
        f"ALERT target {alert.target_id} ({alert.short_id}): {alert.class_name} "
        f"{alert.format_score()} {where} (frame {alert.frame_index}{track}{evidence}{drift})"
    )


def _time(sighting: Any) -> float:
    return sighting.t


def format_refined(alert: Alert, refinement: Refinement, frame_index: int) -> str:
    """One console line for a placed alert moved to its target's better position."""
    where = f"{alert.format_position(6)} {alert.format_error()}".rstrip()
    drift = f"{alert.format_drift()}; " if alert.drift_ne is not None else ""
    apart = (
        f"sightings {refinement.apart_m:.1f} m apart: one person moved, or two; "
        if refinement.apart_m > 0
        else ""
    )
    return (
        f"REFINED target {alert.target_id}: {alert.class_name} at {where} "
        f"(moved {refinement.moved_m:.1f} m; {drift}{apart}frame {frame_index})"
    )


def format_located(alert: Alert, frame_index: int, track_id: int | None) -> str:
    """One console line for a position found after its target was alerted without one
    (``track_id`` None: placed from its earlier sightings and buffered telemetry)."""
    where = f"{alert.format_position(6)} {alert.format_error()}".rstrip()
    how = f"track {track_id}" if track_id is not None else "from its earlier sightings"
    return (
        f"POSITION target {alert.target_id}: {alert.class_name} at {where} "
        f"(alerted without a position; frame {frame_index}, {how})"
    )
