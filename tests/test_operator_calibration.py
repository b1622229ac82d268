"""The mission's calibration learnt from the operator's decisions: the offset's posterior, and
the store rating alerts with it, rating them again as decisions come, across restarts."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from alert_samples import make_alert
from test_feed_decisions import decide
from test_feed_server import get

from sarmission.alerts.feed import FeedServer
from sarmission.alerts.operator_calibration import PRIOR_SD, OffsetBelief, check_logit
from sarmission.alerts.store import AlertStore


def sigmoid(x: float) -> float:
    return 1.0 / (1.0 + math.exp(-x))


def test_without_decisions_the_rating_is_the_prior_and_wide():
    belief = OffsetBelief([])
    assert belief.decisions == 0
    even = belief.rate(0.0)
    assert even.confidence == pytest.approx(0.5, abs=1e-6)
    assert even.low == pytest.approx(1 - even.high, abs=1e-6)
    # the prior's 10-90 % range of the offset: ±1.28 standard deviations
    assert even.high == pytest.approx(sigmoid(1.2816 * PRIOR_SD), abs=0.01)
    doubtful = belief.rate(-3.0)
    assert doubtful.low < sigmoid(-3.0) < doubtful.confidence < 0.5 < doubtful.high


@pytest.mark.parametrize("offset", [-2.0, 0.0, 2.5])
def test_the_decisions_teach_the_offset(offset: float):
    """Decisions drawn from p = sigmoid(z + offset): after 300 of them the rating of any z
    is the true probability, within a narrow range that holds it."""
    rng = np.random.default_rng(7)
    zs = rng.uniform(-4.0, 2.0, 300)
    people = rng.random(300) < 1.0 / (1.0 + np.exp(-(zs + offset)))
    belief = OffsetBelief(zip(zs.tolist(), people.tolist(), strict=True))
    assert belief.decisions == 300
    for z in (-3.0, -1.0, 1.0):
        rated = belief.rate(z)
        truth = sigmoid(z + offset)
        assert rated.confidence == pytest.approx(truth, abs=0.06)
        assert rated.low - 0.02 <= truth <= rated.high + 0.02
        assert rated.high - rated.low < 0.2


def test_the_range_narrows_as_decisions_come():
    widths = []
    for n in (0, 2, 8, 32):
        rated = OffsetBelief([(-2.0, True), (-2.0, False)] * (n // 2)).rate(-2.0)
        widths.append(rated.high - rated.low)
    assert widths == sorted(widths, reverse=True) and widths[0] > 3 * widths[-1]


def test_bad_log_odds_and_priors_are_refused():
    for bad in (float("nan"), float("inf"), 51.0, -1e9):
        with pytest.raises(ValueError, match="log-odds"):
            check_logit(bad)
        with pytest.raises(ValueError, match="log-odds"):
            OffsetBelief([(bad, True)])
    with pytest.raises(ValueError, match="prior"):
        OffsetBelief([], prior_sd=0.0)


def rated_alerts(store: AlertStore, n: int, z: float = -2.0, mission: str = "m1") -> list[str]:
    """``n`` candidates of ``mission`` confirmed by the system with evidence log-odds ``z``."""
    ids = []
    for k in range(n):
        alert = make_alert(100 * len(mission) + k, tier="candidate", mission_id=mission)
        store.add(alert)
        store.promote(alert.alert_id, "held 3 s", 1.7e9 + k, z)
        ids.append(alert.alert_id)
    return ids


def test_a_decision_rates_the_undecided_alerts_again(tmp_path: Path):
    with AlertStore(tmp_path / "a.db") as store:
        first, second, third = rated_alerts(store, 3)
        other_mission = rated_alerts(store, 1, mission="m2")[0]
        before = store.get(third).confidence
        assert before == pytest.approx(store.rating("m1", -2.0).confidence)
        seq = store.last_event_seq()
        store.decide(first, "confirmed", "ana")
        rated = [e for e in store.events(seq) if e.kind == "rated"]
        assert sorted(e.alert.alert_id for e in rated) == sorted([second, third])
        assert "after 1 operator decision" in rated[0].detail
        up = store.get(third)
        assert up.confidence > before
        assert up.confidence_range[0] > store.get(other_mission).confidence_range[0]
        assert store.get(first).confidence == pytest.approx(before)  # the decided one stays
        assert store.get(other_mission).confidence == pytest.approx(before)  # its own mission
        store.decide(second, "dismissed", "bo")
        down = store.get(third)
        assert down.confidence < up.confidence
        store.decide(second, "confirmed", "bo")  # a change of mind counts as it stands
        assert store.get(third).confidence == pytest.approx(
            OffsetBelief([(-2.0, True), (-2.0, True)]).rate(-2.0).confidence
        )


def test_a_decision_on_an_unrated_alert_rates_nothing(tmp_path: Path):
    with AlertStore(tmp_path / "a.db") as store:
        (rated,) = rated_alerts(store, 1)
        unrated = make_alert(5, tier="candidate", mission_id="m1")
        store.add(unrated)
        store.promote(unrated.alert_id, "held 3 s")
        seq = store.last_event_seq()
        store.decide(unrated.alert_id, "dismissed", "ana")
        assert [e.kind for e in store.events(seq)] == ["decided"]
        assert store.get(rated).confidence == pytest.approx(store.rating("m1", -2.0).confidence)


def test_the_calibration_survives_a_restart(tmp_path: Path):
    """What the operator taught is in the decisions, so a reopened store rates a new alert
    with it."""
    db = tmp_path / "a.db"
    with AlertStore(db) as store:
        for alert_id in rated_alerts(store, 6):
            store.decide(alert_id, "confirmed", "ana")
        taught = store.rating("m1", -2.0)
    with AlertStore(db) as store:
        assert store.rating("m1", -2.0) == taught
        late = make_alert(77, tier="candidate", mission_id="m1")
        store.add(late)
        promoted = store.promote(late.alert_id, "held 3 s", 1.8e9, -2.0)
        assert promoted.confidence == pytest.approx(taught.confidence)
        assert promoted.confidence > OffsetBelief([]).rate(-2.0).confidence + 0.3


def test_the_feed_shows_the_alerts_rated_again(tmp_path: Path):
    """An operator's confirmation through the feed's HTTP route rates the mission's other
    alerts, and the feed serves the new confidence with its range."""
    with AlertStore(tmp_path / "a.db") as store, FeedServer(store, port=0) as feed:
        first, second = rated_alerts(store, 2)
        status, _ = decide(feed, first, "confirm")
        assert status == 200
        status, _, raw = get(feed, f"/api/alerts/{second}")
        assert status == 200
        body = json.loads(raw)
        shown = store.get(second)
        assert body["confidence"] == pytest.approx(shown.confidence)
        assert body["confidence_range"] == pytest.approx(list(shown.confidence_range))
        assert shown.confidence > OffsetBelief([]).rate(-2.0).confidence
