"""Candidates and their promotion: what a lock becomes before anyone is told it is a person.

A frame-level lock stores a *candidate* alert: the operator sees it ("unconfirmed"), the
autopilot and the team do not. :class:`CandidateBook` gathers each candidate's sightings and,
every frame, asks :func:`~sarmission.mission.confirmation.assess` for a verdict: ``confirm``
promotes it in the store (durable first), and only then is it announced; ``discard`` records
the reason. The operator's own decisions, taken in the feed and written to the same store, are
read back from its event log: an operator's confirmation announces a candidate at once, a
dismissal adds a zone in which new locks stay silent (:meth:`CandidateBook.suppressing`),
also after a restart (the zones are read from the store).
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass

from sarmission.alerts.model import Alert
from sarmission.alerts.store import AlertStore
from sarmission.geo.wgs84 import geodetic_to_ned
from sarmission.mission.confidence import ConfidenceModel
from sarmission.mission.config import ConfirmConfig
from sarmission.mission.confirmation import (
    Assessment,
    Sighting,
    TargetEvidence,
    assess,
    frames_seen,
)

log = logging.getLogger(__name__)

#: A candidate's extent is measured on every this-many placed sightings.
EXTENT_EVERY = 3


@dataclass(frozen=True)
class Promotion:
    """A candidate the evidence (or an operator) confirmed: announce it."""

    alert: Alert
    assessment: Assessment | None  # None: the operator confirmed it


class CandidateBook:
    """The mission's candidates, their evidence and the dismissed zones (one controller owns
    it; the store is shared with the feed)."""

    def __init__(
        self,
        store: AlertStore,
        mission_id: str,
        rule: ConfirmConfig,
        confidence: ConfidenceModel | None = None,
    ) -> None:
        self.store = store
        self.mission_id = mission_id
        self.rule = rule
        self.confidence = confidence  # None: confirmations carry no calibrated confidence
        self.evidence: dict[int, TargetEvidence] = {}
        self.decided: set[int] = set()  # targets whose candidate was confirmed or discarded
        self.discarded: Counter[str] = Counter()
        self.suppressed = 0
        self.zones = list(store.dismissed_zones(mission_id))
        # candidates an earlier run left undecided: new sightings of them count on
        self.candidates: dict[int, Alert] = {
            a.target_id: a for a in store.pending_candidates(mission_id)
        }
        self._seen_event = store.last_event_seq()

    # -- evidence ----------------------------------------------------------------------------
    def sighting(
        self,
        target_id: int,
        t: float,
        lat: float | None,
        lon: float | None,
        error_m: float | None,
        size_m: float | None,
        score: float,
        label: str = "",
        track_id: int | None = None,
        extent_m: float | None = None,
        look_change: float | None = None,
    ) -> None:
        """One frame's sighting of a target (``lat`` None: no fix this frame; ``label`` the
        head's class for it, empty when unknown; ``track_id`` the track that saw it;
        ``extent_m`` the object's size against its surroundings and ``look_change`` how much
        its look changed over about a second, None when not measured)."""
        evidence = self.evidence.setdefault(target_id, TargetEvidence())
        if lat is None or lon is None or error_m is None:
            evidence.note_unplaced(t)
        else:
            evidence.add(
                Sighting(
                    t, lat, lon, error_m, size_m, score, label, track_id, extent_m, look_change
                )
            )

    def wants_extent(self, target_id: int) -> bool:
        """Whether this sighting of ``target_id`` should measure the object's extent: only
        while its candidate is undecided, on every :data:`EXTENT_EVERY`-th placed sighting (a
        measurement costs about a millisecond; the median of a few is what counts)."""
        if target_id in self.decided:
            return False
        evidence = self.evidence.get(target_id)
        return evidence is None or len(evidence.sightings) % EXTENT_EVERY == 0

    def forget(self, target_id: int, track_id: int) -> None:
        """Drop ``track_id``'s sightings from ``target_id``'s evidence (the registry took the
        track back out of that target)."""
        evidence = self.evidence.get(target_id)
        if evidence is not None:
            evidence.forget(track_id)

    def suppressing(
        self, position: tuple[float, float] | None
    ) -> tuple[float, float, float] | None:
        """The dismissed zone ``position`` lies in, if any."""
        if position is None:
            return None
        for zone in self.zones:
            n, e, _ = geodetic_to_ned(position[0], position[1], 0.0, zone[0], zone[1], 0.0)
            if math.hypot(float(n), float(e)) <= zone[2]:
                return zone
        return None

    def add(self, target_id: int, alert: Alert) -> None:
        """A new candidate (already stored by the caller)."""
        self.candidates[target_id] = alert

    # -- verdicts ----------------------------------------------------------------------------
    def review(
        self,
        now: float,
        when: float | None = None,
        prepare: Callable[[Alert], None] | None = None,
    ) -> list[Promotion]:
        """Count this processed frame for every candidate, assess each at time ``now``; returns
        those confirmed now (promoted in the store first). Discarded ones are recorded and
        forgotten. ``when``: ``now`` as POSIX seconds for the store (default: the wall clock;
        a replay gives the footage's time, so that a confirmation and its lock share a clock).
        ``prepare`` is called with each candidate the evidence confirms just before it is
        promoted (the controller places it at its target's position then, so that the
        confirmation is stored and streamed with it)."""
        promoted = []
        for target_id in self.candidates:
            if target_id in self.evidence:
                frames_seen(self.evidence[target_id])
        for target_id, alert in list(self.candidates.items()):
            found = assess(self.evidence.get(target_id, TargetEvidence()), now, self.rule)
            if found.verdict == "wait":
                continue
            del self.candidates[target_id]
            self.decided.add(target_id)
            if found.verdict == "confirm":
                if prepare is not None:
                    prepare(alert)
                evidence_logit = (
                    None
                    if self.confidence is None
                    else self.confidence.logit(self.evidence[target_id].sightings)
                )
                stored = self.store.promote(alert.alert_id, found.summary(), when, evidence_logit)
                if stored is None:  # dismissed by the operator meanwhile: stays silent
                    log.info(
                        "target %d confirmed by evidence but dismissed by the operator", target_id
                    )
                    continue
                promoted.append(Promotion(stored, found))
            else:
                self.store.discard(alert.alert_id, found.reason, when)
                self.discarded[_kind(found.reason)] += 1
                log.info("candidate target %d discarded: %s", target_id, found.reason)
        return promoted

    def operator_decisions(self) -> list[Promotion]:
        """Read the operator's decisions stored since the last call: dismissals become zones,
        confirmations of candidates are returned to be announced."""
        promoted = []
        for event in self.store.events(after=self._seen_event):
            self._seen_event = max(self._seen_event, event.seq)
            if event.kind != "decided":
                continue
            alert = self.store.get(event.alert.alert_id)  # as it is now, not at the event
            if alert is None or alert.mission_id != self.mission_id:
                continue
            if alert.decision == "dismissed":
                self.zones = list(self.store.dismissed_zones(self.mission_id))
                if self.candidates.pop(alert.target_id, None):
                    self.decided.add(alert.target_id)
            elif alert.decision == "confirmed" and self.candidates.pop(alert.target_id, None):
                self.decided.add(alert.target_id)
                promoted.append(Promotion(alert, None))
        return promoted


def _kind(reason: str) -> str:
    """A discard reason without its figures, for counting."""
    for word in ("no person", "moves", "score", "called", "not confirmed", "never placed"):
        if word in reason:
            return word
    return reason
