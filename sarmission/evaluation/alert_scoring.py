"""Scoring confirmed alerts against a flight's ground truth: people found, false alerts per hour,
time from first view to alert, geolocation error.

Inputs are plain records, so any simulator or annotated flight can be scored:

- frames: objects with ``index``, ``sim_time`` (s), ``targets`` and ``others`` (annotations
  with ``track_id``, ``category``, ``bbox_xyxy`` pixel edges, ``lat``/``lon``);
- alerts: ``(alert, frame_index, t)``: a confirmed alert, the frame it was confirmed on and
  that frame's time (the same clock as ``sim_time``).

An alert is matched to the person whose box centre lies nearest its last pixel position, within
``match_px``, in the frame it was locked on (``alert.frame_index``); failing that (a swimmer
washed over by a wave has no box in that frame), to the person whose true position within
``window_s`` of the lock lies within ``max(match_m, 3 x the alert's error)`` of the alert's
position. Neither makes it a false alert, named after the distractor under it ("open water"
when none), unless it is an appliance alert (its class a life-saving appliance,
:mod:`sarmission.class_roles`) over a life-saving appliance: that is an appliance
found, counted apart. A person is *in view*
when a stretch of frames showing them (gaps up to ``max_gap_s``) lasts at least ``min_view_s``;
the time to alert runs from their first frame to the confirmation.

The geolocation error of a found person's alert is measured twice: as the alert went out (its
position at the confirmation) and as stored at the flight's end (``final``: alert id -> the
stored alert; a placed alert's position is refined as its target's fixes come in), each against
where the person was in the frame that position is of (``sent_frames`` and ``position_frames``:
alert id -> frame index, by default the lock's; people drift). Each time
the truth is also checked against the alert's own error: within twice its 1-sigma error is
where an honest estimate puts it about 95 % of the time.
"""

from __future__ import annotations

import bisect
import math
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sarmission.class_roles import role_of
from sarmission.evaluation.reliability import PROBABILITY_EDGES, reliability_table
from sarmission.geo.wgs84 import geodetic_to_ned

#: A detection is the person whose box centre is within this many pixels.
MATCH_PX = 24.0
#: Or whose true position is within this many metres (or 3 x the alert's error) ...
MATCH_M = 5.0
#: ... at a time within this many seconds of the lock.
WINDOW_S = 2.0


@dataclass
class FlightScore:
    """The figures of one flight (or a suite: :meth:`add`)."""

    flight_s: float = 0.0
    people_in_view: int = 0
    found: int = 0
    found_briefly_seen: int = 0
    alerts: int = 0
    false_alerts: int = 0
    duplicates: int = 0
    appliances_found: int = 0  # appliance alerts over a life-saving appliance
    false_on: Counter[str] = field(default_factory=Counter)
    time_to_alert_s: list[float] = field(default_factory=list)
    geo_error_m: list[float] = field(default_factory=list)  # as the alert went out
    geo_error_final_m: list[float] = field(default_factory=list)  # as stored at the flight's end
    # whether the truth lay within twice the alert's 1-sigma error, as it went out / at the end
    geo_within_2x: list[bool] = field(default_factory=list)
    geo_within_2x_final: list[bool] = field(default_factory=list)
    missed: list[str] = field(default_factory=list)
    # every candidate's track score and whether a person was under it (reliability)
    candidate_scores: list[float] = field(default_factory=list)
    candidate_right: list[bool] = field(default_factory=list)
    # every confirmed alert's calibrated confidence (when it had one) and whether a person was
    # under it
    alert_confidences: list[float] = field(default_factory=list)
    alert_right: list[bool] = field(default_factory=list)

    def add(self, other: FlightScore) -> None:
        """Fold another flight's figures into this one."""
        for name in (
            "flight_s",
            "people_in_view",
            "found",
            "found_briefly_seen",
            "alerts",
            "false_alerts",
            "duplicates",
            "appliances_found",
        ):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        self.false_on.update(other.false_on)
        self.time_to_alert_s += other.time_to_alert_s
        self.geo_error_m += other.geo_error_m
        self.geo_error_final_m += other.geo_error_final_m
        self.geo_within_2x += other.geo_within_2x
        self.geo_within_2x_final += other.geo_within_2x_final
        self.missed += other.missed
        self.candidate_scores += other.candidate_scores
        self.candidate_right += other.candidate_right
        self.alert_confidences += other.alert_confidences
        self.alert_right += other.alert_right

    @property
    def false_per_hour(self) -> float:
        return self.false_alerts / (self.flight_s / 3600.0) if self.flight_s > 0 else math.nan

    @property
    def found_share(self) -> float:
        return self.found / self.people_in_view if self.people_in_view else math.nan

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready figures (percentiles computed here)."""
        return {
            "flight_s": round(self.flight_s, 1),
            "people_in_view": self.people_in_view,
            "found": self.found,
            "found_share": _round(self.found_share, 4),
            "found_briefly_seen": self.found_briefly_seen,
            "alerts": self.alerts,
            "false_alerts": self.false_alerts,
            "false_per_hour": _round(self.false_per_hour, 2),
            "false_on": dict(self.false_on.most_common()),
            "duplicates": self.duplicates,
            "appliances_found": self.appliances_found,
            "time_to_alert_s": {
                "p50": _pct(self.time_to_alert_s, 50),
                "p90": _pct(self.time_to_alert_s, 90),
            },
            "geo_error_m": {"p50": _pct(self.geo_error_m, 50), "p95": _pct(self.geo_error_m, 95)},
            "geo_error_final_m": {
                "p50": _pct(self.geo_error_final_m, 50),
                "p95": _pct(self.geo_error_final_m, 95),
            },
            "geo_within_2x": {
                "at_alert": _share(self.geo_within_2x),
                "final": _share(self.geo_within_2x_final),
            },
            "missed": list(self.missed),
            "candidate_reliability": reliability_table(self.candidate_scores, self.candidate_right),
            "alert_confidence_reliability": reliability_table(
                self.alert_confidences, self.alert_right, PROBABILITY_EDGES
            ),
        }


def _round(v: float, digits: int) -> float | None:
    return None if math.isnan(v) else round(v, digits)


def _share(flags: Sequence[bool]) -> float | None:
    return None if not flags else round(sum(flags) / len(flags), 4)


def _pct(values: Sequence[float], q: float) -> float | None:
    return None if not values else round(float(np.percentile(values, q)), 2)


def _centre(box: Sequence[float]) -> tuple[float, float]:
    return (box[0] + box[2]) / 2 - 0.5, (box[1] + box[3]) / 2 - 0.5


def nearest(
    annotations: Iterable[Any], cx: float, cy: float, match_px: float = MATCH_PX
) -> Any | None:
    """The annotation whose box centre is nearest ``(cx, cy)`` within ``match_px``, or None."""
    best, best_d = None, match_px
    for a in annotations:
        x, y = _centre(a.bbox_xyxy)
        d = math.hypot(x - cx, y - cy)
        if d <= best_d:
            best, best_d = a, d
    return best


def _metres(a: tuple[float, float], b: tuple[float, float]) -> float:
    n, e, _ = geodetic_to_ned(a[0], a[1], 0.0, b[0], b[1], 0.0)
    return math.hypot(float(n), float(e))


def _by_position(
    frames: Sequence[Any], index: int, alert: Any, window_s: float, match_m: float
) -> Any | None:
    """The person nearest the alert's position, in the frames within ``window_s`` of its
    lock, if within ``max(match_m, 3 x error)``."""
    if alert.position is None:
        return None
    times = [f.sim_time for f in frames]  # frames come in capture order
    here = next((k for k, f in enumerate(frames) if f.index == index), None)
    if here is None:
        return None
    at = times[here]
    gate = max(match_m, 3.0 * (alert.error_m or 0.0))
    best, best_d = None, gate
    lo, hi = bisect.bisect_left(times, at - window_s), bisect.bisect_right(times, at + window_s)
    for frame in frames[lo:hi]:
        for a in frame.targets:
            if a.lat is None:
                continue
            d = _metres(alert.position, (a.lat, a.lon))
            if d <= best_d:
                best, best_d = a, d
    return best


def _views(frames: Sequence[Any], max_gap_s: float) -> tuple[dict[int, float], dict[int, float]]:
    """Per person: first sighting time and longest stretch in view (s)."""
    first: dict[int, float] = {}
    last: dict[int, float] = {}
    start: dict[int, float] = {}
    longest: dict[int, float] = {}
    for frame in frames:
        t = frame.sim_time
        for a in frame.targets:
            tid = a.track_id
            first.setdefault(tid, t)
            if tid not in last or t - last[tid] > max_gap_s:
                start[tid] = t
            last[tid] = t
            longest[tid] = max(longest.get(tid, 0.0), t - start[tid])
    return first, longest


def _person_at(
    by_index: Mapping[int, Any], track_id: int, frame_index: int
) -> tuple[float, float] | None:
    """Person ``track_id``'s true position in the frame nearest ``frame_index`` that shows
    them (a swimmer drifts: the position an alert was refined to is of its frame); searched
    outwards from that frame, the earlier one first at equal distance."""
    reach = max((abs(i - frame_index) for i in by_index), default=-1)
    for gap in range(reach + 1):
        for index in (frame_index - gap, frame_index + gap):
            frame = by_index.get(index)
            for a in frame.targets if frame is not None else ():
                if a.track_id == track_id and a.lat is not None:
                    return a.lat, a.lon
    return None


def _geo(errors: list[float], within: list[bool], alert: Any, truth: tuple[float, float]) -> None:
    """The alert's distance from the truth, and whether that is within twice its error."""
    err = _metres(alert.position, truth)
    errors.append(err)
    within.append(alert.error_m is not None and err <= 2.0 * alert.error_m)


def score_flight(
    frames: Sequence[Any],
    alerts: Sequence[tuple[Any, int, float]],
    min_view_s: float = 3.0,
    max_gap_s: float = 0.5,
    match_px: float = MATCH_PX,
    match_m: float = MATCH_M,
    window_s: float = WINDOW_S,
    candidates: Sequence[Any] = (),
    track_scores: dict[str, float] | None = None,
    final: Mapping[str, Any] | None = None,
    position_frames: Mapping[str, int] | None = None,
    sent_frames: Mapping[str, int] | None = None,
) -> FlightScore:
    """The figures of one flight (see the module docstring). ``candidates`` (every stored
    alert, confirmed or not) explain the misses (what became of a missed person's candidate,
    or that none was locked) and, with ``track_scores`` (alert id -> its track score; else its
    lock score), give the reliability of a candidate's score."""
    by_index = {f.index: f for f in frames}
    first, longest = _views(frames, max_gap_s)
    in_view = {tid for tid, s in longest.items() if s >= min_view_s}
    out = FlightScore(
        flight_s=(frames[-1].sim_time - frames[0].sim_time) if frames else 0.0,
        people_in_view=len(in_view),
        alerts=len(alerts),
    )
    found: set[int] = set()
    for alert, _confirm_index, confirm_t in alerts:
        frame = by_index.get(alert.frame_index)
        cx, cy = alert.pixel_track[-1][1:] if alert.pixel_track else (math.nan, math.nan)
        person = None if frame is None else nearest(frame.targets, cx, cy, match_px)
        if person is None:
            person = _by_position(frames, alert.frame_index, alert, window_s, match_m)
        if getattr(alert, "confidence", None) is not None:
            out.alert_confidences.append(alert.confidence)
            out.alert_right.append(person is not None)
        if person is None:
            other = None if frame is None else nearest(frame.others, cx, cy, match_px)
            if (
                other is not None
                and role_of(alert.class_name) == "appliance"
                and role_of(other.category) == "appliance"
            ):
                out.appliances_found += 1
                continue
            out.false_alerts += 1
            out.false_on[other.category if other is not None else "open water"] += 1
            continue
        if person.track_id in found:
            out.duplicates += 1
            continue
        found.add(person.track_id)
        out.time_to_alert_s.append(confirm_t - first[person.track_id])
        if person.lat is None:
            continue
        truth = (person.lat, person.lon)
        if alert.position is not None:
            frame_of = (sent_frames or {}).get(alert.alert_id, alert.frame_index)
            then = _person_at(by_index, person.track_id, frame_of) or truth
            _geo(out.geo_error_m, out.geo_within_2x, alert, then)
        last = (final or {}).get(alert.alert_id, alert)
        if last.position is not None:
            frame_of = (position_frames or {}).get(alert.alert_id, alert.frame_index)
            then = _person_at(by_index, person.track_id, frame_of) or truth
            _geo(out.geo_error_final_m, out.geo_within_2x_final, last, then)
    out.found = len(found & in_view)
    out.found_briefly_seen = len(found - in_view)
    fate: dict[int, str] = {}
    for candidate in candidates:
        frame = by_index.get(candidate.frame_index)
        cx, cy = candidate.pixel_track[-1][1:] if candidate.pixel_track else (math.nan, math.nan)
        person = None if frame is None else nearest(frame.targets, cx, cy, match_px)
        person = person or _by_position(frames, candidate.frame_index, candidate, window_s, match_m)
        out.candidate_scores.append((track_scores or {}).get(candidate.alert_id, candidate.score))
        out.candidate_right.append(person is not None)
        if person is not None and person.track_id not in found:
            why = (
                f"discarded: {candidate.discarded}" if candidate.discarded else "still unconfirmed"
            )
            fate.setdefault(person.track_id, why)
    out.missed = [
        f"person {tid} ({longest[tid]:.1f} s in view; {fate.get(tid, 'never locked')})"
        for tid in sorted(in_view - found)
    ]
    return out
