"""Evidence over seconds in the world frame: when a locked candidate becomes a confirmed alert.

A frame-level lock (m of k frames) is a fraction of a second of evidence: foam, glint, debris
and birds persist that long. A candidate is confirmed only when, over at least
``min_seen_s`` and ``min_sightings`` geolocated sightings, seen in at least ``min_seen_share`` of
the frames processed since its first sighting (a person stays in view; clutter flickers):

- its position persists, or drifts no faster than water and people do: a straight-line fit of
  its fixes over time gives a ground velocity whose speed, less twice its standard error, is at
  most ``max_speed_m_s`` (sun glint moves with the aircraft, birds fly, waves travel); a speed
  above it by less than twice its error waits for a longer span (an oblique view's fixes
  wander by metres with the pose over seconds, as a drifting person does not);
- its size fits a person: the median over sightings of the box's size across the line of
  sight (:func:`sarmission.geo.ground_size.apparent_size_m`: a standing person's height even
  in an oblique view) lies in ``[min_size_m, max_size_m]`` (a boat is metres long, a speck
  centimetres);
- the object under it, measured against its surroundings (:mod:`sarmission.perception.extent`:
  the head's box never grows past its crop, so a boat it calls a swimmer gets a person-sized
  box), is at most ``max_extent_m`` across: the median over the sightings that measured it,
  once at least :data:`MIN_EXTENTS` did (the controller measures every few sightings while the
  candidate is undecided). Its limit is looser than the box's, since a person's shadow, splash
  or ring of disturbed water counts with the person;
- the head's scores of its sightings agree: their mean is at least ``min_score`` (a few lucky
  crops do not make a person). With ``score_window_s`` > 0 the mean is over the sightings of
  the latest ``score_window_s`` only, and a candidate below it waits (until ``give_up_s``)
  rather than being discarded: a person first seen at the edge of the view, small or blurred,
  gets the score of the better view that follows;
- the head calls it a person (or a life-saving appliance) in most of its sightings: a target
  called a boat, jetski or buoy in at least half of them is discarded
  (:mod:`sarmission.class_roles`);
- with ``min_look_change`` > 0, its look changes over a second (:mod:`sarmission.perception.look`:
  a swimmer's arms and head move, a floating object's look stays): the median over the
  sightings that measured it, once at least :data:`MIN_LOOKS` did, is at least
  ``min_look_change``; a steadier one, or one not yet measured, waits (its look may change
  later) until ``give_up_s``.

A candidate that clearly fails (too large, too fast or too faint over ``min_sightings``) is
discarded with the reason; one not confirmed within ``give_up_s`` of its first sighting is
discarded too. Without a position nothing can be checked in the world frame: the candidate
waits (the operator still sees it).

Positions are local metres around the first fix; the velocity's standard error comes from the
fit's residuals, and is at least what two independent fixes of the fixes' own error at the
ends of the span would give (the pose's errors wander over seconds: frame-to-frame fixes are
not independent), so a few fixes on a line cannot fake a precise drift.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from sarmission.class_roles import role_of
from sarmission.mission.config import ConfirmConfig
from sarmission.mission.position_estimate import line_fit

Verdict = Literal["confirm", "wait", "discard"]

#: Sightings that must have measured a candidate's extent for it to count.
MIN_EXTENTS = 3
#: Sightings that must have measured a candidate's look change for it to count.
MIN_LOOKS = 3


@dataclass(frozen=True)
class Sighting:
    """One frame's evidence of a target: capture time, fix, its 1-sigma error, the object's size
    across the line of sight (metres; None when it could not be measured), the head's score and
    its class name (empty: unknown, taken for a person), the track that saw it (None:
    not known), the object's extent against its surroundings (metres; None: not measured) and
    how much its look changed over about a second (:mod:`sarmission.perception.look`; None:
    not measured)."""

    t: float
    lat: float
    lon: float
    error_m: float
    size_m: float | None
    score: float
    label: str = ""
    track_id: int | None = None
    extent_m: float | None = None
    look_change: float | None = None


@dataclass(frozen=True)
class Assessment:
    """A verdict with its reason (``wait``/``discard``) or its evidence (``confirm``), and the
    measured figures (None until measurable)."""

    verdict: Verdict
    reason: str
    seen_s: float = 0.0
    sightings: int = 0
    seen_share: float | None = None
    speed_m_s: float | None = None
    size_m: float | None = None
    score: float | None = None
    extent_m: float | None = None
    look_change: float | None = None

    def summary(self) -> str:
        """One line of the evidence, e.g. ``1.3 s, 9 sightings, drift 0.2 m/s, 0.6 m, 0.84``."""
        parts = [f"{self.seen_s:.1f} s", f"{self.sightings} sightings"]
        if self.seen_share is not None:
            parts.append(f"in {100 * self.seen_share:.0f} % of frames")
        if self.speed_m_s is not None:
            parts.append(f"drift {self.speed_m_s:.1f} m/s")
        if self.size_m is not None:
            parts.append(f"{self.size_m:.1f} m")
        if self.extent_m is not None:
            parts.append(f"extent {self.extent_m:.1f} m")
        if self.look_change is not None:
            parts.append(f"look change {self.look_change:.2f}")
        if self.score is not None:
            parts.append(f"score {self.score:.2f}")
        return ", ".join(parts)


@dataclass(frozen=True)
class SightingFigures:
    """What a candidate's sightings say, whatever the time or the frames since: the span they
    cover, the median size, extent and look change (None: unmeasured), the mean score (over
    the latest ``score_window_s`` when > 0), the drift speed and its standard error (None:
    under three sightings) and the object classes the head named."""

    seen_s: float
    size_m: float | None
    extent_m: float | None
    look_change: float | None
    score: float
    speed_m_s: float | None
    spread_m_s: float | None
    objects: Counter[str]


def sighting_figures(sightings: list[Sighting], score_window_s: float) -> SightingFigures:
    """The figures of ``sightings`` (non-empty, in time order)."""
    sizes = [s.size_m for s in sightings if s.size_m is not None]
    extents = [s.extent_m for s in sightings if s.extent_m is not None]
    looks = [s.look_change for s in sightings if s.look_change is not None]
    speed = spread = None
    if len(sightings) >= 3:
        speed, spread = drift_speed(sightings)
    return SightingFigures(
        seen_s=sightings[-1].t - sightings[0].t,
        size_m=float(np.median(sizes)) if sizes else None,
        extent_m=float(np.median(extents)) if len(extents) >= MIN_EXTENTS else None,
        look_change=float(np.median(looks)) if len(looks) >= MIN_LOOKS else None,
        score=track_score(sightings, score_window_s),
        speed_m_s=speed,
        spread_m_s=spread,
        objects=Counter(s.label for s in sightings if s.label and role_of(s.label) == "object"),
    )


@dataclass
class TargetEvidence:
    """The sightings of one target, in order of capture time. The figures of its sightings
    are kept until they change (:meth:`figures`): a candidate is assessed every frame, and
    fitting its drift over hundreds of sightings each time would cost milliseconds a frame."""

    sightings: list[Sighting] = field(default_factory=list)
    first_seen: float = math.nan
    frames: int = 0  # frames processed since the first sighting, that one included
    _figures: tuple[tuple[int, float, float, float], SightingFigures] | None = field(
        default=None, repr=False, compare=False
    )

    def figures(self, score_window_s: float) -> SightingFigures:
        """:func:`sighting_figures` of the sightings (non-empty), computed again only when
        they changed."""
        key = (len(self.sightings), self.sightings[0].t, self.sightings[-1].t, score_window_s)
        if self._figures is None or self._figures[0] != key:
            self._figures = (key, sighting_figures(self.sightings, score_window_s))
        return self._figures[1]

    @property
    def seen_share(self) -> float:
        """Share of the frames since the first sighting that placed it."""
        return len(self.sightings) / self.frames if self.frames else 0.0

    def add(self, sighting: Sighting) -> None:
        if math.isnan(self.first_seen):
            self.first_seen = sighting.t
        if not self.sightings or sighting.t > self.sightings[-1].t:
            self.sightings.append(sighting)

    def forget(self, track_id: int) -> None:
        """Drop the sightings of ``track_id`` (a track the target registry took back out)."""
        self.sightings = [s for s in self.sightings if s.track_id != track_id]

    def note_unplaced(self, t: float) -> None:
        """A sighting without a fix still starts the give-up clock."""
        if math.isnan(self.first_seen):
            self.first_seen = t


def frames_seen(evidence: TargetEvidence) -> None:
    """Count one processed frame for ``evidence`` (from its first sighting on)."""
    if not math.isnan(evidence.first_seen):
        evidence.frames += 1


def drift_speed(sightings: list[Sighting]) -> tuple[float, float]:
    """``(speed, its standard error)`` in m/s of a straight-line fit of the fixes over time
    (:func:`~sarmission.mission.position_estimate.line_fit`: the error is at least what two
    independent fixes at the ends of the span would give)."""
    fit = line_fit(sightings, (sightings[0].lat, sightings[0].lon))
    if fit is None:
        return 0.0, math.inf
    return fit.speed_m_s, fit.speed_sigma_m_s


def track_score(sightings: list[Sighting], window_s: float = 0.0) -> float:
    """The mean of the head's scores of ``sightings`` (non-empty), over those of the latest
    ``window_s`` seconds when it is > 0."""
    if window_s > 0:
        since = sightings[-1].t - window_s
        sightings = [s for s in sightings if s.t >= since]
    return float(np.mean([s.score for s in sightings]))


def assess(evidence: TargetEvidence, now: float, rule: ConfirmConfig) -> Assessment:
    """The verdict on one candidate at time ``now`` (see the module docstring)."""
    sightings = evidence.sightings
    age = now - evidence.first_seen if not math.isnan(evidence.first_seen) else 0.0
    if not sightings:
        if age > rule.give_up_s:
            return Assessment("discard", f"never placed within {rule.give_up_s:g} s")
        return Assessment("wait", "no position yet")
    measured = evidence.figures(rule.score_window_s)
    seen, size, extent, score = measured.seen_s, measured.size_m, measured.extent_m, measured.score
    speed, spread, objects = measured.speed_m_s, measured.spread_m_s, measured.objects
    share = evidence.seen_share if evidence.frames else None
    figures = dict(
        seen_s=seen,
        sightings=len(sightings),
        seen_share=share,
        speed_m_s=speed,
        size_m=size,
        score=score,
        extent_m=extent,
        look_change=measured.look_change,
    )
    enough = len(sightings) >= rule.min_sightings
    late = f"not confirmed within {rule.give_up_s:g} s"
    if enough and 2 * sum(objects.values()) >= len(sightings):
        name, _ = objects.most_common(1)[0]
        return Assessment(
            "discard",
            f"called {name} in {sum(objects.values())} of {len(sightings)} sightings",
            **figures,
        )
    if enough and size is not None and not rule.min_size_m <= size <= rule.max_size_m:
        return Assessment(
            "discard",
            f"{size:.2f} m across is no person ({rule.min_size_m:g}-{rule.max_size_m:g} m)",
            **figures,
        )
    if enough and extent is not None and 0 < rule.max_extent_m < extent:
        return Assessment(
            "discard",
            f"{extent:.1f} m across against its surroundings is no person "
            f"(at most {rule.max_extent_m:g} m)",
            **figures,
        )
    if (
        enough
        and speed is not None
        and spread is not None
        and speed - 2 * spread > rule.max_speed_m_s
    ):
        return Assessment(
            "discard",
            f"moves {speed:.1f} m/s over the ground (people drift <= {rule.max_speed_m_s:g})",
            **figures,
        )
    unsure = (
        f"drift {speed:.1f} +- {2 * spread:.1f} m/s unsure (people drift <= {rule.max_speed_m_s:g})"
        if speed is not None and spread is not None and speed > rule.max_speed_m_s
        else ""
    )
    if enough and seen >= rule.min_seen_s:
        low = f"score {score:.2f} below {rule.min_score:g}"
        may_wait = rule.score_window_s > 0 and age <= rule.give_up_s
        if score < rule.min_score and not may_wait:
            return Assessment("discard", low, **figures)
        if share is not None and share < rule.min_seen_share:
            return Assessment(
                "discard",
                f"seen in {100 * share:.0f} % of frames (a person "
                f"stays in view: {100 * rule.min_seen_share:.0f} %)",
                **figures,
            )
        if score < rule.min_score:
            return Assessment("wait", low, **figures)
        look = measured.look_change
        steady = ""
        if rule.min_look_change > 0 and look is None:
            steady = "look change not measured yet"
        elif look is not None and look < rule.min_look_change:
            steady = f"look steady over a second (change {look:.2f} < {rule.min_look_change:g})"
        pending = "size unknown" if size is None else unsure or steady
        if pending:
            if age > rule.give_up_s:
                return Assessment("discard", f"{late} ({pending})", **figures)
            return Assessment("wait", pending, **figures)
        return Assessment("confirm", "", **figures)
    have = (
        f"{len(sightings)} sightings over {seen:.1f} s; "
        f"needs {rule.min_sightings} over {rule.min_seen_s:g} s"
    )
    if age > rule.give_up_s:
        return Assessment("discard", f"{late} ({have})", **figures)
    return Assessment("wait", have, **figures)
