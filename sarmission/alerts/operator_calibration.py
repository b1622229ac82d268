"""What the operator's decisions teach about this mission's alerts: a confidence model's
offset, learnt as the mission goes.

A confidence model (:mod:`sarmission.mission.confidence`) turns a target's evidence into
log-odds ``z`` that a person is there. Fitted on the simulator, its ``z`` ranks alerts well but
its level does not carry: the share of people among confirmed alerts is the scene's
(docs/confidence.md). So the level is learnt per mission from the operator's decisions on its
earlier alerts: ``p = sigmoid(z + d)`` with one offset ``d``, a normal prior of standard
deviation :data:`PRIOR_SD` on it, and every decided alert as evidence (an operator's
confirmation: a person; a dismissal: none). The confidence shown is the posterior mean of ``p``
with its central :data:`INTERVAL` range: wide before the operator has decided anything, narrowing
as decisions come (docs/confidence_adaptation.md measured the prior on held-out footage).

The belief is a pure function of the decisions, so it lives wherever they do (the alert store)
and survives restarts with them.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import NamedTuple

import numpy as np

#: Standard deviation of the prior on the mission's offset (log-odds).
PRIOR_SD = 3.0
#: The quantiles of the confidence's range.
INTERVAL = (0.1, 0.9)
#: Largest log-odds a model may report (a fitted model's are a few units).
MAX_LOGIT = 50.0
#: The offsets the posterior is evaluated on: the prior's mass lies well within.
_GRID = np.linspace(-12.0, 12.0, 1201)


class Rating(NamedTuple):
    """An alert's confidence that a person is there: the posterior mean and its range."""

    confidence: float
    low: float
    high: float


def check_logit(value: float) -> float:
    """``value`` as a float; ValueError unless finite and within :data:`MAX_LOGIT`."""
    z = float(value)
    if not (math.isfinite(z) and abs(z) <= MAX_LOGIT):
        raise ValueError(f"evidence log-odds must be finite and within ±{MAX_LOGIT:g}, got {value}")
    return z


def _log_sigmoid(x: np.ndarray) -> np.ndarray:
    return -np.logaddexp(0.0, -x)


class OffsetBelief:
    """The posterior of the mission's offset given the operator's decisions (module
    docstring). ``decided``: ``(z, person)`` per decided alert."""

    def __init__(self, decided: Iterable[tuple[float, bool]], prior_sd: float = PRIOR_SD) -> None:
        if not prior_sd > 0:
            raise ValueError(f"prior standard deviation must be positive, got {prior_sd}")
        log_post = -0.5 * (_GRID / prior_sd) ** 2
        self.decisions = 0
        for z, person in decided:
            shifted = check_logit(z) + _GRID
            log_post += _log_sigmoid(shifted) if person else _log_sigmoid(-shifted)
            self.decisions += 1
        weights = np.exp(log_post - log_post.max())
        self._weights = weights / weights.sum()
        self._cdf = np.cumsum(self._weights)

    def rate(self, z: float) -> Rating:
        """The confidence for an alert whose evidence says log-odds ``z``."""
        p = 1.0 / (1.0 + np.exp(-(check_logit(z) + _GRID)))
        low, high = (float(p[min(np.searchsorted(self._cdf, q), len(p) - 1)]) for q in INTERVAL)
        mean = float(np.dot(self._weights, p))
        return Rating(mean, min(low, mean), max(high, mean))
