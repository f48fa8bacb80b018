"""Self-awareness quality: AUC, and the scores that rank observation models."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.awareness.observation import (
    BlackBoxObservationModel,
    RAObservationModel,
    calibrate_correctness,
    wrong_label_distribution,
)
from rapomdp.awareness.quality import awareness_quality, roc_auc
from tests.awareness.test_observation import CLASSES, synthetic


def test_auc_matches_pairwise_counting():
    rng = np.random.default_rng(1)
    s = rng.integers(0, 5, 60).astype(float)
    y = rng.random(60) < 0.5
    pairs = [(1.0 if a > b else 0.5 if a == b else 0.0) for a in s[y] for b in s[~y]]
    assert roc_auc(s, y) == pytest.approx(np.mean(pairs))
    assert np.isnan(roc_auc(s, np.ones(60, bool)))


def test_quality_prefers_the_model_that_knows_when_it_is_right():
    scores, correct, predicted = synthetic(views=200)
    true = np.arange(3)
    wrong = wrong_label_distribution(np.repeat(true, 200), predicted, 3, 1.0)
    ra = RAObservationModel(scores, calibrate_correctness(scores, correct), wrong, CLASSES)
    blind = BlackBoxObservationModel(true, predicted, CLASSES, 1.0)
    good, flat = awareness_quality(ra, true, predicted), awareness_quality(blind, true, predicted)
    assert good["auc"] > 0.7 and good["brier"] < flat["brier"]
    assert good["log_likelihood"] > flat["log_likelihood"]
    assert good["accuracy"] == pytest.approx(correct.mean())
