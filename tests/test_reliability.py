"""Reliability tables: bins, means and shares counted by hand; a calibrated score has ECE near
zero, an over-confident one does not; eval's report carries the table."""

import numpy as np
import pytest

from sarmission.evaluation.reliability import format_reliability, reliability_table


def test_bins_means_shares_and_ece_by_hand():
    scores = [0.55, 0.58, 0.91, 0.93, 0.97, 0.99]
    correct = [False, True, True, True, False, True]
    table = reliability_table(scores, correct, edges=(0.0, 0.5, 0.9, 0.95, 1.0))
    assert [(b["low"], b["n"]) for b in table["bins"]] == [(0.5, 2), (0.9, 2), (0.95, 2)]
    assert table["bins"][0]["mean_score"] == pytest.approx(0.565)
    assert table["bins"][0]["share_correct"] == pytest.approx(0.5)
    assert table["bins"][2]["share_correct"] == pytest.approx(0.5)
    expected = (2 * abs(0.565 - 0.5) + 2 * abs(0.92 - 1.0) + 2 * abs(0.98 - 0.5)) / 6
    assert table["ece"] == pytest.approx(expected, abs=1e-4)
    assert "expected calibration error: 0.208" in format_reliability(table)[-1]


def test_a_calibrated_score_has_a_small_ece_an_overconfident_one_a_large():
    rng = np.random.default_rng(0)
    p = rng.uniform(0, 1, 20000)
    calibrated = reliability_table(p, rng.uniform(0, 1, p.size) < p)
    overconfident = reliability_table(np.sqrt(p), rng.uniform(0, 1, p.size) < p)
    assert calibrated["ece"] < 0.02 < 0.1 < overconfident["ece"]


def test_mismatched_lengths_are_refused():
    with pytest.raises(ValueError, match="3 scores but 2 outcomes"):
        reliability_table([0.1, 0.2, 0.3], [True, False])
