"""The RA variants' fits: the per-viewpoint evidence stacked over held-out groups, pooled
over the classes for ra_region."""

from __future__ import annotations

import numpy as np

from rapomdp.awareness.evidence import (
    Evidence,
)
from rapomdp.awareness.variants import fit_observation_models
from rapomdp.config import ObserveConfig
from rapomdp.geometry.viewsphere import fibonacci_directions


def test_viewpoint_evidence_is_stacked_on_other_groups_and_finds_a_bad_patch():
    from rapomdp.awareness.variants import fit_viewpoint_correctness, viewpoint_logit

    rng = np.random.default_rng(7)
    directions = fibonacci_directions(64, hemisphere=True)
    bad = directions[:, 0] > 0.5  # the classifier fails on class 0 seen from +x
    labels = np.repeat([0, 1], 4)
    p_right = np.where(bad[None] & (labels[:, None] == 0), 0.2, 0.9)
    right = rng.random(p_right.shape) < p_right
    predicted = np.where(right, labels[:, None], 1 - labels[:, None])
    logit = viewpoint_logit(labels, predicted, 2, directions)
    assert logit[0, bad].mean() < 0.0 < logit[0, ~bad].mean()  # centred over the viewpoints
    assert logit[0, ~bad].mean() - logit[0, bad].mean() > 1.2  # smoothed, still apart
    assert np.allclose(logit.mean(axis=1), 0.0)
    assert abs(logit[1, bad].mean() - logit[1, ~bad].mean()) < 0.6
    evidence = Evidence(labels, predicted, np.tile(np.arange(4), 2))
    flat = np.full((2, 64), 0.5)  # a score that says nothing
    fused = fit_viewpoint_correctness(evidence, flat, 2, directions)
    assert fused is not None and fused.weights[1] > 0.5
    assert fused.correct[0, bad].mean() < 0.45 < 0.75 < fused.correct[0, ~bad].mean()
    single = Evidence(labels, predicted, np.zeros(8, np.int64))
    assert fit_viewpoint_correctness(single, flat, 2, directions) is None


def test_region_evidence_pools_the_classes_and_finds_a_patch_bad_for_every_class():
    """A patch of viewpoints bad for every class, two objects a class: the pooled term sees it
    on every object and gives it the same logit for each class; the per-class term, counted on
    each class's own objects, is noisier there."""
    from rapomdp.awareness.variants import (
        REGION_METHOD,
        fit_viewpoint_correctness,
        viewpoint_logit,
    )

    rng = np.random.default_rng(11)
    directions = fibonacci_directions(64, hemisphere=True)
    bad = directions[:, 2] > 0.7  # looking down: bad for every class
    classes = 6
    labels = np.repeat(np.arange(classes), 3)
    p_right = np.where(bad[None], 0.25, 0.8) * np.ones((labels.size, 1))
    right = rng.random(p_right.shape) < p_right
    predicted = np.where(right, labels[:, None], (labels[:, None] + 1) % classes)
    pooled = viewpoint_logit(labels, predicted, classes, directions, pooled=True)
    assert pooled.shape == (classes, 64)
    assert np.allclose(pooled, pooled[0])  # one row shared by every class
    assert abs(pooled.mean()) < 1e-9  # centred: which views are harder, not how hard
    assert pooled[0, ~bad].mean() - pooled[0, bad].mean() > 1.0
    per_class = viewpoint_logit(labels, predicted, classes, directions)
    truth = np.log(np.where(bad, 0.25, 0.8) / (1 - np.where(bad, 0.25, 0.8)))
    shape = truth - truth.mean()
    assert np.abs(pooled - shape).mean() < np.abs(
        per_class - per_class.mean(axis=1, keepdims=True) - shape).mean()
    evidence = Evidence(labels, predicted, np.tile(np.arange(3), classes))
    flat = np.full((classes, 64), 0.5)
    fused = fit_viewpoint_correctness(evidence, flat, classes, directions, pooled=True)
    assert fused is not None and fused.method == REGION_METHOD and fused.weights[1] > 0.5
    assert fused.correct[:, bad].mean() < 0.42 < 0.7 < fused.correct[:, ~bad].mean()
    models = fit_observation_models(evidence, {"mean": flat, "area": flat},
                                    [str(c) for c in range(classes)], ObserveConfig(), directions)
    diagonal = models["ra_region"].probabilities[:, np.arange(classes), np.arange(classes)]
    assert diagonal[bad].mean() < 0.42 < 0.7 < diagonal[~bad].mean()  # (V, C) P(correct)
    assert abs(models["ra_class"].probabilities[bad].mean()
               - models["ra_class"].probabilities[~bad].mean()) < 1e-9  # flat score: no region


def test_region_weight_is_not_misled_by_the_held_out_groups_levels():
    """Groups of objects far apart in accuracy (0.35 / 0.6 / 0.75), a mild region shared by
    all: the other groups' level falls as the held-out group's rises, which an uncentred term
    would fit as a falling weight; the centred one finds the region."""
    from rapomdp.awareness.variants import fit_viewpoint_correctness

    rng = np.random.default_rng(5)
    directions = fibonacci_directions(64, hemisphere=True)
    bad = directions[:, 2] > 0.7
    classes, groups = 6, np.tile(np.arange(3), 6)
    labels = np.repeat(np.arange(classes), 3)
    level = np.array([-0.6, 0.4, 1.1])[groups][:, None]
    p_right = 1.0 / (1.0 + np.exp(-(level - 0.8 * bad[None])))
    right = rng.random(p_right.shape) < p_right
    predicted = np.where(right, labels[:, None], (labels[:, None] + 1) % classes)
    fused = fit_viewpoint_correctness(Evidence(labels, predicted, groups),
                                      np.full((classes, 64), 0.5), classes, directions,
                                      pooled=True)
    assert fused is not None and fused.weights[1] > 0.3
    assert fused.correct[:, bad].mean() < fused.correct[:, ~bad].mean() - 0.08


