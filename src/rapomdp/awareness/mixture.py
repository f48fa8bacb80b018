"""RA-POMDP's model: the RA variants averaged with weights fitted on held-out labels, or one
variant by name.

One variant picked from a few held-out objects is brittle; a weighted average of them is not
(docs/decisions/0006-ra-model-mixture.md). The weights maximise the held-out likelihood of the
held-out labels, each group scored by the variants fitted without it. With too little held-out
evidence the model falls back to :data:`ROBUST_RA_VARIANT` and says so.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rapomdp.awareness.evidence import (
    MIN_HELD_OUT_OBJECTS,
    Evidence,
    Folds,
    covered_rows,
    held_out_object_log_likelihoods,
    held_out_observed_probabilities,
)
from rapomdp.awareness.observation import MixtureObservationModel
from rapomdp.awareness.variants import REPORTED_ONLY

ROBUST_RA_VARIANT = "class"
"""The RA variant the mixture falls back to when the held-out evidence is too small to weigh
the variants: per-class intercepts (each class's held-out accuracy, the effect that dominates
and is always estimable) and one shared saliency slope b ≥ 0 (b = 0 is the black box's
diagonal). Chosen a priori, on its number of free parameters, not on any measurement."""
MIXTURE_VARIANT = "mixture"
"""``observe.ra_model: mixture`` (the default): RA-POMDP's model is the weighted average of the
RA variants (:func:`ra_mixture_folds`)."""
MIXTURE_ITERATIONS = 5000
"""EM iterations at most for the mixture weights (it stops when the log-likelihood gains less
than 1e-10 per label)."""


def fit_mixture_weights(observed: np.ndarray) -> np.ndarray:
    """The mixture weights of greatest likelihood, by EM from equal weights (the problem is
    concave, so the start only sets the speed).

    Args:
        observed: (K, M) the positive probabilities that K models give M labels.

    Returns:
        (K,) simplex weights maximising Σ_m log Σ_k w_k p[k, m].

    Raises:
        ValueError: ``observed`` is not a non-empty (K, M) array of positive probabilities.
    """
    p = np.asarray(observed, dtype=np.float64)
    if p.ndim != 2 or p.shape[0] == 0 or p.shape[1] == 0 or np.any(p <= 0):
        raise ValueError(f"mixture weights need positive probabilities (models, labels), got "
                         f"shape {p.shape}")
    w = np.full(p.shape[0], 1.0 / p.shape[0])
    last = -np.inf
    for _ in range(MIXTURE_ITERATIONS):
        mix = w @ p
        ll = float(np.log(mix).sum())
        if ll - last < 1e-10 * p.shape[1]:
            break
        last = ll
        w = (w[:, None] * p / mix).mean(axis=1)
    return w / w.sum()


def mixture_candidates(names: Collection[str]) -> list[str]:
    """The models a mixture averages: every RA variant (``ra_*``) but the reported-only ones
    and the mixture itself, in ``names``' order."""
    return [n for n in names if n.startswith("ra_") and n != f"ra_{MIXTURE_VARIANT}"
            and n.removeprefix("ra_") not in REPORTED_ONLY]


def ra_mixture_folds(evidence: Evidence, folds: Folds, classes: Sequence[str]
                     ) -> tuple[dict[str, float], Folds]:
    """``ra_mixture``'s weights, and the folds with each fold's own mixture.

    Args:
        evidence: the held-out outcomes.
        folds: its leave-one-group-out folds of the RA variants.
        classes: the class names, in order.

    Returns:
        The weights by variant on every held-out group (each group's labels scored by the
        variants fitted without it), and ``folds`` with each fold's ``ra_mixture`` added,
        weighted by the *other* groups' labels only, so that no fold's mixture has seen the
        group it scores.

    Raises:
        ValueError: fewer than two folds.
    """
    if len(folds) < 2:
        raise ValueError("a mixture of the RA variants is weighted on held-out groups: it "
                         "needs two groups of held-out evidence or more")
    names = mixture_candidates(folds[0][1])
    observed = held_out_observed_probabilities(evidence, folds, names)
    covered = covered_rows(evidence, folds)
    weights = fit_mixture_weights(observed[:, covered].reshape(len(names), -1))
    out = []
    for held, models in folds:
        nested = fit_mixture_weights(observed[:, covered & ~held].reshape(len(names), -1))
        mixture = MixtureObservationModel(models, dict(zip(names, nested, strict=True)), classes)
        out.append((held, {**models, f"ra_{MIXTURE_VARIANT}": mixture}))
    return dict(zip(names, (float(w) for w in weights), strict=True)), out


@dataclass
class VariantChoice:
    """RA-POMDP's model and why.

    Attributes:
        variant: the variant ``ra`` is (``mixture`` or a variant's name).
        rule: ``configured`` (a variant by name), ``mixture``, or ``too little evidence`` (the
            robust default: fewer than :data:`MIN_HELD_OUT_OBJECTS` held-out objects in some
            class).
        reason: one sentence saying so.
        best: the variant of best mean held-out log-likelihood per object, where compared.
        held_out: per RA variant, its mean held-out log-likelihood per object and the paired
            difference to the best with its standard error.
        objects_per_class: the held-out objects each class had.
    """

    variant: str
    rule: str
    reason: str
    best: str | None = None
    held_out: dict[str, dict[str, float]] = field(default_factory=dict)
    objects_per_class: dict[str, int] = field(default_factory=dict)

    @property
    def too_little_evidence(self) -> bool:
        return self.rule == "too little evidence"

    def to_dict(self) -> dict[str, Any]:
        """The record of ``calibration.json: ra_model_choice``."""
        return {"variant": self.variant, "rule": self.rule, "reason": self.reason,
                "best": self.best, "too_little_evidence": self.too_little_evidence,
                "robust_default": ROBUST_RA_VARIANT,
                "min_held_out_objects": MIN_HELD_OUT_OBJECTS, "held_out": self.held_out,
                "objects_per_class": self.objects_per_class,
                # the retired stability check's record (docs/decisions/0006-ra-model-mixture.md),
                # always empty: kept so that the records of every workspace read alike
                "without_each_group": {}}


def choose_ra_variant(evidence: Evidence, folds: Folds, configured: str,
                      classes: Sequence[str]) -> VariantChoice:
    """RA-POMDP's model: the configured variant, or with ``mixture`` the weighted average of
    the variants, knowing how little the held-out objects may tell.

    Args:
        evidence: the held-out outcomes.
        folds: its leave-one-group-out folds of every model.
        configured: ``observe.ra_model``.
        classes: the class names, in order.

    Returns:
        A named variant as configured (rule ``configured``). ``mixture`` with too little
        evidence — some class with fewer than :data:`MIN_HELD_OUT_OBJECTS` held-out objects (no
        folds: none) — gives the robust default :data:`ROBUST_RA_VARIANT`, and says so;
        otherwise the mixture, with every variant's held-out table recorded.
    """
    if configured != MIXTURE_VARIANT:
        return VariantChoice(configured, "configured", f"observe.ra_model is '{configured}'")
    per_object = held_out_object_log_likelihoods(evidence, folds)
    covered = covered_rows(evidence, folds)
    counts = np.bincount(evidence.labels[covered], minlength=len(classes))
    objects = {name: int(n) for name, n in zip(classes, counts, strict=True)}
    ra = {name.removeprefix("ra_"): ll for name, ll in per_object.items()
          if name.startswith("ra_") and name.removeprefix("ra_") not in REPORTED_ONLY}
    if counts.min() < MIN_HELD_OUT_OBJECTS or ROBUST_RA_VARIANT not in ra:
        short = [f"'{name}' ({n})" for name, n in objects.items() if n < MIN_HELD_OUT_OBJECTS]
        reason = (f"too little held-out evidence to choose: class {', '.join(short[:5])}"
                  f"{' and more' if len(short) > 5 else ''} has fewer than "
                  f"{MIN_HELD_OUT_OBJECTS} held-out objects; the robust default "
                  f"'{ROBUST_RA_VARIANT}'")
        return VariantChoice(ROBUST_RA_VARIANT, "too little evidence", reason, None, {}, objects)
    means = {name: float(np.nanmean(ll)) for name, ll in ra.items()}
    best = max(means, key=means.__getitem__)
    table = {}
    for name, ll in ra.items():
        d = (ll - ra[best])[covered]
        se = float(d.std(ddof=1) / np.sqrt(d.size)) if d.size > 1 else float("inf")
        table[name] = {"mean_log_likelihood": means[name], "difference_to_best": float(d.mean()),
                       "standard_error": se}
    reason = (f"the RA variants averaged with weights fitted on the held-out labels "
              f"({int(covered.sum())} held-out objects; '{best}' alone is the best)")
    return VariantChoice(MIXTURE_VARIANT, "mixture", reason, best, table, objects)
