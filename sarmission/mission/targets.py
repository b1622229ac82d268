"""Target registry: one target per person on the ground, however many tracks saw them.

The tracker's ids live in image space and break whenever a person leaves the frame, is hidden by
a wave for too long, or the drone flies a new leg over them. The registry joins tracks in ground
space, and in the image where there is no ground position to compare:

- a track keeps the target it first joined (``track_id -> target_id``);
- a new locked track with a position joins the nearest target whose position lies within
  ``max(merge_radius_m, GATE_SIGMA * hypot(target error, fix error))`` of its fix: the errors
  are 1-sigma RMS (DRMS), so two fixes of one person lie within twice their combined error
  98 % of the time, and a target with poorer fixes gets a wider gate. The radius beyond that
  statistical gate is for a person found again after a while: it is granted only as far as a
  person can move since the target was last seen (:data:`PERSON_SPEED_M_S`). The same gate
  around the target's latest fix (its error, the time since that fix) also admits the track:
  a person drifting with a current lies, after a while, far from the mean of their fixes and
  near the latest one, so a new track on them minutes later, or moments after another track
  saw them, is not a second person. A target another
  track saw moments ago (:data:`CONCURRENT_S`) is in view now: there the image says more than
  the ground, since simultaneous fixes share their errors, so the new track joins it only if
  its box lies within twice the larger box side of the target's. Two people a few metres
  apart, both in view, stay two targets (mixed, their fixes would look like one target jumping
  between them, and its position would lie between them). Only boxes of the same frame are
  compared at once: a box seen moments before may be far only because a turning drone swept
  the person across the image (the camera shift is no rotation) and the tracker lost them, so
  the new track is *pending* (``observe`` returns no target) until the target's own track sees
  it again in one frame with the new one (two people) or has not seen it for
  :data:`CONCURRENT_S` (the same person, found again). One exception: a track that joined
  the target at most :data:`YIELD_S` ago only by the re-find radius (a sun glint or debris a
  few metres from a person seen a while ago, which locked first on the next pass) yields the
  target to a new track that sees it in the same frame within the statistical gate of the
  target's position without the yielding track's fixes. The yielding track's fixes, votes and
  score leave the target and its next sighting is compared as a new track's (it is listed in
  :attr:`TargetRegistry.detached` until then), so the person is not alerted twice and the
  glint gets no share of their position;
- a new locked track without a position (stale telemetry, ray above the horizon) cannot be
  compared on the ground, so it is compared in the image: it joins the target whose last box
  was seen at most ``merge_window_s`` earlier (or later) with its centre within
  ``max(merge_gate_px, the larger side of either box)`` of the track's box centre (nearest
  wins), unless another track sees that target now somewhere else (as above, pending
  included). This keeps one
  person one target while telemetry is out: a track lost and re-born, or a second track locking
  on the same person;
- a new locked track with a position that matches no target on the ground is compared in the
  image with the targets that have no position yet, the same way: the person first seen
  while telemetry was out gets their position from it;
- otherwise the track starts a new target (``position None`` and the reason if it has no fix).

Boxes are ``[x1, y1, x2, y2]`` in full-resolution pixels of the scene: the caller removes the
camera's own motion (the sum of the image shifts since the stream began), so a person who
stays put keeps their coordinates while the drone flies on. The defaults (5 s, 64 px) cover a
track that coasts through its misses and locks again at a few frames per second, while 64 px
at 4K is about 1.5-2 m on the water from 60-80 m: closer than the ground merge radius.

A target's position is the inverse-variance weighted mean of its fixes (weights ``1 / e^2``,
``e`` each fix's 1-sigma error), computed in metres around the first fix. Successive fixes share
most of their error (GNSS bias, altitude and attitude errors that wander over seconds), so
averaging does not shrink it: the target's error (:attr:`Target.error_m`) is that of a weighted
mean of fully correlated errors, the same weighted mean of the fixes' errors. It is never
below the best fix's error, and at an oblique view, where the fixes' errors vary with their
depression, it is not that of the luckiest fix either. This mean is what the merge gates compare;
an alert reports where the target is as of its latest fix instead
(:mod:`sarmission.mission.position_estimate`: a person drifting with a current is not where the
mean of a minute's fixes lies).

A restarted controller seeds the registry from the alert store's known targets
(:meth:`TargetRegistry.seed`), each with the error of its stored position: they are already
announced, so a person found again joins them (through the same gate) instead of being
announced twice. The stored position counts as one fix of its stored error, so the fixes of
the new run are averaged with it rather than replacing it.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from sarmission.geo.geolocate import GeoFix
from sarmission.geo.wgs84 import geodetic_to_ned, ned_to_geodetic

log = logging.getLogger(__name__)

#: Weight floor: a fix without an error estimate counts as this error (metres).
DEFAULT_FIX_ERROR_M = 10.0
#: Merge gate in combined 1-sigma errors (see the module docstring).
GATE_SIGMA = 2.0
#: The fastest a person moves over the ground (m/s): walking, swimming, drifting with a current.
#: A target last seen ``dt`` seconds ago is joined only within the statistical gate plus this
#: speed times ``dt`` (and never beyond the merge radius's reach).
PERSON_SPEED_M_S = 2.0
#: A target seen by another track at most this many seconds ago is in view now (see the module
#: docstring): a new track joins it only where their boxes nearly meet.
CONCURRENT_S = 0.5
#: A track that joined a target only by the re-find radius (beyond the statistical gate) yields
#: the target for this long to a track that fits it within the gate in the same frame (see the
#: module docstring).
YIELD_S = 2.0


@dataclass(frozen=True)
class KnownTarget:
    """A target announced in an earlier run: its stored position and that position's 1-sigma
    error (None when unknown)."""

    position: tuple[float, float] | None
    error_m: float | None = None


@dataclass
class WeightedFixes:
    """Sums over fixes with weights ``w = 1 / error^2``: of ``w``, ``w * error``, and of ``w``
    times the north and east offsets (metres around the target's first fix). Sums add and
    subtract, so a track's share can be taken out of its target again."""

    w: float = 0.0
    w_error: float = 0.0
    w_n: float = 0.0
    w_e: float = 0.0

    def add(self, n: float, e: float, error_m: float) -> None:
        """Fold in one fix at ``(n, e)`` with 1-sigma ``error_m``."""
        w = 1.0 / error_m**2
        self.w += w
        self.w_error += w * error_m
        self.w_n += w * n
        self.w_e += w * e

    def minus(self, other: WeightedFixes) -> WeightedFixes:
        """These sums without ``other``'s."""
        return WeightedFixes(
            self.w - other.w,
            self.w_error - other.w_error,
            self.w_n - other.w_n,
            self.w_e - other.w_e,
        )

    def empty(self, scale: float = 1.0) -> bool:
        """Whether no weight is left (relative to ``scale``, against rounding)."""
        return self.w <= 1e-12 * max(scale, 1.0)

    def mean(self) -> tuple[float, float]:
        """The weighted mean ``(north, east)``."""
        return self.w_n / self.w, self.w_e / self.w

    def error_m(self) -> float:
        """The error of the weighted mean when the fixes' errors are fully correlated: the
        weighted mean of their errors."""
        return self.w_error / self.w


@dataclass
class TrackShare:
    """What one track added to a target, so that it can be taken out again: its fixes' weighted
    sums (:class:`WeightedFixes`), latest fix, class votes and best score, when it joined and
    whether it joined only by the re-find radius (``loose``).

    ``gap_s`` is how long the target had been out of sight when the track joined (0 for the
    track that started it, NaN for a target known from an earlier run); ``fixes`` and
    ``first_fix_t`` count its placed sightings. ``jump_m`` is set by
    :mod:`sarmission.mission.continuity` once the track's fixes were compared with the
    target's before it joined (None: not yet)."""

    joined: float
    loose: bool = False
    sums: WeightedFixes = field(default_factory=WeightedFixes)
    last_fix: tuple[float, float, float | None, float] | None = None
    class_votes: Counter[int] = field(default_factory=Counter)
    best_score: float = 0.0
    gap_s: float = 0.0
    fixes: int = 0
    first_fix_t: float = math.nan
    jump_m: float | None = None


@dataclass
class Target:
    """One person on the ground (or one unplaced sighting).

    ``lat``/``lon`` are None when no fix was possible (``note`` says why). ``error_m`` is the
    1-sigma horizontal error of the position. ``first_seen``/``last_seen`` are the capture times
    of the frames that showed it. ``announced`` is True once an alert exists for it (seeded
    targets start announced). ``box`` is the last box seen, in scene pixels (see the module
    docstring), at capture time ``box_time`` (None and NaN for a seeded target).
    """

    target_id: int
    first_seen: float
    last_seen: float
    lat: float | None = None
    lon: float | None = None
    error_m: float | None = None
    note: str = ""
    best_score: float = 0.0
    class_votes: Counter[int] = field(default_factory=Counter)
    track_ids: set[int] = field(default_factory=set)
    announced: bool = False
    box: tuple[float, float, float, float] | None = None
    box_time: float = math.nan
    #: ``(lat, lon, error_m, capture time)`` of the latest fix (None: none yet, or seeded)
    last_fix: tuple[float, float, float | None, float] | None = None
    #: the track whose box :attr:`box` is
    box_track: int | None = None
    #: track id -> what it added (:meth:`detach` takes it out)
    shares: dict[int, TrackShare] = field(default_factory=dict)
    _sums: WeightedFixes = field(default_factory=WeightedFixes)
    _origin: tuple[float, float] | None = None

    @property
    def position(self) -> tuple[float, float] | None:
        """``(lat, lon)`` in degrees, or None when the target has no fix."""
        if self.lat is None or self.lon is None:
            return None
        return self.lat, self.lon

    @property
    def class_id(self) -> int:
        """The majority class over every observation (-1 for a seeded target never seen)."""
        if not self.class_votes:
            return -1
        return self.class_votes.most_common(1)[0][0]

    def add_fix(self, fix: GeoFix, track_id: int | None = None) -> None:
        """Fold one geolocated observation into the weighted mean position (and into the share
        of ``track_id``, when given)."""
        assert fix.lat is not None and fix.lon is not None
        error = fix.error_m if fix.error_m is not None and fix.error_m > 0 else DEFAULT_FIX_ERROR_M
        n, e = self._fold((fix.lat, fix.lon), error)
        share = self.shares.get(track_id) if track_id is not None else None
        if share is not None:
            share.sums.add(n, e, error)
        self._place()
        self.note = fix.note

    def seed_position(self, position: tuple[float, float], error_m: float) -> None:
        """Start from a stored position as one fix of ``error_m``: fixes found after a restart
        are averaged with it, never put in its place (the stored position is already the
        mean of the fixes the earlier run had)."""
        self._fold(position, error_m)
        self._place()
        self.note = "known from an earlier run"

    def _fold(self, position: tuple[float, float], error_m: float) -> tuple[float, float]:
        """Add ``position`` with 1-sigma ``error_m`` to the weighted sums (metres around the
        first position folded in); returns its north, east offsets."""
        if self._origin is None:
            self._origin = position
        n, e = offset_m(self._origin, position)
        self._sums.add(n, e, error_m)
        return n, e

    def _place(self) -> None:
        """``lat``/``lon`` and ``error_m`` from the weighted sums."""
        self.lat, self.lon = self._mean(self._sums)
        self.error_m = self._sums.error_m()

    def _mean(self, sums: WeightedFixes) -> tuple[float, float]:
        """``(lat, lon)`` of the weighted mean of ``sums`` (metres around the first fix)."""
        assert self._origin is not None and sums.w > 0
        n, e = sums.mean()
        lat, lon, _ = ned_to_geodetic(n, e, 0.0, self._origin[0], self._origin[1], 0.0)
        return float(lat), float(lon)

    def position_without(self, track_id: int) -> tuple[float, float] | None:
        """The position the target would have without ``track_id``'s fixes (None: none left)."""
        share = self.shares.get(track_id)
        if share is None:
            return self.position
        rest = self._sums.minus(share.sums)
        if self._origin is None or rest.empty(self._sums.w):
            return None
        return self._mean(rest)

    def detach(self, track_id: int) -> None:
        """Take ``track_id`` and what it added out of the target (its position, error, latest
        fix, class votes and best score are those of the other tracks again)."""
        share = self.shares.pop(track_id, None)
        self.track_ids.discard(track_id)
        if share is None:
            return
        rest = self._sums.minus(share.sums)
        self.class_votes.subtract(share.class_votes)
        self.class_votes = +self.class_votes
        others = list(self.shares.values())
        self.best_score = max((o.best_score for o in others), default=0.0)
        fixes = [o.last_fix for o in others if o.last_fix is not None]
        self.last_fix = max(fixes, key=lambda f: f[3]) if fixes else None
        emptied = rest.empty(self._sums.w)
        self._sums = rest
        if not emptied:
            self._place()
        if self.box_track == track_id:
            self.box, self.box_time, self.box_track = None, math.nan, None


def offset_m(origin: tuple[float, float], point: tuple[float, float]) -> tuple[float, float]:
    """``(north, east)`` metres of ``point`` from ``origin`` (both ``(lat, lon)`` degrees)."""
    n, e, _ = geodetic_to_ned(point[0], point[1], 0.0, origin[0], origin[1], 0.0)
    return float(n), float(e)


def distance_m(a: tuple[float, float], b: tuple[float, float]) -> float:
    """Horizontal distance in metres between two ``(lat, lon)`` points."""
    return math.hypot(*offset_m(a, b))


def _centre(box: Sequence[float]) -> tuple[float, float]:
    return (box[0] + box[2]) / 2.0, (box[1] + box[3]) / 2.0


def _side(box: Sequence[float]) -> float:
    return max(box[2] - box[0], box[3] - box[1])


#: :func:`_in_view_elsewhere`'s answers.
APART, UNSURE, NOT_ELSEWHERE = "apart", "unsure", ""


def _in_view_elsewhere(target: Target, box: Sequence[float] | None, t: float) -> str:
    """Whether another track saw ``target`` moments before ``t`` (:data:`CONCURRENT_S`) at a
    place in the image ``box`` does not nearly meet: :data:`APART` in the same frame (both in
    view, so another person), :data:`UNSURE` in an earlier one (another person, or this one
    swept across the image since), else :data:`NOT_ELSEWHERE`."""
    since = t - target.box_time
    if box is None or target.box is None or not 0 <= since <= CONCURRENT_S:
        return NOT_ELSEWHERE
    if math.dist(_centre(box), _centre(target.box)) <= 2 * max(_side(box), _side(target.box)):
        return NOT_ELSEWHERE
    return APART if since == 0 else UNSURE


@dataclass
class Match:
    """A new track's match: the target it joins (None: none), whether that is still unsure
    (pending), whether it lies only within the re-find radius (``loose``), and the track it
    takes the target over from (None: none)."""

    target: Target | None = None
    unsure: bool = False
    loose: bool = False
    takes_from: int | None = None


class TargetRegistry:
    """Tracks -> targets (see the module docstring). Not thread-safe: one controller owns it.

    Args:
        merge_radius_m: a new fix joins a target within this distance (metres) or within the
            combined 1-sigma errors, whichever is larger.
        merge_window_s: a new track is compared in the image only with targets whose last box
            was seen at most this many seconds from its sighting.
        merge_gate_px: the largest distance (full-resolution pixels) between box centres for
            the image comparison to match, unless either box's larger side is larger still.
    """

    def __init__(
        self, merge_radius_m: float = 8.0, merge_window_s: float = 5.0, merge_gate_px: float = 64.0
    ) -> None:
        for name, value in (
            ("merge_radius_m", merge_radius_m),
            ("merge_window_s", merge_window_s),
            ("merge_gate_px", merge_gate_px),
        ):
            if not value >= 0:
                raise ValueError(f"{name} must be >= 0, got {value}")
        self.merge_radius_m = merge_radius_m
        self.merge_window_s = merge_window_s
        self.merge_gate_px = merge_gate_px
        self.targets: dict[int, Target] = {}
        self._by_track: dict[int, int] = {}
        self._next_id = 1
        #: track -> the target it was taken out of (:meth:`_detach`), until the caller clears
        #: it; the track's next sighting is compared as a new track's
        self.detached: dict[int, int] = {}

    def __len__(self) -> int:
        return len(self.targets)

    def seed(self, known: Mapping[int, KnownTarget | tuple[float, float] | None]) -> None:
        """Add targets already announced (alert store ``known_targets``: id -> known target,
        or a bare position / None when the error is unknown; an unknown error counts as
        :data:`DEFAULT_FIX_ERROR_M`). New targets are numbered after the highest known id.
        """
        for target_id, entry in known.items():
            if not isinstance(entry, KnownTarget):
                entry = KnownTarget(entry, None)
            position = entry.position
            target = Target(int(target_id), math.nan, math.nan, announced=True)
            if position is not None:
                error = (
                    entry.error_m
                    if entry.error_m is not None and entry.error_m > 0
                    else DEFAULT_FIX_ERROR_M
                )
                target.seed_position((float(position[0]), float(position[1])), error)
            else:
                target.note = "known from an earlier run, without a position"
            self.targets[target.target_id] = target
            self._next_id = max(self._next_id, target.target_id + 1)

    def target_of(self, track_id: int) -> Target | None:
        """The target a track joined, if any."""
        target_id = self._by_track.get(track_id)
        return None if target_id is None else self.targets[target_id]

    def observe(
        self,
        track_id: int,
        class_id: int,
        score: float,
        t: float,
        fix: GeoFix | None,
        note: str = "",
        box: Sequence[float] | None = None,
    ) -> tuple[Target | None, bool]:
        """Record a locked track's sighting at capture time ``t``; returns ``(target, is_new)``.

        ``fix`` is the sighting's geolocation (None or not ``ok`` when there is none; ``note``,
        or the fix's own note, then says why). ``box`` is the track's box in scene pixels (see
        the module docstring); without it a new track is compared on the ground only.
        ``is_new`` is True only when this sighting created the target. A new track whose match
        is still unsure (see the module docstring) is pending: ``(None, False)``, nothing is
        recorded, and a later sighting decides. Observe the tracks that have a target first in
        each frame, so that a new one is compared with their boxes of that frame.
        """
        placed = fix is not None and fix.ok
        target = self.target_of(track_id)
        is_new = False
        if target is None:
            match = self._nearest(fix, t, box) if placed else Match()
            if match.target is None and not match.unsure and box is not None:
                match = self._nearest_in_image(box, t, unplaced_only=placed)
            if match.unsure:
                return None, False
            target = match.target
            if target is None:
                is_new = True
                target = Target(self._next_id, t, t)
                self._next_id += 1
                self.targets[target.target_id] = target
            elif match.takes_from is not None:
                self._detach(target, match.takes_from)
                log.info(
                    "track %d took target %d over from track %d, which had joined it only by "
                    "the re-find radius and sees something else in this frame",
                    track_id,
                    target.target_id,
                    match.takes_from,
                )
            self._by_track[track_id] = target.target_id
            target.track_ids.add(track_id)
            gap = 0.0 if is_new else t - target.last_seen
            target.shares[track_id] = TrackShare(joined=t, loose=match.loose, gap_s=gap)
        share = target.shares[track_id]  # every track that joined through here has one
        if placed:
            target.add_fix(fix, track_id)
            assert fix.lat is not None and fix.lon is not None
            target.last_fix = share.last_fix = (fix.lat, fix.lon, fix.error_m, t)
            share.fixes += 1
            if share.fixes == 1:
                share.first_fix_t = t
        elif target.position is None:
            target.note = note or (fix.note if fix is not None else "") or "no position"
        target.class_votes[int(class_id)] += 1
        target.best_score = max(target.best_score, float(score))
        share.class_votes[int(class_id)] += 1
        share.best_score = max(share.best_score, float(score))
        if math.isnan(target.first_seen):
            target.first_seen = t
        target.last_seen = t if math.isnan(target.last_seen) else max(target.last_seen, t)
        if box is not None:
            target.box = (float(box[0]), float(box[1]), float(box[2]), float(box[3]))
            target.box_time = t
            target.box_track = track_id
        return target, is_new

    def _detach(self, target: Target, track_id: int) -> None:
        """``track_id`` leaves ``target``: its next sighting is compared as a new track's."""
        target.detach(track_id)
        self._by_track.pop(track_id, None)
        self.detached[track_id] = target.target_id

    def _nearest(self, fix: GeoFix, t: float, box: Sequence[float] | None) -> Match:
        """The target ``fix`` joins on the ground: the nearest one within the gate, unsure when
        its box of an earlier frame lies elsewhere in the image. A target another track sees
        elsewhere in this frame is someone else, unless that track joined it moments ago only
        by the re-find radius and ``fix`` lies within the statistical gate of the target
        without it: then this track is the better match and takes the target over."""
        assert fix.lat is not None and fix.lon is not None
        here = (fix.lat, fix.lon)
        best = Match()
        best_d = math.inf
        for target in self.targets.values():
            if target.position is None:
                continue
            if _in_view_elsewhere(target, box, t) == APART:
                yielding = self._yielding_track(target, fix, t)
                if yielding is not None and yielding[1] < best_d:
                    best, best_d = Match(target, takes_from=yielding[0]), yielding[1]
                continue
            d = distance_m(target.position, here)
            near = self._within(d, target.error_m, fix.error_m, t - target.last_seen)
            tight = near and d <= self._statistical(target.error_m, fix.error_m)
            if target.last_fix is not None:
                lat, lon, error, when = target.last_fix
                d_last = distance_m((lat, lon), here)
                if self._within(d_last, error, fix.error_m, t - when):
                    d = min(d, d_last) if near else d_last
                    near = True
                    tight = tight or d_last <= self._statistical(error, fix.error_m)
            if near and d < best_d:
                best, best_d = Match(target, loose=not tight), d
        if best.target is not None and best.takes_from is None:
            best.unsure = _in_view_elsewhere(best.target, box, t) == UNSURE
        return best

    def _yielding_track(self, target: Target, fix: GeoFix, t: float) -> tuple[int, float] | None:
        """The track that saw ``target`` in this frame and the distance (metres) of ``fix``
        from the target without it, when that track joined at most :data:`YIELD_S` ago only by
        the re-find radius and ``fix`` lies within the statistical gate (see :meth:`_nearest`);
        else None."""
        holder = target.box_track
        share = target.shares.get(holder) if holder is not None else None
        if share is None or not share.loose or not 0 <= t - share.joined <= YIELD_S:
            return None
        position = target.position_without(holder)
        if position is None:
            return None
        assert fix.lat is not None and fix.lon is not None
        d = distance_m(position, (fix.lat, fix.lon))
        return (holder, d) if d <= self._statistical(target.error_m, fix.error_m) else None

    @staticmethod
    def _statistical(error_a: float | None, error_b: float | None) -> float:
        """The statistical gate (metres) of two fixes with 1-sigma errors ``error_a`` and
        ``error_b`` (None or NaN: :data:`DEFAULT_FIX_ERROR_M`)."""
        a = DEFAULT_FIX_ERROR_M if error_a is None or not error_a > 0 else error_a
        b = DEFAULT_FIX_ERROR_M if error_b is None or not error_b > 0 else error_b
        return GATE_SIGMA * math.hypot(a, b)

    def _within(self, d: float, error_a: float | None, error_b: float | None, since: float) -> bool:
        """Whether two positions ``d`` metres apart, with 1-sigma errors ``error_a`` and
        ``error_b`` (None or NaN: :data:`DEFAULT_FIX_ERROR_M`) and ``since`` seconds between
        them, may be one person (the module docstring's gate; NaN ``since``: a target known from
        an earlier run, the whole radius)."""
        statistical = self._statistical(error_a, error_b)
        gate = max(self.merge_radius_m, statistical)
        if since >= 0:
            gate = min(gate, statistical + PERSON_SPEED_M_S * since)
        return d <= gate

    def _nearest_in_image(self, box: Sequence[float], t: float, unplaced_only: bool) -> Match:
        """The target ``box`` joins in the image, and whether that match is unsure."""
        centre = _centre(box)
        best: Target | None = None
        best_d = math.inf
        for target in self.targets.values():
            if target.box is None or (unplaced_only and target.position is not None):
                continue
            if not abs(t - target.box_time) <= self.merge_window_s:
                continue
            if _in_view_elsewhere(target, box, t) == APART:
                continue
            d = math.dist(centre, _centre(target.box))
            gate = max(self.merge_gate_px, _side(box), _side(target.box))
            if d <= gate and d < best_d:
                best, best_d = target, d
        return Match(best, unsure=best is not None and _in_view_elsewhere(best, box, t) == UNSURE)
