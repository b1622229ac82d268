"""How likely a confirmed alert is a person: the head's scores of a target turned into a
calibrated probability.

The head's score is no probability (the reliability tables of docs/alert_suite.md): an operator
reading "swimmer 0.86" over debris is misled. A :class:`ConfidenceModel` is a logistic
regression over the target's evidence, fitted on flights whose truth is known
(``tools/fit_confidence.py``, never the scored suite)::

    p = 1 / (1 + exp(-(bias + score_weight * logit(mean score)
                       + sum_c class_weights[c] * share of sightings called c)))

The mean score is clipped to [0.02, 0.98] before its logit, so one perfect crop does not make a
certainty. The class shares let a head's classes weigh differently (a life jacket is far more
telling than a dark blob called a swimmer). A model is fitted for one head: it names that
head's classes and is kept beside its files as ``<stem>.confidence.json``
(:func:`confidence_beside`). Every figure the model reads comes from the evidence the
confirmation already gathers (:mod:`sarmission.mission.confirmation`).

The share of people among confirmed alerts is a property of the scene's clutter: a model
fitted on the simulator ranks alerts but its level was badly wrong on held-out footage
(docs/confidence.md). So the confirmation stores the model's log-odds (:meth:`logit`), and
the alert store turns them into the confidence shown with the level the mission's operator
decisions teach (:mod:`sarmission.alerts.operator_calibration`).

The file is input like any other: a malformed one is refused with a one-line reason, and a
model fitted for other classes than the head's is not used (its numbers would mean nothing).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from sarmission.alerts.operator_calibration import MAX_LOGIT
from sarmission.errors import SarmissionError
from sarmission.mission.confirmation import Sighting

FORMAT = "sarmission.alert_confidence"
FORMAT_VERSION = 1
SUFFIX = ".confidence.json"
#: The mean score is clipped to this range before its logit (module docstring).
SCORE_CLIP = (0.02, 0.98)
#: Largest file read (a model is a few hundred bytes).
MAX_BYTES = 64 * 1024


class ConfidenceFileError(SarmissionError):
    """A confidence model file that cannot be used; the message says why in one line."""


def score_logit(mean_score: float) -> float:
    """``logit`` of the mean score clipped to :data:`SCORE_CLIP`."""
    p = min(max(mean_score, SCORE_CLIP[0]), SCORE_CLIP[1])
    return math.log(p / (1.0 - p))


def class_shares(sightings: Sequence[Sighting], names: Sequence[str]) -> list[float]:
    """Share of ``sightings`` the head called each class of ``names``."""
    n = len(sightings)
    return [sum(s.label == name for s in sightings) / n for name in names]


@dataclass(frozen=True)
class ConfidenceModel:
    """A fitted confidence (module docstring). ``classes``: the head's classes it was fitted
    for; ``class_weights``: the weight of the share of sightings called each class named (the
    others weigh 0); ``fitted_on``: what it was fitted on, for people reading the file."""

    classes: tuple[str, ...]
    bias: float
    score_weight: float
    class_weights: Mapping[str, float] = field(default_factory=dict)
    fitted_on: str = ""

    def __post_init__(self) -> None:
        numbers = [self.bias, self.score_weight, *self.class_weights.values()]
        if not all(isinstance(v, int | float) and math.isfinite(v) for v in numbers):
            raise ValueError("confidence weights must be finite numbers")
        unknown = sorted(set(self.class_weights) - set(self.classes))
        if unknown:
            raise ValueError(f"class weights for classes the head lacks: {', '.join(unknown)}")

    def features(self, sightings: Sequence[Sighting]) -> list[float]:
        """The model's inputs from ``sightings`` (non-empty): the mean score's logit, then each
        weighted class's share, in the order of ``class_weights``."""
        mean = float(np.mean([s.score for s in sightings]))
        return [score_logit(mean), *class_shares(sightings, list(self.class_weights))]

    def logit(self, sightings: Sequence[Sighting]) -> float | None:
        """The log-odds that a person is there (within ±:data:`MAX_LOGIT`), or None without
        sightings."""
        if not sightings:
            return None
        x = self.features(sightings)
        z = self.bias + self.score_weight * x[0]
        z += sum(w * v for w, v in zip(self.class_weights.values(), x[1:], strict=True))
        return min(max(z, -MAX_LOGIT), MAX_LOGIT)

    def probability(self, sightings: Sequence[Sighting]) -> float | None:
        """The probability that a person is there, or None without sightings."""
        z = self.logit(sightings)
        if z is None:
            return None
        return 1.0 / (1.0 + math.exp(-z)) if z > -700 else 0.0

    def to_json(self) -> str:
        """The file's text."""
        return json.dumps(
            {
                "format": FORMAT,
                "format_version": FORMAT_VERSION,
                "classes": list(self.classes),
                "bias": self.bias,
                "score_weight": self.score_weight,
                "class_weights": dict(self.class_weights),
                "fitted_on": self.fitted_on,
            },
            indent=2,
        )


def parse_confidence(text: str, origin: str = "confidence model") -> ConfidenceModel:
    """A model from its JSON text; :class:`ConfidenceFileError` (one line) when malformed."""
    try:
        doc = json.loads(text)
    except ValueError as exc:
        raise ConfidenceFileError(f"{origin}: not JSON ({exc})") from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ConfidenceFileError(f"{origin}: not a {FORMAT} file")
    if doc.get("format_version") != FORMAT_VERSION:
        raise ConfidenceFileError(
            f"{origin}: format version {doc.get('format_version')!r}, expected {FORMAT_VERSION}"
        )
    classes, weights = doc.get("classes"), doc.get("class_weights", {})
    if not isinstance(classes, list) or not all(isinstance(c, str) for c in classes):
        raise ConfidenceFileError(f"{origin}: 'classes' must be a list of class names")
    if not isinstance(weights, dict):
        raise ConfidenceFileError(f"{origin}: 'class_weights' must map class names to numbers")
    numbers = [doc.get("bias"), doc.get("score_weight"), *weights.values()]
    if not all(isinstance(v, int | float) and not isinstance(v, bool) for v in numbers):
        raise ConfidenceFileError(f"{origin}: 'bias', 'score_weight' and weights must be numbers")
    try:
        return ConfidenceModel(
            tuple(classes),
            float(doc["bias"]),
            float(doc["score_weight"]),
            {str(k): float(v) for k, v in weights.items()},
            str(doc.get("fitted_on", "")),
        )
    except ValueError as exc:
        raise ConfidenceFileError(f"{origin}: {exc}") from None


def load_confidence(path: str | Path) -> ConfidenceModel:
    """The model in ``path``; :class:`ConfidenceFileError` (one line) when it cannot be used."""
    path = Path(path)
    try:
        if path.stat().st_size > MAX_BYTES:
            raise ConfidenceFileError(f"{path}: larger than {MAX_BYTES} bytes")
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfidenceFileError(f"{path}: cannot be read ({exc})") from None
    return parse_confidence(text, str(path))


def confidence_beside(head_path: str | Path) -> Path:
    """Where the confidence model of the head in ``head_path`` (``.pt`` or ``.onnx``) is kept."""
    head_path = Path(head_path)
    return head_path.with_name(head_path.stem + SUFFIX)


def fit_confidence(
    samples: Sequence[tuple[Sequence[Sighting], bool]],
    classes: Sequence[str],
    weighted_classes: Sequence[str],
    l2: float = 0.1,
    fitted_on: str = "",
) -> ConfidenceModel:
    """Fit a model to ``samples`` (each target's sightings and whether a person was there) by
    L2-penalised maximum likelihood (the bias is not penalised). ``weighted_classes``: the
    classes whose share is an input. At least one person and one non-person are needed."""
    from scipy.optimize import minimize

    samples = [(s, bool(y)) for s, y in samples if len(s)]
    labels = np.array([y for _, y in samples], float)
    if labels.size == 0 or labels.min() == labels.max():
        raise ValueError("fitting needs targets with and without a person")
    probe = ConfidenceModel(tuple(classes), 0.0, 0.0, {c: 0.0 for c in weighted_classes})
    x = np.array([[1.0, *probe.features(s)] for s, _ in samples])

    def loss(w: np.ndarray) -> tuple[float, np.ndarray]:
        z = x @ w
        p = 1.0 / (1.0 + np.exp(-z))
        penalty = l2 * float(np.sum(w[1:] ** 2))
        grad = x.T @ (p - labels) + 2 * l2 * np.r_[0.0, w[1:]]
        return float(np.sum(np.logaddexp(0.0, z) - labels * z)) + penalty, grad

    w = minimize(loss, np.zeros(x.shape[1]), jac=True, method="BFGS").x
    return ConfidenceModel(
        tuple(classes),
        float(w[0]),
        float(w[1]),
        {c: float(v) for c, v in zip(weighted_classes, w[2:], strict=True)},
        fitted_on,
    )


class HeadConfidence(NamedTuple):
    """The model found for a head (None: none used), a line saying which or why none, and
    whether a file was there but refused (worth a warning)."""

    model: ConfidenceModel | None
    note: str
    refused: bool = False


def confidence_of_head(head: object) -> HeadConfidence:
    """The confidence model kept beside ``head``'s model file (a head runtime with a ``source``
    path and ``classes``; anything else has none). A file that cannot be used, or was fitted for
    other classes, is refused."""
    source = getattr(head, "source", None)
    if source is None:
        return HeadConfidence(None, "alert confidence: none (the head was not loaded from a file)")
    path = confidence_beside(source)
    if not path.is_file():
        name = Path(source).name
        return HeadConfidence(None, f"alert confidence: none fitted for {name} (its score only)")
    try:
        model = load_confidence(path)
    except ConfidenceFileError as exc:
        return HeadConfidence(None, f"alert confidence not used: {exc}", True)
    classes = tuple(getattr(head, "classes", ()))
    if model.classes != classes:
        return HeadConfidence(
            None,
            f"alert confidence not used: {path} was fitted for the classes "
            f"{', '.join(model.classes)}, the head has {', '.join(classes)}",
            True,
        )
    return HeadConfidence(
        model, f"alert confidence: {path.name}, its level learnt from the operator's decisions"
    )
