"""ra_transfer: rows shared by viewpoints that see the same saliency, and its kernel chosen on
held-out log-likelihood."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.awareness.evidence import (
    Evidence,
    validation_quality,
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
from rapomdp.awareness.variants import leave_one_group_out
from rapomdp.config import ObserveConfig
from rapomdp.geometry.viewsphere import fibonacci_directions


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


