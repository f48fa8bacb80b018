"""The observe stage's held-out choices, in the order it makes them, as one function.

Every knob of the observation models is chosen on groups of held-out objects (the volume
models, or cross-fitted training models), each group scored by models fitted without it:
``ra_transfer``'s kernel, the RA variant (``observe.ra_model``, with its stability check), the
class-intercept and wrong-label shrinkage, the cross-fitted level shift, the belief's model of
one object's views (``observe.belief``), its temperature or view discount, and the declared
confidence. :func:`held_out_choices` makes them all; the stage calls it on its whole evidence,
and a nested held-out loop (``benchmarks/nested_choices.py``) on the evidence without one
group, so the two cannot make different choices.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from rapomdp.awareness.evidence import (
    MIXTURE_VARIANT,
    STACKED_VARIANTS,
    Evidence,
    Folds,
    ShrinkageChoice,
    TransferKernel,
    VariantChoice,
    check_variant_stability,
    choose_belief_correction,
    choose_class_shrinkage,
    choose_ra_variant,
    choose_wrong_label_shrinkage,
    class_shrunk_folds,
    configured_transfer_kernel,
    fit_level,
    fit_observation_models,
    held_out_declared_confidence,
    held_out_temperatures,
    held_out_view_discounts,
    leave_one_group_out,
    ra_mixture_folds,
    shift_level,
    shrink_class_intercepts,
    shrink_wrong_labels,
    shrunk_folds,
    validation_quality,
    view_similarity_kernel,
)
from rapomdp.awareness.nuisance import NuisanceModel, nuisance_belief_models
from rapomdp.awareness.observation import MixtureObservationModel, ObservationModel
from rapomdp.config import ObserveConfig
from rapomdp.data.splits import class_seed
from rapomdp.recognition.belief import (
    DISCOUNT_JUMP,
    TEMPERATURE_NEIGHBOURS,
    TEMPERATURE_WALK_LENGTH,
    TEMPERATURE_WALKS_PER_ROW,
    DeclaredConfidence,
    ViewDiscount,
)
from rapomdp.workspace import StageError


@dataclass
class HeldOutChoices:
    """What :func:`held_out_choices` chose, and the models it fitted with those choices.

    Every per-model dict holds each fitted model by name (``ra_<variant>``, ``classifier``,
    ``blackbox``) and ``ra``, the chosen variant's entry again.
    """

    #: ``ra_transfer``'s kernel and, per grid kernel, its held-out score.
    kernel: TransferKernel
    kernel_grid: list[dict[str, float]]
    #: Seconds the kernel's choice took.
    kernel_s: float
    #: Held-out quality of every model, each group scored by the models fitted without it.
    validation: list[dict[str, float | str]]
    #: The RA variant (``observe.ra_model``) and why.
    choice: VariantChoice
    #: ``ra_class``'s class-intercept shrinkage (``observe.class_shrinkage``) and why.
    class_shrinkage: ShrinkageChoice
    #: Each model's P(correct) shift to the modelled classifier's level (cross-fitted evidence).
    levels: dict[str, float]
    #: Each model's wrong-label shrinkage (``observe.wrong_labels``) and why.
    shrinkage: dict[str, ShrinkageChoice]
    #: The single-view models: fitted, shrunk and shifted, not tempered.
    single_view: dict[str, ObservationModel]
    #: The belief's models of one view (``observe.belief``; the single-view ones when naive).
    belief_models: dict[str, ObservationModel]
    #: Each held-out group's rows and the belief's models fitted without it.
    belief_folds: Folds
    nuisance: dict[str, NuisanceModel]
    #: The belief's correction per model (``observe.belief_correction``) and its temperature.
    corrections: dict[str, str]
    temperatures: dict[str, float]
    #: Per model, the held-out walks' calibration, naive and tempered.
    belief_calibration: dict[str, dict[str, float]]
    discounts: dict[str, ViewDiscount] = field(default_factory=dict)
    discount_kernel: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    declared: dict[str, DeclaredConfidence] = field(default_factory=dict)

    @property
    def variant(self) -> str:
        """The chosen RA variant (``ra`` is ``ra_<variant>``)."""
        return self.choice.variant


def held_out_choices(evidence: Evidence, scores: dict[str, np.ndarray], classes: Sequence[str],
                     cfg: ObserveConfig, directions: np.ndarray, seed: int) -> HeldOutChoices:
    """Every held-out choice of the observe stage on ``evidence``, in the stage's order, and
    the models fitted with them; ``seed`` is the run's (the walks' streams derive from it)."""
    if len(evidence.labels) == 0:
        raise ValueError("no held-out evidence to choose on (an empty subset of the groups?)")
    kernel_start = time.perf_counter()  # ra_transfer's kernel (one group: the default)
    kernel, kernel_grid = configured_transfer_kernel(evidence, scores, cfg, directions)
    kernel_s = time.perf_counter() - kernel_start
    folds = leave_one_group_out(evidence, scores, classes, cfg, directions, kernel)
    validation = validation_quality(evidence, folds)
    choice = check_variant_stability(choose_ra_variant(evidence, folds, cfg.ra_model, classes),
                                     evidence, scores, classes, cfg, directions)
    variant = choice.variant
    if variant == MIXTURE_VARIANT:  # its held-out row: each fold's weights without its group
        name = f"ra_{MIXTURE_VARIANT}"
        validation += validation_quality(evidence, [
            (held, {name: models[name]})
            for held, models in ra_mixture_folds(evidence, folds, classes)[1]])
    if variant == "contrastive" and not cfg.contrastive:
        raise StageError("observe.ra_model is 'contrastive': set observe.contrastive: true")
    if variant in STACKED_VARIANTS and len(np.unique(evidence.groups)) < 2:
        raise StageError(f"observe.ra_model '{variant}' stacks over groups of held-out "
                         "evidence: use two or more volume models per class "
                         "(dataset.split.volume) or set observe.evidence to crossfit or both")
    if variant == MIXTURE_VARIANT and cfg.belief == "nuisance":
        raise StageError("observe.ra_model 'mixture' (the default) averages the single-view "
                         "variants, and observe.belief 'nuisance' refits each model's rows by "
                         "EM: with the nuisance belief set observe.ra_model to auto or a variant")
    fitted = fit_observation_models(evidence, scores, classes, cfg, directions, kernel)
    # ra_class's class intercepts moved toward their mean where held-out objects say so
    # (observe.class_shrinkage); after the variant is chosen, which it leaves as it is
    # (benchmarks/results/class_shrinkage_closed_loop_rule.md), and before what is fitted on it
    class_shrinkage = choose_class_shrinkage(evidence, folds, cfg.class_shrinkage)
    folds = class_shrunk_folds(folds, class_shrinkage.amount)
    if class_shrinkage.amount:
        fitted["ra_class"] = shrink_class_intercepts(fitted["ra_class"],
                                                     class_shrinkage.amount)
    levels = {name: 0.0 for name in fitted}
    if (~evidence.volume_mask).any() and evidence.volume_mask.any():
        # cross-fitted classifiers train on less data and err more: each model's P(correct)
        # is moved to the level of the modelled classifier on its own held-out objects
        own = evidence.subset(evidence.volume_mask)
        levels = {name: fit_level(m.probabilities, own.labels, own.predicted)
                  for name, m in fitted.items()}
        fitted = {name: _with_probabilities(m, shift_level(m.probabilities, levels[name]))
                  for name, m in fitted.items()}
    # where each model's mistakes go, shrunk toward uniform by the held-out choice
    # (observe.wrong_labels); the folds too, so the belief's corrections are fitted on the
    # models the belief uses
    shrinkage = {name: (choose_wrong_label_shrinkage(evidence, folds, name, cfg.wrong_labels)
                        if cfg.belief != "nuisance" else
                        ShrinkageChoice(0.0, "configured", "observe.belief 'nuisance' fits "
                                        "its own rows"))
                 for name in fitted}
    fitted = {name: _with_probabilities(m, shrink_wrong_labels(
                  m.probabilities, shrinkage[name].amount))
              for name, m in fitted.items()}
    folds = shrunk_folds(folds, {name: c.amount for name, c in shrinkage.items()})
    if variant == MIXTURE_VARIANT:  # the shrunk variants averaged, weighted held out
        weights, folds = ra_mixture_folds(evidence, folds, classes)
        name = f"ra_{MIXTURE_VARIANT}"
        fitted[name] = MixtureObservationModel(fitted, weights, classes)
        levels[name] = 0.0  # its variants' rows carry their level shifts already
        shrinkage[name] = ShrinkageChoice(0.0, "configured", "a mixture of its variants' "
                                          "shrunk rows")
    ra = f"ra_{variant}"
    single_view = {"ra": fitted[ra], **fitted}
    levels["ra"] = levels[ra]
    shrinkage["ra"] = shrinkage[ra]
    # the belief's model of one object's views (observe.belief): independent given the class
    # (naive), or given (class, instance type) with the per-object nuisance fitted by EM over
    # the held-out objects — for the folds (the walks that fit the temperature) and for all
    belief_models: dict[str, ObservationModel] = single_view
    belief_folds = folds
    nuisance: dict[str, NuisanceModel] = {}
    if cfg.belief == "nuisance":
        def base_fit(part: Evidence, names: Sequence[str] | None) -> dict[str, np.ndarray]:
            return {n: m.probabilities for n, m in fit_observation_models(
                part, scores, classes, cfg, directions, kernel, names).items()}

        nuisance, per_fold = nuisance_belief_models(
            evidence, [held for held, _ in folds], base_fit, list(fitted),
            cfg.confusion_pseudo_count)
        for name, nm in nuisance.items():  # cross-fitted evidence: the typical rows' level
            nm.typical = shift_level(nm.typical, levels[name])
        belief_models = {name: ObservationModel(nm.probabilities, classes, nm.prior)
                         for name, nm in nuisance.items()}
        belief_models = {"ra": belief_models[ra], **belief_models}
        belief_folds = [(held, {name: ObservationModel(nm.probabilities, classes, nm.prior)
                                for name, nm in fold.items()})
                        for (held, _), fold in zip(folds, per_fold, strict=True)]
    temperatures = {name: 1.0 for name in single_view}
    corrections = {name: "none" for name in single_view}
    fits = {kind: held_out_temperatures(  # the same walks for both
        evidence, belief_folds, directions, TEMPERATURE_WALK_LENGTH, TEMPERATURE_WALKS_PER_ROW,
        TEMPERATURE_NEIGHBOURS, class_seed(seed, "observe/temperature"),
        after_first=kind == "after_first") for kind in ("temperature", "after_first")}
    belief_calibration = {name: {**report, **{f"after_first_{k}": v for k, v in
                                              fits["after_first"][1][name].items()}}
                          for name, report in fits["temperature"][1].items()}
    for name in belief_calibration:
        corrections[name] = choose_belief_correction(belief_calibration[name],
                                                     cfg.belief_correction)
        kind = corrections[name]
        temperatures[name] = fits[kind][0][name] if kind != "none" else 1.0
    discounts: dict[str, ViewDiscount] = {}
    discount_kernel = np.zeros((0, 0))
    if cfg.belief == "similarity" and folds:
        # evidence discounted by how alike a view is to those taken (ra_transfer's kernel),
        # fitted on the same held-out walks; the planner's model is the memoryless stand-in
        # tempered by the mean later weight there, the first view counts in full
        discount_kernel = view_similarity_kernel(scores["similarity"], directions, kernel)
        discounts, stand_ins = held_out_view_discounts(
            evidence, folds, directions, discount_kernel, TEMPERATURE_WALK_LENGTH,
            TEMPERATURE_WALKS_PER_ROW, TEMPERATURE_NEIGHBOURS,
            class_seed(seed, "observe/temperature"),
            DISCOUNT_JUMP if cfg.discount_walks == "mixed" else 0.0)
        for name, t in stand_ins.items():
            corrections[name], temperatures[name] = "similarity", t
    corrections["ra"] = corrections.get(ra, "none")
    temperatures["ra"] = temperatures.get(ra, 1.0)
    if ra in discounts:
        discounts["ra"] = discounts[ra]
    # what a policy reports after its views: its belief ** a, a fitted where held-out walks
    # stop; the belief it acts on is unchanged
    declared = held_out_declared_confidence(
        evidence, belief_folds, temperatures, corrections, directions,
        TEMPERATURE_WALKS_PER_ROW, TEMPERATURE_NEIGHBOURS,
        class_seed(seed, "observe/declared"))
    if ra in declared:
        declared["ra"] = declared[ra]
    return HeldOutChoices(kernel, kernel_grid, kernel_s, validation, choice, class_shrinkage,
                          levels, shrinkage, single_view, belief_models, belief_folds, nuisance,
                          corrections, temperatures, belief_calibration, discounts,
                          discount_kernel, declared)


def _with_probabilities(model: ObservationModel, probabilities: np.ndarray
                        ) -> ObservationModel:
    """``model``'s rows replaced (its score calibration kept, for the records)."""
    out = ObservationModel(probabilities, model.classes)
    out.calibration = getattr(model, "calibration", None)  # type: ignore[attr-defined]
    return out
