"""Held-out fitting: planted calibration curves, the RA variants' fits, ra_transfer's kernel,
the mixture and the wrong labels' shrinkage."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.awareness.evidence import (
    MIN_HELD_OUT_OBJECTS,
    Evidence,
    recorded_evidence,
    recorded_scores,
    validation_quality,
)
from rapomdp.awareness.mixture import (
    ROBUST_RA_VARIANT,
    choose_ra_variant,
    fit_mixture_weights,
    ra_mixture_folds,
)
from rapomdp.awareness.observation import (
    ObservationModel,
    calibrate_correctness,
    calibrate_per_class,
)
from rapomdp.awareness.shrinkage import (
    WRONG_LABEL_SHRINKAGES,
    choose_wrong_label_shrinkage,
    shrink_wrong_labels,
)
from rapomdp.awareness.transfer import (
    DEFAULT_TRANSFER_KERNEL,
    TRANSFER_KERNEL_GRID,
    TRANSFER_PRIOR,
    TransferKernel,
    choose_transfer_kernel,
    recorded_transfer_kernel,
    salient_view_similarity,
    transfer_confusion,
)
from rapomdp.awareness.variants import fit_observation_models, leave_one_group_out
from rapomdp.config import ObserveConfig
from rapomdp.geometry.viewsphere import fibonacci_directions


def _sigmoid(z: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-z))


def test_logistic_calibration_recovers_a_planted_curve():
    rng = np.random.default_rng(0)
    s = rng.random(40_000)
    correct = rng.random(s.size) < _sigmoid(-1.0 + 3.0 * s)
    fit = calibrate_correctness(s, correct, "logistic")
    assert fit.intercept == pytest.approx(-1.0, abs=0.08)
    assert fit.slope == pytest.approx(3.0, abs=0.15)
    grid = np.linspace(0, 1, 11)
    assert np.max(np.abs(fit(grid) - _sigmoid(-1.0 + 3.0 * grid))) < 0.02


def test_isotonic_calibration_recovers_a_planted_step():
    rng = np.random.default_rng(1)
    s = rng.random(20_000)
    truth = np.where(s < 0.5, 0.3, 0.9)
    fit = calibrate_correctness(s, rng.random(s.size) < truth, "isotonic")
    assert np.abs(fit(np.array([0.2, 0.8])) - [0.3, 0.9]).max() < 0.03
    assert np.all(np.diff(fit(np.linspace(0, 1, 50))) >= 0)


def test_per_class_calibration_recovers_intercepts_and_the_shared_slope():
    rng = np.random.default_rng(2)
    intercepts = np.array([-1.5, 0.0, 1.0])
    g = rng.integers(0, 3, 60_000)
    s = rng.random(g.size)
    correct = rng.random(g.size) < _sigmoid(intercepts[g] + 2.0 * s)
    fit = calibrate_per_class(s, correct, g, 3)
    assert np.abs(fit.intercepts - intercepts).max() < 0.12
    assert fit.slope == pytest.approx(2.0, abs=0.15)


def test_held_out_validation_prefers_the_score_that_predicts_correctness():
    """Planted: class 0 is right where its 'mean' score is high, whatever the 'area' score."""
    rng = np.random.default_rng(6)
    views, classes = 64, 2
    mean = np.stack([np.linspace(0, 1, views), rng.random(views)])
    area = rng.random((classes, views))
    labels = np.repeat([0, 1], 6)
    p_right = _sigmoid(-2.0 + 5.0 * mean[labels])
    right = rng.random(p_right.shape) < p_right
    predicted = np.where(right, labels[:, None], 1 - labels[:, None])
    evidence = Evidence(labels, predicted, np.tile(np.arange(6), 2))
    cfg = ObserveConfig()
    folds = leave_one_group_out(evidence, {"mean": mean, "area": area}, ["a", "b"], cfg)
    assert len(folds) == 6 and all(held.sum() == 2 for held, _ in folds)
    rows = {r["model"]: r for r in validation_quality(evidence, folds)}
    assert rows["ra_paper"]["log_likelihood"] > rows["ra_area"]["log_likelihood"]
    assert rows["ra_paper"]["auc"] > 0.75 > rows["ra_area"]["auc"]
    choice = choose_ra_variant(evidence, folds, "area", ["a", "b"])
    assert (choice.variant, choice.rule) == ("area", "configured")
    models = fit_observation_models(evidence, {"mean": mean, "area": area}, ["a", "b"], cfg)
    assert set(models) == {"ra_paper", "ra_class", "ra_area", "ra_class_area", "classifier",
                           "blackbox"}


def _planted_area_evidence(groups: int, seed: int) -> tuple[Evidence, dict[str, np.ndarray]]:
    """Three classes whose correctness follows the 'area' score strongly; 'mean' is noise."""
    rng = np.random.default_rng(seed)
    views, classes = 96, 3
    scores = {"mean": rng.random((classes, views)), "area": rng.random((classes, views))}
    labels = np.repeat(np.arange(classes), groups)
    p_right = _sigmoid(-3.0 + 7.0 * scores["area"][labels])
    right = rng.random(p_right.shape) < p_right
    predicted = np.where(right, labels[:, None], (labels[:, None] + 1) % classes)
    return Evidence(labels, predicted, np.tile(np.arange(groups), classes)), scores


def test_the_mixture_records_every_variants_held_out_table_and_the_best() -> None:
    evidence, scores = _planted_area_evidence(4, 8)
    classes = ["a", "b", "c"]
    folds = leave_one_group_out(evidence, scores, classes, ObserveConfig())
    choice = choose_ra_variant(evidence, folds, "mixture", classes)
    assert (choice.variant, choice.rule) == ("mixture", "mixture")
    assert not choice.too_little_evidence
    assert choice.best in {"area", "class_area"}  # the score that carries correctness
    assert choice.objects_per_class == {"a": 4, "b": 4, "c": 4}
    robust = choice.held_out[ROBUST_RA_VARIANT]
    assert robust["difference_to_best"] < -robust["standard_error"] < 0  # beyond one SE
    best = choice.held_out[choice.best]
    assert best["mean_log_likelihood"] == max(r["mean_log_likelihood"]
                                              for r in choice.held_out.values())
    assert best["difference_to_best"] == 0.0
    # the per-object figures average to the pooled held-out table's
    pooled = {r["model"]: r for r in validation_quality(evidence, folds)}
    assert best["mean_log_likelihood"] == pytest.approx(
        float(pooled[f"ra_{choice.best}"]["log_likelihood"]), abs=1e-9)
    assert choice.reason == (f"the RA variants averaged with weights fitted on the held-out "
                             f"labels (12 held-out objects; '{choice.best}' alone is the best)")
    assert choice.to_dict()["without_each_group"] == {}


def test_the_held_out_chooser_says_when_there_is_too_little_evidence() -> None:
    evidence, scores = _planted_area_evidence(4, 9)
    classes = ["a", "b", "c"]
    one = Evidence(evidence.labels, evidence.predicted, np.zeros_like(evidence.groups))
    choice = choose_ra_variant(one, leave_one_group_out(one, scores, classes, ObserveConfig()),
                               "mixture", classes)
    assert (choice.variant, choice.rule) == (ROBUST_RA_VARIANT, "too little evidence")
    assert choice.too_little_evidence and choice.objects_per_class == {"a": 0, "b": 0, "c": 0}
    assert choice.reason.startswith("too little held-out evidence to choose: class 'a' (0)")
    # class c with one volume model only: its one object is never held out, so too little
    keep = (evidence.labels != 2) | (evidence.groups == 0)
    short = evidence.subset(keep)
    folds = leave_one_group_out(short, scores, classes, ObserveConfig())
    choice = choose_ra_variant(short, folds, "mixture", classes)
    assert choice.too_little_evidence and choice.variant == ROBUST_RA_VARIANT
    assert choice.objects_per_class["c"] < MIN_HELD_OUT_OBJECTS <= choice.objects_per_class["a"]
    assert "'c'" in choice.reason and "'a'" not in choice.reason
    recorded = choice.to_dict()
    assert recorded["too_little_evidence"] is True and recorded["robust_default"] == "class"


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


def test_the_mixture_never_weighs_a_reported_only_variant() -> None:
    """A region bad for every class is ra_region's best case; it is fitted and reported, but
    left out of the mixture's table (it is not selectable, docs/decisions/0006)."""
    from rapomdp.awareness.variants import REPORTED_ONLY

    rng = np.random.default_rng(3)
    directions = fibonacci_directions(64, hemisphere=True)
    bad = directions[:, 2] > 0.7
    classes = 4
    labels = np.repeat(np.arange(classes), 4)
    right = rng.random((labels.size, 64)) < np.where(bad, 0.1, 0.9)[None]
    predicted = np.where(right, labels[:, None], (labels[:, None] + 1) % classes)
    evidence = Evidence(labels, predicted, np.tile(np.arange(4), classes))
    flat = np.full((classes, 64), 0.5)
    names = [str(c) for c in range(classes)]
    folds = leave_one_group_out(evidence, {"mean": flat, "area": flat}, names, ObserveConfig(),
                                directions)
    assert REPORTED_ONLY == {"region"} and all("ra_region" in m for _, m in folds)
    choice = choose_ra_variant(evidence, folds, "mixture", names)
    assert "region" not in choice.held_out
    assert choice.best == "viewpoint"  # the per-class region term finds it too
    weights, _ = ra_mixture_folds(evidence, folds, names)
    assert "ra_region" not in weights and "ra_viewpoint" in weights


def test_salient_view_similarity_is_one_for_the_same_parts_and_zero_for_disjoint_ones():
    seen = np.array([[1.0, 2.0, 0.0, 0.0], [2.0, 4.0, 0.0, 0.0], [0.0, 0.0, 3.0, 1.0]])
    sim = salient_view_similarity(seen)
    assert sim[0, 1] == pytest.approx(1.0)
    assert sim[0, 2] == pytest.approx(0.0)
    assert np.allclose(np.diag(sim), 1.0)
    assert np.allclose(sim, sim.T)


def test_transfer_shares_evidence_between_views_that_see_the_same_saliency_only():
    # two classes, 4 viewpoints at one direction (no geometric preference): views 0-1 see
    # one salient part, views 2-3 another; class 0 is mistaken for class 1 at view 0 only
    directions = np.tile([[0.0, 0.0, 1.0]], (4, 1))
    block = np.kron(np.eye(2), np.ones((2, 2)))  # similarity 1 within a part, 0 across
    similarity = np.stack([block, block])
    labels = np.zeros(20, np.int64)
    predicted = np.zeros((20, 4), np.int64)
    predicted[:, 0] = 1  # always wrong at view 0, always right elsewhere
    evidence = Evidence(labels, predicted, np.arange(20))
    p = transfer_confusion(evidence, similarity, directions, pseudo_count=1.0)
    assert np.allclose(p.sum(axis=2), 1.0)
    # views 0 and 1 pool 20 wrong + 20 right labels; views 2 and 3 pool 40 right ones
    row = np.array([61.0, 21.0]) / 82.0  # class 0's confusion row: 60 right, 20 wrong, +1 each
    expected_01 = (np.array([20.0, 20.0]) + TRANSFER_PRIOR * row) / (40 + TRANSFER_PRIOR)
    expected_23 = (np.array([40.0, 0.0]) + TRANSFER_PRIOR * row) / (40 + TRANSFER_PRIOR)
    assert np.allclose(p[0, 0], expected_01) and np.allclose(p[1, 0], expected_01)
    assert np.allclose(p[2, 0], expected_23) and np.allclose(p[3, 0], expected_23)
    # class 1 has no evidence: its confusion row's pseudo-counts, uniform
    assert np.allclose(p[:, 1], 0.5)


def test_transfer_confusion_with_an_explicit_kernel_matches_a_hand_computed_row() -> None:
    # views 0 and 1 look from one direction, view 2 from 90° away; class 0's view 0 sees
    # saliency half like view 1's; kernel: power 2, 45°, 3 pseudo-observations
    directions = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    similarity = np.ones((2, 3, 3))
    similarity[0, 0, 1] = similarity[0, 1, 0] = 0.5
    labels = np.array([0, 0])
    predicted = np.array([[1, 0, 0], [0, 0, 1]])
    evidence = Evidence(labels, predicted, np.array([0, 1]))
    p = transfer_confusion(evidence, similarity, directions, 1.0, TransferKernel(2.0, 45.0, 3.0))
    far = np.exp(-0.5 * (90.0 / 45.0) ** 2)
    row = np.array([5.0, 3.0]) / 8.0  # class 0: 4 right, 2 wrong, +1 each
    # at view 0: its own [1, 1], view 1's [2, 0] at 0.5 ** 2, view 2's [1, 1] at `far`
    near = np.array([1.0, 1.0]) + 0.25 * np.array([2.0, 0.0]) + far * np.array([1.0, 1.0])
    assert np.allclose(p[0, 0], (near + 3.0 * row) / (near.sum() + 3.0))
    # at view 2: views 0 and 1 at `far` (similarity 1), its own [1, 1] at 1
    there = far * np.array([3.0, 1.0]) + np.array([1.0, 1.0])
    assert np.allclose(p[2, 0], (there + 3.0 * row) / (there.sum() + 3.0))
    assert np.allclose(p[:, 1], 0.5)  # class 1: no evidence, the uniform row


def _planted_kernel_evidence(structured: bool, seed: int,
                             object_rates: bool = False) -> tuple[Evidence, np.ndarray,
                                                                  np.ndarray]:
    """Three classes, 64 viewpoints, three groups of two objects a class; every view sees the
    same saliency. ``structured``: each (class, viewpoint) has one label for every object,
    drawn independently per viewpoint; else every outcome is i.i.d. around the class's rate
    (``object_rates``: around the object's own rate, drawn for every object alike, so that no
    class's rate says anything about its next object)."""
    rng = np.random.default_rng(seed)
    classes, views = 3, 64
    directions = fibonacci_directions(views, hemisphere=True)
    labels = np.tile(np.repeat(np.arange(classes), 2), 3)
    groups = np.repeat(np.arange(3), 2 * classes)
    if structured:
        predicted = rng.integers(0, classes, (classes, views))[labels]
    else:
        rate = (rng.choice([0.2, 0.95], labels.size) if object_rates
                else np.array([0.5, 0.7, 0.9])[labels])
        right = rng.random((labels.size, views)) < rate[:, None]
        wrong = (labels[:, None] + rng.integers(1, classes, right.shape)) % classes
        predicted = np.where(right, labels[:, None], wrong)
    return (Evidence(labels, predicted, groups), np.ones((classes, views, views)),
            directions)


def test_transfer_kernel_choice_pools_widely_on_viewpoint_free_noise() -> None:
    evidence, similarity, directions = _planted_kernel_evidence(False, 31)
    kernel, table = choose_transfer_kernel(evidence, similarity, directions, 1.0)
    assert (kernel.bandwidth_deg, kernel.prior) == (40.0, 8.0)
    assert len(table) == len(TRANSFER_KERNEL_GRID) == 64
    best = max(r["held_out_log_likelihood"] for r in table)
    narrowest = max(r["held_out_log_likelihood"] for r in table if r["bandwidth_deg"] == 5.0)
    assert narrowest < best
    assert {r["class_prior"] for r in table} == {0.0}  # the retired shrinkage's record: none


def test_transfer_kernel_choice_stays_local_on_per_viewpoint_structure() -> None:
    evidence, similarity, directions = _planted_kernel_evidence(True, 32)
    kernel, table = choose_transfer_kernel(evidence, similarity, directions, 1.0)
    assert (kernel.bandwidth_deg, kernel.prior) == (5.0, 1.0)
    assert kernel.power == 0.0  # every view sees the same saliency: powers tie, the first wins
    default = next(r for r in table if TransferKernel.from_dict(r) == DEFAULT_TRANSFER_KERNEL)
    assert default["held_out_log_likelihood"] < table[0]["held_out_log_likelihood"]


def test_transfer_kernel_table_is_the_held_out_validation_of_ra_transfer() -> None:
    evidence, similarity, directions = _planted_kernel_evidence(False, 33)
    _, table = choose_transfer_kernel(evidence, similarity, directions, 1.0)
    flat = np.full((3, 64), 0.5)
    scores = {"mean": flat, "area": flat, "similarity": similarity}
    for row in (table[0], table[37]):
        folds = leave_one_group_out(evidence, scores, ["a", "b", "c"], ObserveConfig(),
                                    directions, TransferKernel.from_dict(row))
        ra = next(r for r in validation_quality(evidence, folds) if r["model"] == "ra_transfer")
        assert ra["log_likelihood"] == pytest.approx(row["held_out_log_likelihood"], abs=1e-12)


def test_transfer_kernel_choice_falls_back_to_the_default_without_two_folds() -> None:
    evidence, similarity, directions = _planted_kernel_evidence(False, 34)
    single = Evidence(evidence.labels, evidence.predicted, np.zeros_like(evidence.groups))
    assert choose_transfer_kernel(single, similarity, directions, 1.0) == (
        DEFAULT_TRANSFER_KERNEL, [])
    # two groups, but holding out group 1 leaves class 2 without evidence: one fold only
    two = np.where(evidence.labels == 2, 1, evidence.groups % 2)
    assert choose_transfer_kernel(Evidence(evidence.labels, evidence.predicted, two),
                                  similarity, directions, 1.0) == (DEFAULT_TRANSFER_KERNEL, [])
    assert DEFAULT_TRANSFER_KERNEL.to_dict() == {"power": 4.0, "bandwidth_deg": 20.0,
                                                 "prior": TRANSFER_PRIOR, "class_prior": 0.0}


def test_the_recorded_kernel_is_read_back_and_older_workspaces_get_the_default() -> None:
    chosen = TransferKernel(2.0, 10.0, 2.0)
    recorded = {"transfer_kernel": {**chosen.to_dict(), "grid": []}, "ra_model": "transfer"}
    assert recorded_transfer_kernel(recorded) == chosen
    assert recorded_transfer_kernel({"ra_model": "transfer"}) == DEFAULT_TRANSFER_KERNEL


def test_the_recorded_evidence_and_scores_are_what_a_refit_reads() -> None:
    artefact = {"evidence_labels": np.array([0, 1]),
                "evidence_predictions": np.array([[0, 1], [1, 1]]),
                "evidence_groups": np.array([0, 1]),
                "evidence_from_volume": np.array([True, False]),
                "scores": np.ones((2, 2)), "area_scores": np.zeros((2, 2)),
                "view_similarity": np.eye(2, dtype=np.float32)[None].repeat(2, axis=0)}
    evidence = recorded_evidence(artefact)
    assert evidence.labels.tolist() == [0, 1] and evidence.groups.tolist() == [0, 1]
    assert evidence.correct.tolist() == [[True, False], [True, True]]
    scores = recorded_scores(artefact)
    assert set(scores) == {"mean", "area", "similarity"}
    assert scores["similarity"].dtype == np.float64
    del artefact["view_similarity"]  # an artefact from before ra_transfer: no similarity
    assert set(recorded_scores(artefact)) == {"mean", "area"}


def test_softmax_temperature_recovers_a_planted_overconfidence():
    from rapomdp.awareness.temperature import fit_softmax_temperature

    rng = np.random.default_rng(21)
    logits = rng.normal(size=(4000, 5)) * 2.0
    labels = np.array([rng.choice(5, p=np.exp(z) / np.exp(z).sum()) for z in logits])
    calibrated = np.exp(logits) / np.exp(logits).sum(axis=1, keepdims=True)
    over = np.exp(3.0 * logits) / np.exp(3.0 * logits).sum(axis=1, keepdims=True)
    assert fit_softmax_temperature(calibrated, labels) == pytest.approx(1.0, abs=0.08)
    assert fit_softmax_temperature(over[:, None], labels) == pytest.approx(3.0, rel=0.08)


def test_shrinking_wrong_labels_keeps_p_correct_and_ends_at_uniform() -> None:
    rng = np.random.default_rng(3)
    p = rng.dirichlet(np.ones(4), size=(6, 4))  # (V, C, C)
    idx = np.arange(4)
    for amount in WRONG_LABEL_SHRINKAGES:
        shrunk = shrink_wrong_labels(p, amount)
        np.testing.assert_allclose(shrunk.sum(axis=2), 1.0)
        np.testing.assert_array_equal(shrunk[:, idx, idx], p[:, idx, idx])
    np.testing.assert_array_equal(shrink_wrong_labels(p, 0.0), p)
    uniform = shrink_wrong_labels(p, 1.0)
    wrong = ~np.eye(4, dtype=bool)
    np.testing.assert_allclose(uniform[:, wrong].reshape(6, 4, 3),
                               np.repeat(((1 - p[:, idx, idx]) / 3)[:, :, None], 3, axis=2))
    half = shrink_wrong_labels(p, 0.5)
    np.testing.assert_allclose(half, (p + uniform) / 2)
    with pytest.raises(ValueError, match=r"shrink a \(V, C, C\) model, got shape \(6, 4\)"):
        shrink_wrong_labels(p[:, 0], 0.5)
    with pytest.raises(ValueError, match=r"in \[0, 1\], got 1.5"):
        shrink_wrong_labels(p, 1.5)


def _planted_wrong_labels(per_object: bool, seed: int, groups: int = 4
                          ) -> tuple[Evidence, dict[str, np.ndarray]]:
    """Eight classes, ``groups`` held-out objects each, right on 60 % of the views; every wrong
    view of an object names one class: the object's own (``per_object``, drawn: where one
    object's mistakes go says little of another's) or its class's (the same for every object)."""
    rng = np.random.default_rng(seed)
    classes, views = 8, 48
    labels = np.repeat(np.arange(classes), groups)
    right = rng.random((labels.size, views)) < 0.6
    offset = rng.integers(1, classes, labels.size) if per_object else np.ones(labels.size, int)
    predicted = np.where(right, labels[:, None], ((labels + offset) % classes)[:, None])
    scores = {"mean": rng.random((classes, views)), "area": rng.random((classes, views))}
    return Evidence(labels, predicted, np.tile(np.arange(groups), classes)), scores


def test_the_wrong_label_shrinkage_is_chosen_where_mistakes_do_not_transfer() -> None:
    names = list("abcdefgh")
    evidence, scores = _planted_wrong_labels(per_object=True, seed=4)
    folds = leave_one_group_out(evidence, scores, names, ObserveConfig())
    for model in ("blackbox", "ra_class", "classifier"):
        choice = choose_wrong_label_shrinkage(evidence, folds, model)
        assert choice.rule == "best" and choice.amount >= 0.75, (model, choice)
        row = choice.held_out[f"{choice.amount:g}"]
        assert row["difference_to_none"] > row["standard_error"] > 0
        assert row["mean_log_likelihood"] == max(r["mean_log_likelihood"]
                                                 for r in choice.held_out.values())
        assert choice.held_out["0"]["difference_to_none"] == 0.0
        assert "more than one standard error" in choice.reason
    # mistakes every object of a class makes alike: the counted wrong labels are kept
    evidence, scores = _planted_wrong_labels(per_object=False, seed=4)
    folds = leave_one_group_out(evidence, scores, names, ObserveConfig())
    choice = choose_wrong_label_shrinkage(evidence, folds, "blackbox")
    assert (choice.amount, choice.rule) == (0.0, "best")
    assert all(r["difference_to_none"] < 0 for a, r in choice.held_out.items() if a != "0")
    assert choice.to_dict()["grid"] == list(WRONG_LABEL_SHRINKAGES)


def test_the_wrong_label_shrinkage_needs_held_out_objects() -> None:
    names = list("abcdefgh")
    evidence, scores = _planted_wrong_labels(per_object=True, seed=5)
    one = Evidence(evidence.labels, evidence.predicted, np.zeros_like(evidence.groups))
    none_held = leave_one_group_out(one, scores, names, ObserveConfig())
    choice = choose_wrong_label_shrinkage(one, none_held, "blackbox")
    assert (choice.amount, choice.rule, choice.held_out) == (0.0, "too little evidence", {})
    assert choice.reason.startswith("too little held-out evidence to choose")


def test_a_gain_within_one_standard_error_keeps_the_counted_wrong_labels() -> None:
    """Four held-out objects make their mistakes where the counted rows expect them, two
    elsewhere: uniform wrong labels gain on average, by less than one standard error."""
    from rapomdp.awareness.observation import ObservationModel

    rows = np.array([[0.5, 0.45, 0.05], [0.05, 0.5, 0.45], [0.45, 0.05, 0.5]])
    model = ObservationModel(rows[None], ["a", "b", "c"])  # one viewpoint
    labels = np.array([0, 0, 1, 1, 2, 2])
    expected = (labels + 1) % 3  # where the rows put a class's mistakes
    elsewhere = np.array([True, False, True, False, False, False])
    wrong = np.where(elsewhere, (labels + 2) % 3, expected)
    predicted = np.where(np.arange(10)[None] < 5, labels[:, None], wrong[:, None])
    evidence = Evidence(labels, predicted, np.array([0, 1, 0, 1, 0, 1]))
    folds = [(evidence.groups == g, {"m": model}) for g in (0, 1)]
    choice = choose_wrong_label_shrinkage(evidence, folds, "m")
    assert (choice.amount, choice.rule) == (0.0, "one standard error")
    best = max(choice.held_out.values(), key=lambda r: r["mean_log_likelihood"])
    assert 0 < best["difference_to_none"] <= best["standard_error"]
    uniform = choice.held_out["1"]  # per object: 5 wrong views of 10, log(0.25 / row's share)
    d = np.where(elsewhere, 0.5 * np.log(0.25 / 0.05), 0.5 * np.log(0.25 / 0.45))
    assert uniform["difference_to_none"] == pytest.approx(d.mean())
    assert uniform["standard_error"] == pytest.approx(d.std(ddof=1) / np.sqrt(6))
    assert "not better than none by more than one standard error" in choice.reason


def test_a_model_some_folds_cannot_fit_is_chosen_on_the_folds_that_have_it() -> None:
    """ra_viewpoint stacks over groups: a fold left with one group has none; the choice reads
    the folds that fitted it, and no fold at all is too little evidence."""
    names = list("abcdefgh")
    evidence, scores = _planted_wrong_labels(per_object=True, seed=4)
    folds = leave_one_group_out(evidence, scores, names, ObserveConfig())
    full = choose_wrong_label_shrinkage(evidence, folds, "blackbox")
    missing = [(held, {k: m for k, m in models.items() if k != "blackbox"}) if i == 0
               else (held, models) for i, (held, models) in enumerate(folds)]
    fewer = choose_wrong_label_shrinkage(evidence, missing, "blackbox")
    assert fewer.rule == "best" and fewer.amount >= 0.75
    assert fewer.held_out["1"] != full.held_out["1"]  # one group fewer scored
    none = [(held, {k: m for k, m in models.items() if k != "blackbox"})
            for held, models in folds]
    assert choose_wrong_label_shrinkage(evidence, none, "blackbox").rule == \
        "too little evidence"


def _planted_class_rates(rates: list[float], seed: int, groups: int = 4, spread: float = 1.5,
                         views: int = 64) -> tuple[Evidence, dict[str, np.ndarray]]:
    """Each object right on its views at its own rate: logit N(logit(its class's rate), spread)."""
    rng = np.random.default_rng(seed)
    c = len(rates)
    scores = {"mean": rng.random((c, views)), "area": rng.random((c, views))}
    labels, groups_of = np.repeat(np.arange(c), groups), np.tile(np.arange(groups), c)
    logit = np.log(np.array(rates) / (1 - np.array(rates)))[labels]
    own = _sigmoid(logit + spread * rng.standard_normal(labels.size))
    right = rng.random((labels.size, views)) < own[:, None]
    predicted = np.where(right, labels[:, None], (labels[:, None] + 1) % c)
    return Evidence(labels, predicted, groups_of), scores


def test_shrunk_folds_shrink_the_named_models_wrong_labels_and_keep_the_rest():
    from rapomdp.awareness.observation import ObservationModel
    from rapomdp.awareness.shrinkage import shrunk_folds

    rng = np.random.default_rng(3)
    p = rng.dirichlet(np.ones(3), size=(4, 3))
    held = np.array([True, False])
    folds = [(held, {"a": ObservationModel(p, ["x", "y", "z"]),
                     "b": ObservationModel(p, ["x", "y", "z"])})]
    (mask, models), = shrunk_folds(folds, {"a": 0.5})
    assert mask is held
    assert np.allclose(models["a"].probabilities, shrink_wrong_labels(p, 0.5))
    assert models["b"] is folds[0][1]["b"]
    idx = np.arange(3)
    assert np.allclose(models["a"].probabilities[:, idx, idx], p[:, idx, idx])


def test_the_configured_kernel_is_the_grids_choice_or_the_default_without_similarity() -> None:
    from rapomdp.awareness.transfer import configured_transfer_kernel

    evidence, similarity, directions = _planted_kernel_evidence(True, 1)
    scores = {"similarity": similarity}
    cfg = ObserveConfig()
    pseudo = cfg.confusion_pseudo_count
    assert configured_transfer_kernel(evidence, {}, directions, pseudo) == (
        DEFAULT_TRANSFER_KERNEL, [])
    assert configured_transfer_kernel(evidence, scores, None, pseudo) == (
        DEFAULT_TRANSFER_KERNEL, [])
    kernel, table = configured_transfer_kernel(evidence, scores, directions, pseudo)
    expected = choose_transfer_kernel(evidence, similarity, directions,
                                      cfg.confusion_pseudo_count, TRANSFER_KERNEL_GRID)
    assert (kernel, table) == expected and len(table) == len(TRANSFER_KERNEL_GRID)


def test_mixture_weights_recover_a_planted_mixture_and_refuse_zero_probabilities() -> None:
    rng = np.random.default_rng(0)
    first, second = np.array([0.7, 0.1, 0.1, 0.1]), np.array([0.1, 0.1, 0.1, 0.7])
    source = rng.random(20_000) < 0.3  # 30 % of the labels drawn from the first model
    labels = np.where(source, rng.choice(4, 20_000, p=first), rng.choice(4, 20_000, p=second))
    w = fit_mixture_weights(np.stack([first[labels], second[labels]]))
    assert w.sum() == pytest.approx(1.0) and w[0] == pytest.approx(0.3, abs=0.02)
    # a model that is the truth against a uniform one takes almost all the weight
    truth = fit_mixture_weights(np.stack([second[labels[~source]], np.full((~source).sum(), 0.25)]))
    assert truth[0] > 0.95
    with pytest.raises(ValueError, match="positive probabilities"):
        fit_mixture_weights(np.array([[0.5, 0.0], [0.5, 0.5]]))


def test_each_folds_mixture_is_weighted_without_the_group_it_scores() -> None:
    """Group 0's objects are always misread, groups 1 and 2 always read right: group 0's
    fold weighs the variants on groups 1-2 alone (all on the one that says 'right'), and the
    mixture over every group weighs both."""
    classes = ["a", "b"]
    labels = np.array([0, 1, 0, 1, 0, 1])
    groups = np.array([0, 0, 1, 1, 2, 2])
    predicted = np.where(groups[:, None] == 0, 1 - labels[:, None], labels[:, None])
    predicted = np.repeat(predicted, 4, axis=1)  # (6, 4 viewpoints)
    evidence = Evidence(labels, predicted, groups)

    def table(p_correct: float) -> ObservationModel:
        return ObservationModel(np.broadcast_to(np.array([[p_correct, 1 - p_correct],
                                                          [1 - p_correct, p_correct]]),
                                                (4, 2, 2)).copy(), classes)

    models = {"ra_right": table(0.9), "ra_wrong": table(0.1), "ra_region": table(0.5),
              "classifier": table(0.5)}
    folds = [(groups == g, dict(models)) for g in range(3)]
    weights, mixed = ra_mixture_folds(evidence, folds, classes)
    assert set(weights) == {"ra_right", "ra_wrong"}  # the RA variants but the reported-only
    assert 0.5 < weights["ra_right"] < 0.8  # a third of the labels are misread
    fold_weights = [m["ra_mixture"].calibration.weights for _, m in mixed]
    assert fold_weights[0]["ra_right"] > 0.99  # fitted on groups 1-2: always right
    assert 0.3 < fold_weights[1]["ra_right"] < 0.7  # groups 0 and 2: half misread
    assert np.allclose(mixed[0][1]["ra_mixture"].probabilities[:, 0, 0],
                       0.9 * fold_weights[0]["ra_right"] + 0.1 * fold_weights[0]["ra_wrong"])
    with pytest.raises(ValueError, match="two groups of held-out evidence"):
        ra_mixture_folds(evidence, folds[:1], classes)
