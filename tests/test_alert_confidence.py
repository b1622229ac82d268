"""The calibrated confidence of a confirmed alert (:mod:`sarmission.mission.confidence`): the
model's arithmetic, its fit, its file as untrusted input, the file kept beside a head, and the
confidence a confirmation stores and everyone is shown."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from alert_samples import make_alert

from sarmission.alerts.model import confidence_percent
from sarmission.alerts.store import AlertStore
from sarmission.mission.candidates import CandidateBook
from sarmission.mission.confidence import (
    ConfidenceFileError,
    ConfidenceModel,
    confidence_beside,
    confidence_of_head,
    fit_confidence,
    load_confidence,
    parse_confidence,
)
from sarmission.mission.config import ConfirmConfig
from sarmission.mission.confirmation import Sighting
from sarmission.mission.controller import format_alert

CLASSES = ("swimmer", "swimmer_with_life_jacket")
MODEL = ConfidenceModel(CLASSES, -4.0, 1.5, {"swimmer_with_life_jacket": 6.0})


def seen(scores, labels="swimmer", t0: float = 100.0) -> list[Sighting]:
    """Sightings 0.1 s apart at one place with ``scores`` and ``labels`` (one or per score)."""
    labels = [labels] * len(scores) if isinstance(labels, str) else labels
    return [
        Sighting(t0 + 0.1 * k, 54.17, 7.89, 1.0, 0.6, s, lab, 1)
        for k, (s, lab) in enumerate(zip(scores, labels, strict=True))
    ]


def test_the_probability_follows_the_formula():
    """Mean score 0.8 (logit ln 4), half the sightings in a life jacket."""
    sightings = seen([0.7, 0.9, 0.7, 0.9], ["swimmer", "swimmer_with_life_jacket"] * 2)
    z = -4.0 + 1.5 * math.log(4.0) + 6.0 * 0.5
    assert MODEL.probability(sightings) == pytest.approx(1 / (1 + math.exp(-z)))
    assert MODEL.probability([]) is None


def test_more_score_and_a_life_jacket_mean_more_likely():
    low, high = MODEL.probability(seen([0.6] * 5)), MODEL.probability(seen([0.9] * 5))
    jacket = MODEL.probability(seen([0.9] * 5, "swimmer_with_life_jacket"))
    assert low < high < jacket


def test_a_perfect_score_is_clipped_not_a_certainty():
    """Scores of 1.0 are taken as 0.98: finite, and below what a class share adds."""
    p = MODEL.probability(seen([1.0] * 5))
    assert p == pytest.approx(1 / (1 + math.exp(4.0 - 1.5 * math.log(0.98 / 0.02))))
    assert p < 1.0


def synthetic(rng: np.random.Generator, n: int = 400) -> list[tuple[list[Sighting], bool]]:
    """Targets whose truth follows a known model: bias -2, score weight 1, jacket share +4."""
    data = []
    for _ in range(n):
        mean = float(rng.uniform(0.5, 0.95))
        jacket = rng.random() < 0.3
        labels = ["swimmer_with_life_jacket" if jacket else "swimmer"] * 4
        sightings = seen([mean] * 4, labels)
        z = -2.0 + math.log(mean / (1 - mean)) + (4.0 if jacket else 0.0)
        data.append((sightings, bool(rng.random() < 1 / (1 + math.exp(-z)))))
    return data


def test_the_fit_recovers_the_model_that_made_the_data():
    data = synthetic(np.random.default_rng(3), 3000)
    model = fit_confidence(data, CLASSES, ["swimmer_with_life_jacket"], l2=0.01)
    assert model.bias == pytest.approx(-2.0, abs=0.4)
    assert model.score_weight == pytest.approx(1.0, abs=0.3)
    assert model.class_weights["swimmer_with_life_jacket"] == pytest.approx(4.0, abs=0.6)
    assert model.classes == CLASSES


def test_the_fit_needs_both_kinds_of_target():
    data = [(s, True) for s, _ in synthetic(np.random.default_rng(0), 20)]
    with pytest.raises(ValueError, match="with and without"):
        fit_confidence(data, CLASSES, [])


def test_a_model_survives_its_file():
    assert parse_confidence(MODEL.to_json()) == MODEL


def document(**changes) -> str:
    doc = json.loads(MODEL.to_json())
    doc.update(changes)
    return json.dumps(doc)


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("{not json", "not JSON"),
        ("[1, 2]", "not a sarmission.alert_confidence file"),
        (document(format="other"), "not a sarmission.alert_confidence file"),
        (document(format_version=2), "format version 2"),
        (document(bias="high"), "must be numbers"),
        (document(bias=True), "must be numbers"),
        (document(score_weight=None), "must be numbers"),
        (document(bias=float("nan")), "finite"),
        (document(class_weights={"boat": 1.0}), "classes the head lacks: boat"),
        (document(class_weights=[1.0]), "'class_weights' must map"),
        (document(classes="swimmer"), "'classes' must be a list"),
    ],
)
def test_a_bad_file_is_refused_in_one_line(text, why):
    with pytest.raises(ConfidenceFileError, match=why) as caught:
        parse_confidence(text, "m.confidence.json")
    assert "\n" not in str(caught.value) and str(caught.value).startswith("m.confidence.json")


def test_an_unreadable_or_huge_file_is_refused(tmp_path: Path):
    with pytest.raises(ConfidenceFileError, match="cannot be read"):
        load_confidence(tmp_path / "missing.confidence.json")
    huge = tmp_path / "huge.confidence.json"
    huge.write_text(" " * 70_000 + MODEL.to_json())
    with pytest.raises(ConfidenceFileError, match="larger than"):
        load_confidence(huge)


class Head:
    """A head runtime as far as the confidence asks: its file and its classes."""

    def __init__(self, source: Path | None, classes=CLASSES) -> None:
        self.source, self.classes = source, classes


def test_the_model_is_found_beside_its_head(tmp_path: Path):
    head = tmp_path / "my_head.onnx"
    assert confidence_beside(head) == tmp_path / "my_head.confidence.json"
    missing = confidence_of_head(Head(head))
    assert missing.model is None and not missing.refused and "none fitted" in missing.note
    assert confidence_of_head(Head(None)).model is None
    assert confidence_of_head(object()).model is None
    confidence_beside(head).write_text(MODEL.to_json())
    found = confidence_of_head(Head(head))
    assert found.model == MODEL and not found.refused


def test_a_model_for_other_classes_or_a_bad_file_is_not_used(tmp_path: Path):
    head = tmp_path / "land.pt"
    confidence_beside(head).write_text(MODEL.to_json())
    other = confidence_of_head(Head(head, ("person",)))
    assert other.model is None and other.refused and "fitted for the classes" in other.note
    confidence_beside(head).write_text("{")
    broken = confidence_of_head(Head(head))
    assert broken.model is None and broken.refused and "not JSON" in broken.note


RULE = ConfirmConfig(min_seen_s=1.0, min_sightings=5, min_seen_share=0.3, min_score=0.5)


def confirm_one(store: AlertStore, model: ConfidenceModel | None, labels: str) -> list:
    """A candidate seen 11 times over 1 s, reviewed once: the promotions."""
    book = CandidateBook(store, "test-mission", RULE, model)
    alert = make_alert(1, tier="candidate")
    store.add(alert)
    book.add(1, alert)
    for s in seen([0.8] * 11, labels):
        book.sighting(1, s.t, s.lat, s.lon, s.error_m, s.size_m, s.score, s.label, s.track_id)
    return book.review(101.1, when=1.7e9)


def test_a_confirmation_stores_its_confidence(tmp_path: Path):
    """The model's log-odds are stored; the confidence is what the mission's decisions (none
    yet) make of them: a wide range, shown as such in the console and the STATUSTEXT."""
    with AlertStore(tmp_path / "a.db") as store:
        (promotion,) = confirm_one(store, MODEL, "swimmer_with_life_jacket")
        z = MODEL.logit(seen([0.8] * 11, "swimmer_with_life_jacket"))
        assert promotion.alert.evidence_logit == pytest.approx(z)
        expected = store.rating("test-mission", z)
        assert promotion.alert.confidence == pytest.approx(expected.confidence)
        assert promotion.alert.confidence_range == pytest.approx((expected.low, expected.high))
        stored = store.get(promotion.alert.alert_id)
        assert (stored.confidence, stored.confidence_range) == (
            promotion.alert.confidence,
            promotion.alert.confidence_range,
        )
        low, mean, high = (confidence_percent(v) for v in (expected[1], expected[0], expected[2]))
        assert low < mean < high and high - low >= 20  # no decisions yet: a wide range
        line = format_alert(promotion.alert)
        assert f"({mean} % likely a person, between {low} and {high} %)" in line
        assert promotion.alert.statustext().split()[3] == f"{low}-{high}%"


def test_without_a_model_a_confirmation_shows_the_score(tmp_path: Path):
    with AlertStore(tmp_path / "a.db") as store:
        (promotion,) = confirm_one(store, None, "swimmer")
        assert promotion.alert.confidence is None
        assert "likely" not in format_alert(promotion.alert)
        assert promotion.alert.statustext().split()[3] == "0.91"


@pytest.mark.parametrize(("value", "shown"), [(0.001, 1), (0.35, 35), (0.999, 99)])
def test_the_percentage_is_never_a_certainty(value, shown):
    alert = make_alert(1, confidence=value)
    assert alert.format_confidence() == f"{shown} % likely a person"
    assert alert.to_json_dict()["confidence"] == value


def test_an_alert_refuses_an_impossible_confidence():
    for bad in (1.01, -0.5, float("nan")):
        with pytest.raises(ValueError, match="confidence"):
            make_alert(1, confidence=bad)


def test_the_extent_is_measured_every_few_sightings_until_the_candidate_is_decided(
    tmp_path: Path,
):
    from sarmission.mission.candidates import EXTENT_EVERY

    with AlertStore(tmp_path / "a.db") as store:
        book = CandidateBook(store, "test-mission", RULE)
        alert = make_alert(1, tier="candidate")
        store.add(alert)
        book.add(1, alert)
        wanted = []
        for s in seen([0.8] * 11):
            wanted.append(book.wants_extent(1))
            book.sighting(1, s.t, s.lat, s.lon, s.error_m, s.size_m, s.score, s.label, s.track_id)
        assert wanted == [i % EXTENT_EVERY == 0 for i in range(11)]
        assert book.wants_extent(2)  # a target not seen yet: its lock frame measures
        s = seen([0.8] * 12)[-1]
        book.sighting(1, s.t, s.lat, s.lon, s.error_m, s.size_m, s.score, s.label, s.track_id)
        assert len(book.evidence[1].sightings) % EXTENT_EVERY == 0 and book.wants_extent(1)
        (_,) = book.review(101.2, when=1.7e9)  # confirmed: its extent no longer matters
        assert not book.wants_extent(1)
