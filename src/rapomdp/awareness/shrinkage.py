"""Where each model's wrong labels go: as counted held out, or shrunk toward uniform.

Where one object's mistakes went need not be where another's go (docs/awareness.md §4.7): a
class's wrong labels are counted on a few held-out objects. Per model, the amount of shrinkage
toward uniform wrong labels of best held-out log-likelihood is kept only if it beats none by
more than one standard error over held-out objects (:func:`choose_wrong_label_shrinkage`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rapomdp.awareness.evidence import (
    MIN_HELD_OUT_OBJECTS,
    Evidence,
    Folds,
    covered_rows,
    held_out_object_log_likelihoods,
)
from rapomdp.awareness.observation import ObservationModel

WRONG_LABEL_SHRINKAGES = (0.0, 0.25, 0.5, 0.75, 0.9, 1.0)
"""The amounts the wrong-label shrinkage scores: a grid fixed before any measurement of it, from
none (the counted wrong labels) to uniform wrong labels."""


def shrink_wrong_labels(probabilities: np.ndarray, amount: float) -> np.ndarray:
    """A model with each row's wrong labels mixed toward uniform, its P(correct) kept.

    P_a(o | c, x) = (1 - a) P(o | c, x) + a (1 - P(c | c, x)) / (C - 1) for o != c.

    Args:
        probabilities: P(o | c, x) (V, C, C).
        amount: a in [0, 1]; 0 returns the model's values.

    Returns:
        The shrunk model (V, C, C), rows summing to 1.

    Raises:
        ValueError: not a (V, C, C) model, or ``amount`` outside [0, 1].
    """
    p = np.asarray(probabilities, dtype=np.float64)
    c = p.shape[-1]
    if p.ndim != 3 or p.shape[1] != c:
        raise ValueError(f"wrong labels shrink a (V, C, C) model, got shape {p.shape}")
    if not 0.0 <= amount <= 1.0:
        raise ValueError(f"a shrinkage is in [0, 1], got {amount}")
    idx = np.arange(c)
    right = p[:, idx, idx]  # (V, C)
    out = (1.0 - amount) * p + amount * ((1.0 - right) / max(c - 1, 1))[:, :, None]
    out[:, idx, idx] = right
    return out


def shrunk_folds(folds: Folds, amounts: Mapping[str, float]) -> Folds:
    """``folds`` with each named model's wrong labels shrunk by its amount
    (:func:`shrink_wrong_labels`; models not in ``amounts`` as they are): the belief's
    held-out models as the observe stage fits its temperature on them."""
    return [(held, {name: (ObservationModel(shrink_wrong_labels(m.probabilities, amounts[name]),
                                            m.classes) if name in amounts else m)
                    for name, m in models.items()})
            for held, models in folds]


@dataclass
class ShrinkageChoice:
    """One model's wrong-label shrinkage and why.

    Attributes:
        amount: the shrinkage a in [0, 1] applied.
        rule: ``best`` (the best held-out log-likelihood: none, or better than none by more
            than one standard error), ``one standard error`` (none: the best is not better by
            more), ``too little evidence`` (none: fewer than :data:`MIN_HELD_OUT_OBJECTS`
            held-out objects in some class) or ``configured`` (set by the caller).
        reason: one sentence saying so.
        held_out: per amount, its mean held-out log-likelihood per object and its paired
            difference to none with the standard error.
        grid: the amounts scored.
    """

    amount: float
    rule: str
    reason: str
    held_out: dict[str, dict[str, float]] = field(default_factory=dict)
    grid: tuple[float, ...] = WRONG_LABEL_SHRINKAGES

    def to_dict(self) -> dict[str, Any]:
        """The record of ``calibration.json: wrong_labels``."""
        return {"amount": self.amount, "rule": self.rule, "reason": self.reason,
                "grid": list(self.grid), "held_out": self.held_out}


def choose_wrong_label_shrinkage(evidence: Evidence, folds: Folds, name: str
                                 ) -> ShrinkageChoice:
    """Model ``name``'s wrong-label shrinkage (:func:`shrink_wrong_labels`), chosen held out.

    Args:
        evidence: the held-out outcomes.
        folds: its leave-one-group-out folds (the folds without the model are skipped).
        name: the model.

    Returns:
        The amount of :data:`WRONG_LABEL_SHRINKAGES` of best mean held-out log-likelihood per
        object (each object scored by the fold models fitted without its group, shrunk), kept
        only if it beats none by more than one standard error of the paired difference over
        held-out objects; none when some class has fewer than :data:`MIN_HELD_OUT_OBJECTS`
        held-out objects.
    """
    return _choose_amount(evidence, folds, name, WRONG_LABEL_SHRINKAGES, lambda m, a: (
        ObservationModel(shrink_wrong_labels(m.probabilities, a), m.classes)))


def _choose_amount(evidence: Evidence, folds: Folds, name: str, grid: tuple[float, ...],
                   transform: Callable[[ObservationModel, float], ObservationModel]
                   ) -> ShrinkageChoice:
    """The amount of ``grid`` (0 first: none) of best mean held-out log-likelihood per object
    for model ``name`` transformed by it, kept only beyond one standard error over none."""
    # the folds that fitted the model (ra_viewpoint stacks over groups: a fold left with one
    # group has none)
    folds = [(held, models) for held, models in folds if name in models]
    covered = covered_rows(evidence, folds)
    classes = len(folds[0][1][name].classes) if folds else 0
    counts = np.bincount(evidence.labels[covered], minlength=classes)
    if not folds or counts.min() < MIN_HELD_OUT_OBJECTS:
        return ShrinkageChoice(0.0, "too little evidence",
                               f"too little held-out evidence to choose: some class has fewer "
                               f"than {MIN_HELD_OUT_OBJECTS} held-out objects; none", grid=grid)
    per_amount = {}
    for amount in grid:
        shrunk = [(held, {name: transform(models[name], amount)}) for held, models in folds]
        per_amount[amount] = held_out_object_log_likelihoods(evidence, shrunk)[name][covered]
    table = {}
    for amount, ll in per_amount.items():
        d = ll - per_amount[0.0]
        se = float(d.std(ddof=1) / np.sqrt(d.size)) if d.size > 1 else float("inf")
        table[f"{amount:g}"] = {"mean_log_likelihood": float(ll.mean()),
                                "difference_to_none": float(d.mean()), "standard_error": se}
    best = max(grid, key=lambda a: per_amount[a].mean())
    row = table[f"{best:g}"]
    if best == 0.0:
        return ShrinkageChoice(0.0, "best", "none is the best held out", table, grid)
    if row["difference_to_none"] <= row["standard_error"]:
        return ShrinkageChoice(0.0, "one standard error",
                               f"{best:g} is the best held out, but not better than none by "
                               f"more than one standard error ({row['difference_to_none']:+.4f}"
                               f" ± {row['standard_error']:.4f} per object over "
                               f"{int(covered.sum())} held-out objects)", table, grid)
    return ShrinkageChoice(best, "best",
                           f"{best:g} is better held out than none by "
                           f"{row['difference_to_none']:.4f} per object, more than one standard "
                           f"error ({row['standard_error']:.4f}) over {int(covered.sum())} "
                           "held-out objects", table, grid)
