"""``ra_transfer``: whole confusion rows shared by the viewpoints that see the same saliency.

Each viewpoint's row P(o | c, x) pools the held-out labels at every viewpoint, weighted by a
kernel: how alike the saliency the two viewpoints see is (the cosine similarity of their seen
saliency, raised to a power) times how near they are (Gaussian in the angle), shrunk to the
class's viewpoint-free confusion row. The kernel is chosen per dataset on the held-out
log-likelihood (:func:`choose_transfer_kernel`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import sparse

from rapomdp.awareness.evidence import Evidence
from rapomdp.geometry.viewsphere import geodesic_distance_matrix
from rapomdp.recognition.belief import held_out_groups
from rapomdp.recognition.evaluation import viewpoint_label_counts

VIEWPOINT_BANDWIDTH_DEG = 20.0
"""Kernel width over viewpoints (degrees) of the per-viewpoint evidence ``ra_viewpoint`` stacks
and of the default transfer kernel (fixed a priori: about two neighbours' spacing on X_rho)."""
SALIENT_VIEW_POWER = 4.0
"""Exponent on the cosine similarity of two viewpoints' seen saliency in ``ra_transfer``'s
default kernel (:data:`DEFAULT_TRANSFER_KERNEL`: the fallback when there is nothing to choose
on; the observe stage chooses per dataset, :func:`choose_transfer_kernel`)."""
TRANSFER_PRIOR = 4.0
"""Pseudo-observations of the class's viewpoint-free confusion row in each ``ra_transfer``
row of the default kernel (shrinks a viewpoint with little evidence toward the class's
confusion)."""


def angle_deg(directions: np.ndarray) -> np.ndarray:
    """Angles (V, V) in degrees between the viewpoints' unit ``directions`` (V, 3)."""
    return np.degrees(geodesic_distance_matrix(directions, radius_m=1.0))


@dataclass(frozen=True)
class TransferKernel:
    """``ra_transfer``'s kernel.

    Attributes:
        power: the exponent on the seen-saliency similarity (0: the similarity is ignored).
        bandwidth_deg: the Gaussian width over the viewpoint angle, in degrees.
        prior: pseudo-observations of the class's viewpoint-free confusion row per row.
    """

    power: float
    bandwidth_deg: float
    prior: float

    def to_dict(self) -> dict[str, float]:
        """The kernel as recorded in ``calibration.json`` (``class_prior``: always 0, the
        class-row shrinkage that ``observe.transfer_shrinkage`` offered, retired by
        docs/decisions/0008-transfer-shrinkage.md; written so that records read alike)."""
        return {"power": self.power, "bandwidth_deg": self.bandwidth_deg, "prior": self.prior,
                "class_prior": 0.0}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> TransferKernel:
        """The kernel of :meth:`to_dict`'s keys (other keys ignored)."""
        return cls(float(data["power"]), float(data["bandwidth_deg"]), float(data["prior"]))


DEFAULT_TRANSFER_KERNEL = TransferKernel(SALIENT_VIEW_POWER, VIEWPOINT_BANDWIDTH_DEG,
                                         TRANSFER_PRIOR)
"""The kernel without a choice (one group of evidence): the first generation's constants."""
TRANSFER_KERNEL_GRID: tuple[TransferKernel, ...] = tuple(
    TransferKernel(power, bandwidth, prior)
    for power in (0.0, 2.0, 4.0, 8.0)
    for bandwidth in (5.0, 10.0, 20.0, 40.0)
    for prior in (1.0, 2.0, 4.0, 8.0))
"""The 64 kernels :func:`choose_transfer_kernel` scores (the default among them)."""


def recorded_transfer_kernel(calibration: Mapping[str, Any]) -> TransferKernel:
    """The kernel an observe stage's ``calibration.json`` records (``transfer_kernel``), or
    :data:`DEFAULT_TRANSFER_KERNEL` for a workspace from before the per-dataset choice: what a
    refit of that workspace's ``ra_transfer`` must use."""
    recorded = calibration.get("transfer_kernel")
    return TransferKernel.from_dict(recorded) if recorded else DEFAULT_TRANSFER_KERNEL


def salient_view_similarity(seen_saliency: np.ndarray | sparse.spmatrix) -> np.ndarray:
    """Cosine similarity of the saliency each viewpoint sees (1: the same salient parts).

    Args:
        seen_saliency: (V, voxels), dense or sparse: visibility x voxel saliency of a class's
            volume.

    Returns:
        (V, V) similarities in [0, 1].
    """
    f = sparse.csr_matrix(seen_saliency, dtype=np.float64)
    gram = np.asarray((f @ f.T).todense())
    norm = np.sqrt(np.diag(gram)) + 1e-12
    return np.clip(gram / norm[:, None] / norm[None, :], 0.0, 1.0)


def _class_view_counts(labels: np.ndarray, predicted: np.ndarray, classes: int) -> np.ndarray:
    """Label counts n(c, x, o) (C, V, C) of the outcomes, class-major for the per-class
    kernel product: true ``labels`` (N,), ``predicted`` (N, V)."""
    return viewpoint_label_counts(labels, predicted, classes).transpose(1, 0, 2)


def _transfer_weights(similarity: np.ndarray, angle: np.ndarray, power: float,
                      bandwidth_deg: float) -> np.ndarray:
    """K_c(x, x') (C, V, V) = sim_c(x, x') ** power * exp(-(angle / bandwidth) ** 2 / 2)."""
    return np.asarray(similarity, dtype=np.float64) ** power * np.exp(
        -0.5 * (angle / bandwidth_deg) ** 2)[None]


def _confusion_rows(counts: np.ndarray, pseudo_count: float) -> np.ndarray:
    """Each class's viewpoint-free confusion row (C, C) from the counts (C, V, C)."""
    row = counts.sum(axis=1) + pseudo_count
    return row / row.sum(axis=1, keepdims=True)


def transfer_confusion(evidence: Evidence, similarity: np.ndarray, directions: np.ndarray,
                       pseudo_count: float,
                       kernel: TransferKernel = DEFAULT_TRANSFER_KERNEL) -> np.ndarray:
    """``ra_transfer``'s model from the held-out labels at *every* viewpoint.

    Each viewpoint x's row pools the labels at every x', weighted by how alike the saliency
    x' sees is to x's and how near x' is, shrunk to the class's confusion row by
    ``kernel.prior`` pseudo-observations: views that see the same salient parts share their
    evidence, the recognition-aware prior on where the classifier errs alike.

    Args:
        evidence: the held-out outcomes the model is fitted on.
        similarity: (C, V, V) seen-saliency similarity (:func:`salient_view_similarity`).
        directions: (V, 3) unit viewpoint directions.
        pseudo_count: pseudo-count per (class, label) of the class's confusion row.
        kernel: the kernel (:func:`choose_transfer_kernel`'s choice).

    Returns:
        P(o | c, x) (V, C, C), rows summing to 1.
    """
    c = similarity.shape[0]
    counts = _class_view_counts(evidence.labels, evidence.predicted, c)  # (C, V, O)
    weights = _transfer_weights(similarity, angle_deg(directions), kernel.power,
                                kernel.bandwidth_deg)
    smoothed = weights @ counts  # (C, V, O)
    row = _confusion_rows(counts, pseudo_count)
    p = (smoothed + kernel.prior * row[:, None]) / (
        smoothed.sum(axis=2, keepdims=True) + kernel.prior)
    return np.ascontiguousarray(p.transpose(1, 0, 2))


def choose_transfer_kernel(evidence: Evidence, similarity: np.ndarray, directions: np.ndarray,
                           pseudo_count: float,
                           grid: Sequence[TransferKernel] = TRANSFER_KERNEL_GRID
                           ) -> tuple[TransferKernel, list[dict[str, float]]]:
    """The kernel of ``grid`` whose :func:`transfer_confusion` predicts held-out labels best.

    Each group is scored by the model fitted on the others; the score is the mean log
    P(observed label) over every held-out outcome. The smoothed counts are computed once per
    (power, bandwidth) and fold; the priors reuse them.

    Args:
        evidence: the held-out outcomes.
        similarity: (C, V, V) seen-saliency similarity.
        directions: (V, 3) unit viewpoint directions.
        pseudo_count: pseudo-count per (class, label) of the class's confusion row.
        grid: the kernels scored.

    Returns:
        The best kernel (ties: the first) and every kernel's row (its :meth:`~TransferKernel.
        to_dict` and ``held_out_log_likelihood``, nats per label) in ``grid``'s order. With
        fewer than two folds: :data:`DEFAULT_TRANSFER_KERNEL` and an empty table.
    """
    masks = held_out_groups(evidence.labels, evidence.groups)
    if len(masks) < 2:
        return DEFAULT_TRANSFER_KERNEL, []
    c = similarity.shape[0]
    angle = angle_deg(directions)
    folds = []  # (rest's counts, its confusion rows, held-out (class, view, label))
    for held in masks:
        counts = _class_view_counts(evidence.labels[~held], evidence.predicted[~held], c)
        predicted = evidence.predicted[held]
        t = np.broadcast_to(evidence.labels[held][:, None], predicted.shape).ravel()
        x = np.broadcast_to(np.arange(predicted.shape[1])[None], predicted.shape).ravel()
        folds.append((counts, _confusion_rows(counts, pseudo_count), (t, x, predicted.ravel())))
    outcomes = sum(idx[0].size for _, _, idx in folds)
    by_shape: dict[tuple[float, float], list[int]] = {}
    for i, k in enumerate(grid):
        by_shape.setdefault((k.power, k.bandwidth_deg), []).append(i)
    log_likelihood = np.zeros(len(grid))
    for (power, bandwidth), which in by_shape.items():
        weights = _transfer_weights(similarity, angle, power, bandwidth)
        priors = np.array([grid[i].prior for i in which])[:, None]  # (K, 1)
        total = np.zeros(len(which))
        for counts, rows, (t, x, o) in folds:
            smoothed = weights @ counts  # (C, V, O)
            seen = smoothed.sum(axis=2)[t, x]
            row = np.broadcast_to(rows[t, o], (len(which), t.size))  # (K, M)
            p = (smoothed[t, x, o] + priors * row) / (seen + priors)  # (K, M)
            total += np.log(np.maximum(p, 1e-300)).sum(axis=1)
        log_likelihood[which] = total / outcomes
    table = [{**k.to_dict(), "held_out_log_likelihood": float(ll)}
             for k, ll in zip(grid, log_likelihood, strict=True)]
    return grid[int(np.argmax(log_likelihood))], table


def configured_transfer_kernel(evidence: Evidence, scores: Mapping[str, np.ndarray],
                               directions: np.ndarray | None, pseudo_count: float
                               ) -> tuple[TransferKernel, list[dict[str, float]]]:
    """``ra_transfer``'s kernel as the observe stage chooses it on ``evidence``.

    Args:
        evidence: the held-out outcomes.
        scores: the viewpoint scores by kind; ``similarity`` (C, V, V) is read.
        directions: (V, 3) unit viewpoint directions, or None.
        pseudo_count: ``observe.confusion_pseudo_count``.

    Returns:
        :func:`choose_transfer_kernel`'s kernel and table over :data:`TRANSFER_KERNEL_GRID`;
        the default kernel and no table without the similarity or the directions.
    """
    if "similarity" not in scores or directions is None:
        return DEFAULT_TRANSFER_KERNEL, []
    return choose_transfer_kernel(evidence, scores["similarity"], directions, pseudo_count)
