"""Multi-target tracker for tiny boxes: Kalman prediction, Hungarian NWD association, m-of-k lock.

Each call to :meth:`Tracker.update` is one processed frame:

1. predict every track to this frame (``dt`` = frame-index step; optional camera shift);
2. associate predicted boxes with detections by the Hungarian algorithm on the cost
   ``1 - NWD(track, detection)``. A pair may match only if it passes the gate
   ``NWD >= match_nwd  or  centre distance <= max_centre_distance``;
3. matched tracks take the detection (Kalman update, hit); unmatched tracks coast (miss);
4. a track whose consecutive misses exceed ``max_age`` dies;
5. every unmatched detection starts a new track (its first hit).

Every live track feeds its :class:`MofKLock` one hit or miss per frame, its birth frame included,
so it locks at exactly the m-th hit inside a window of k frames and stays locked.

NWD, not IoU: two boxes 4 px wide and 4 px apart do not overlap at all (IoU 0) yet are almost
surely the same swimmer; NWD (``exp(-W/C)``, W the Wasserstein distance of the boxes seen as
Gaussians) falls off smoothly with distance and size difference whatever the box size. The NWD
gate needs the sizes to agree; the centre-distance gate still lets a detection close to the
predicted centre match when its size estimate is off.

Association is class-agnostic: a swimmer flickers between "swimmer" and "swimmer with life jacket"
from frame to frame, and splitting tracks on that would delay or prevent the lock. Each track
instead keeps a vote over its hits' classes and reports the majority class.
"""

from __future__ import annotations

from collections import Counter, deque
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from sarmission.boxes import NWD_CONSTANT, nwd_matrix, xyxy_to_cxcywh
from sarmission.perception.types import Detections
from sarmission.tracking.kalman import BoxKalman, MotionNoise
from sarmission.tracking.lock import MofKLock

#: Weight of the newest detection score in a track's smoothed score (exponential average).
SCORE_SMOOTHING = 0.3

#: One history entry: (frame_index, timestamp, cx, cy), the filtered centre in px.
HistoryEntry = tuple[int, float, float, float]


@dataclass(frozen=True)
class TrackState:
    """Snapshot of one track after a frame.

    ``box`` is the filtered box ``[x1, y1, x2, y2]`` (the prediction when the track missed this
    frame), ``raw_box`` the last detection it took and ``last_score`` that detection's score.
    ``score`` is the exponentially smoothed detection score, ``class_id`` the majority class
    over its hits (ties go to the latest).
    ``hits`` counts detections taken, ``age`` frames lived (1 on its birth frame), ``misses``
    frames since its last hit. ``lock_frame`` is the frame index at which it locked and
    ``just_locked`` is true on that frame only. ``velocity`` is ``(vx, vy)`` in px/frame.
    ``history`` holds the last filtered centres, oldest first.
    """

    track_id: int
    box: np.ndarray
    raw_box: np.ndarray
    score: float
    class_id: int
    hits: int
    age: int
    misses: int
    locked: bool
    lock_frame: int | None
    just_locked: bool
    velocity: tuple[float, float]
    history: tuple[HistoryEntry, ...]
    last_score: float = 0.0


def associate(
    track_boxes: np.ndarray,
    detection_boxes: np.ndarray,
    match_nwd: float,
    max_centre_distance: float,
    nwd_constant: float = NWD_CONSTANT,
) -> tuple[list[tuple[int, int]], list[int], list[int]]:
    """Match ``[T, 4]`` track boxes to ``[D, 4]`` detection boxes (both ``xyxy``).

    Minimises the total ``1 - NWD`` over one-to-one pairs, then drops pairs outside the gate.
    Returns ``(matches as (track, detection) index pairs, unmatched tracks, unmatched detections)``.
    """
    n_tracks, n_dets = len(track_boxes), len(detection_boxes)
    if n_tracks == 0 or n_dets == 0:
        return [], list(range(n_tracks)), list(range(n_dets))
    nwd = nwd_matrix(track_boxes, detection_boxes, nwd_constant)
    t, d = xyxy_to_cxcywh(track_boxes), xyxy_to_cxcywh(detection_boxes)
    centre_distance = np.hypot(t[:, None, 0] - d[None, :, 0], t[:, None, 1] - d[None, :, 1])
    allowed = (nwd >= match_nwd) | (centre_distance <= max_centre_distance)
    # A pair outside the gate costs more than any whole set of gated pairs (each costs <= 1),
    # so the assignment first maximises the number of gated pairs; the others are dropped.
    cost = np.where(allowed, 1.0 - nwd, 2.0 + n_tracks + n_dets)
    rows, cols = linear_sum_assignment(cost)
    matches = [(int(r), int(c)) for r, c in zip(rows, cols, strict=True) if allowed[r, c]]
    matched_tracks = {r for r, _ in matches}
    matched_dets = {c for _, c in matches}
    return (
        matches,
        [i for i in range(n_tracks) if i not in matched_tracks],
        [j for j in range(n_dets) if j not in matched_dets],
    )


class _Track:
    """One target's filter, lock and bookkeeping; born from a detection (its first hit)."""

    def __init__(
        self,
        track_id: int,
        box: np.ndarray,
        score: float,
        class_id: int,
        noise: MotionNoise,
        lock: MofKLock,
        history_length: int,
        lock_min_score: float = 0.0,
    ) -> None:
        self.track_id = track_id
        self.lock_min_score = lock_min_score
        self.kalman = BoxKalman(box, noise)
        self.lock = lock
        self.raw_box = np.asarray(box, dtype=np.float64).copy()
        self.score = float(score)
        self.last_score = float(score)
        self.class_votes: Counter[int] = Counter()
        self.last_class = int(class_id)
        self.hits = self.misses = 0
        self.age = 1
        self.lock_frame: int | None = None
        self.just_locked = False
        self.history: deque[HistoryEntry] = deque(maxlen=history_length)
        self._record_hit(score, class_id)

    def predict(self, dt: float, camera_shift: tuple[float, float] | None) -> np.ndarray:
        self.age += 1
        return self.kalman.predict(dt, camera_shift)

    def hit(self, box: np.ndarray, score: float, class_id: int) -> None:
        self.kalman.update(box)
        self.raw_box = np.asarray(box, dtype=np.float64).copy()
        self.last_score = float(score)
        self.score = (1 - SCORE_SMOOTHING) * self.score + SCORE_SMOOTHING * float(score)
        self._record_hit(score, class_id)

    def miss(self) -> None:
        self.misses += 1
        self.just_locked = False
        self.lock.update(False)

    def _record_hit(self, score: float, class_id: int) -> None:
        self.hits += 1
        self.misses = 0
        self.class_votes[int(class_id)] += 1
        self.last_class = int(class_id)
        was_locked = self.lock.locked
        self.just_locked = self.lock.update(score >= self.lock_min_score) and not was_locked

    def end_frame(self, frame_index: int, timestamp: float) -> None:
        """Record this frame's centre and, if the lock just happened, its frame index."""
        if self.just_locked:
            self.lock_frame = frame_index
        cx, cy = self.kalman.centre
        self.history.append((frame_index, timestamp, cx, cy))

    @property
    def class_id(self) -> int:
        top = max(self.class_votes.values())
        tied = [c for c, n in self.class_votes.items() if n == top]
        return self.last_class if self.last_class in tied else tied[0]

    def state(self) -> TrackState:
        return TrackState(
            track_id=self.track_id,
            box=self.kalman.box,
            raw_box=self.raw_box.copy(),
            score=self.score,
            class_id=self.class_id,
            hits=self.hits,
            age=self.age,
            misses=self.misses,
            locked=self.lock.locked,
            lock_frame=self.lock_frame,
            just_locked=self.just_locked,
            velocity=self.kalman.velocity,
            history=tuple(self.history),
            last_score=self.last_score,
        )


class Tracker:
    """Tracks tiny detections over frames and confirms them with an m-of-k lock.

    ``max_age``: consecutive missed frames a track survives (it dies at ``max_age + 1``); 15 is
    half a second at 30 fps, long enough to ride out a swimmer hidden by a wave crest.
    ``min_hits_to_report``: tracks with fewer hits are not returned unless locked (display
    filter only; the lock is the confirmation).
    ``match_nwd`` / ``max_centre_distance``: association gate (see the module docstring). NWD 0.3
    is a Wasserstein distance of about 15 px at C = 12.8; 8 px covers a new track's first step
    under platform motion even when the detector's size estimate disagrees.
    ``lock_m`` / ``lock_k``: a track locks at the ``lock_m``-th hit within ``lock_k`` frames;
    ``lock_min_score``: a detection scored below it still feeds the track (filter, age) but counts
    as a miss for the lock, as the evaluation's lock counts only detections scored above 0.5.
    ``noise``: Kalman noise levels; ``history_length``: centres kept per track.
    """

    def __init__(
        self,
        max_age: int = 15,
        min_hits_to_report: int = 1,
        match_nwd: float = 0.3,
        max_centre_distance: float = 8.0,
        lock_m: int = 3,
        lock_k: int = 5,
        noise: MotionNoise | None = None,
        history_length: int = 300,
        nwd_constant: float = NWD_CONSTANT,
        lock_min_score: float = 0.0,
    ) -> None:
        if max_age < 0 or history_length < 1:
            raise ValueError("max_age must be >= 0 and history_length >= 1")
        MofKLock(lock_m, lock_k)  # validates m and k now rather than at the first birth
        self.max_age = max_age
        self.min_hits_to_report = min_hits_to_report
        self.match_nwd = match_nwd
        self.max_centre_distance = max_centre_distance
        self.lock_m, self.lock_k = lock_m, lock_k
        if not 0.0 <= lock_min_score <= 1.0:
            raise ValueError(f"lock_min_score must be in [0, 1], got {lock_min_score}")
        self.lock_min_score = lock_min_score
        self.noise = noise or MotionNoise()
        self.history_length = history_length
        self.nwd_constant = nwd_constant
        self._tracks: list[_Track] = []
        self._next_id = 1
        self._last_frame: int | None = None

    def drop_tracks(self) -> None:
        """Forget every track (e.g. after a gap in the frames); new tracks get new ids."""
        self._tracks = []

    def update(
        self,
        detections: Detections,
        frame_index: int,
        timestamp: float,
        *,
        camera_shift: tuple[float, float] | None = None,
    ) -> list[TrackState]:
        """Take one frame's detections and return the reported tracks' states.

        ``frame_index`` must increase from call to call; gaps (skipped frames) scale the motion
        prediction, while misses, ``max_age`` and the lock count calls. ``camera_shift=(dx, dy)``
        is the image displacement of static ground since the previous processed frame, in px,
        applied to every track's prediction; ``None`` when unknown.
        """
        if self._last_frame is not None and frame_index <= self._last_frame:
            raise ValueError(f"frame_index must increase: {frame_index} after {self._last_frame}")
        dt = 1.0 if self._last_frame is None else float(frame_index - self._last_frame)
        self._last_frame = frame_index

        predicted = np.array([t.predict(dt, camera_shift) for t in self._tracks]).reshape(-1, 4)
        boxes = np.asarray(detections.boxes, dtype=np.float64).reshape(-1, 4)
        matches, unmatched_tracks, unmatched_dets = associate(
            predicted, boxes, self.match_nwd, self.max_centre_distance, self.nwd_constant
        )
        for ti, di in matches:
            self._tracks[ti].hit(boxes[di], detections.scores[di], detections.class_ids[di])
        for ti in unmatched_tracks:
            self._tracks[ti].miss()
        self._tracks = [t for t in self._tracks if t.misses <= self.max_age]
        for di in unmatched_dets:
            self._tracks.append(
                _Track(
                    self._next_id,
                    boxes[di],
                    detections.scores[di],
                    detections.class_ids[di],
                    self.noise,
                    MofKLock(self.lock_m, self.lock_k),
                    self.history_length,
                    self.lock_min_score,
                )
            )
            self._next_id += 1

        for track in self._tracks:
            track.end_frame(frame_index, timestamp)
        return [
            t.state() for t in self._tracks if t.hits >= self.min_hits_to_report or t.lock.locked
        ]
