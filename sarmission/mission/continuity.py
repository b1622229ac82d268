"""Which tracks' fixes may place an alert, and how far apart a target's tracks lie.

The registry (:mod:`sarmission.mission.targets`) joins a new track to a target seen a while ago
when its fix lies within the target's gate: the person found again. At an oblique view two
people a few metres apart, seen one after the other, pass that gate too, as do sun glints and
foam where a person was. Their fixes would then move the alert: to the other person, with the
tight error of one person's fixes. So:

- a track *continues* its target at once when it joined moments after the target was last
  seen (within :data:`~sarmission.mission.targets.CONCURRENT_S`, where the registry compares
  boxes in the image) or when it started the target;
- any other track that joined (not by the loose re-find radius) continues it once it has a
  confirmation's evidence of its own (``min_fixes`` fixes over ``min_span_s``): a glint seen for
  a few frames never moves an alert;
- at that moment its first fixes are compared with the target's trajectory before it joined
  (:func:`~sarmission.mission.position_estimate.latest_position` of both, the earlier one carried
  forward by its drift). Within ``GATE_SIGMA`` times the track's own error they agree; beyond
  it, the distance is the track's ``jump_m``: the same person who moved (or whose earlier fixes
  were poorer than their error said), or someone else. The gate does not widen with the
  earlier trajectory's uncertainty: a drift carried over a long gap admits another swimmer or
  debris as easily as the person, and only the image could tell them apart. The jump stays
  with the target: its positions carry it in their error (:func:`ambiguity_m`), since nothing
  seen later tells the two cases apart. The price is a wider error for some people found
  again after they moved.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence

from sarmission.mission.confirmation import Sighting
from sarmission.mission.position_estimate import WINDOW_S, latest_position
from sarmission.mission.targets import CONCURRENT_S, GATE_SIGMA, Target, TrackShare, offset_m


def _time(sighting: Sighting) -> float:
    return sighting.t


def continues(share: TrackShare) -> bool:
    """Whether the track of ``share`` may place its target (see the module docstring)."""
    if share.loose:
        return False
    return share.gap_s <= CONCURRENT_S or share.jump_m is not None


def ambiguity_m(target: Target) -> float:
    """The largest jump of the tracks that continue ``target`` (0: they agree)."""
    return max(
        (s.jump_m or 0.0 for s in target.shares.values() if continues(s)),
        default=0.0,
    )


def placing(target: Target, sightings: Sequence[Sighting]) -> list[Sighting]:
    """``sightings`` of tracks that continue ``target`` (and those of no known track)."""
    shares = target.shares
    return [
        s
        for s in sightings
        if s.track_id is None or (s.track_id in shares and continues(shares[s.track_id]))
    ]


def check(
    target: Target,
    track_id: int,
    sightings: Sequence[Sighting],
    min_fixes: int,
    min_span_s: float,
) -> float | None:
    """Compare ``track_id``'s first fixes with ``target``'s before it joined, once the track
    has ``min_fixes`` fixes over ``min_span_s`` (``sightings``: the target's, in time order);
    sets and returns the share's jump (None: not due, or already done)."""
    share = target.shares.get(track_id)
    if share is None or share.loose or continues(share):  # compared already, or no need
        return None
    if share.fixes < min_fixes or not share.last_fix:
        return None
    if share.last_fix[3] - share.first_fix_t < min_span_s:
        return None
    start = bisect.bisect_left(sightings, share.joined, key=_time)
    before = placing(target, sightings[:start])
    own = [s for s in sightings[start:] if s.track_id == track_id]
    share.jump_m = jump_m(before, own, min_fixes, min_span_s)
    return share.jump_m


def jump_m(
    before: Sequence[Sighting],
    own: Sequence[Sighting],
    min_fixes: int,
    min_span_s: float,
) -> float:
    """How far the first fixes of ``own`` (as many as ``min_fixes`` over ``min_span_s``) lie
    from the trajectory of the latest :data:`WINDOW_S` of ``before``, carried forward to their
    time (a followed drift); 0 within ``GATE_SIGMA`` times their own error, or without fixes on
    either side. The gate leaves out the earlier trajectory's error on purpose: a track that
    lies measurably away from where the target should be fits it only if nothing else is
    near, which the fixes cannot tell (see the module docstring)."""
    if not before or not own:
        return 0.0
    end = next(
        (i + 1 for i, s in enumerate(own) if i + 1 >= min_fixes and s.t - own[0].t >= min_span_s),
        len(own),
    )
    window = before[bisect.bisect_left(before, before[-1].t - WINDOW_S, key=_time) :]
    earlier = latest_position(window, window_s=math.inf)
    later = latest_position(own[:end], window_s=math.inf)
    if earlier is None or later is None:
        return 0.0
    ahead = later.t - earlier.t
    north, east = offset_m(earlier.position, later.position)
    d = math.hypot(north - earlier.velocity_ne[0] * ahead, east - earlier.velocity_ne[1] * ahead)
    return d if d > GATE_SIGMA * later.error_m else 0.0
