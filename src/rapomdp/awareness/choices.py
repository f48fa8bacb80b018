"""The observe stage's held-out choices, in the order it makes them, as one function, and the
refit of what a stage recorded.

Every knob of the observation models is chosen on groups of held-out objects (the volume
models), each group scored by models fitted without it: ``ra_transfer``'s kernel, RA-POMDP's
model (``observe.ra_model``: the mixture of the variants by default), each model's wrong-label
shrinkage, the belief's temperature and the declared confidence. :func:`held_out_choices` makes
them all; the stage calls it on its whole evidence, and a nested held-out loop may call it on
the evidence without one group, so the two cannot make different choices.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rapomdp.awareness.artefacts import CALIBRATION_FILE, OBSERVATION_FILE
from rapomdp.awareness.evidence import (
    Evidence,
    Folds,
    recorded_evidence,
    recorded_scores,
    validation_quality,
)
from rapomdp.awareness.mixture import (
    MIXTURE_VARIANT,
    VariantChoice,
    choose_ra_variant,
    ra_mixture_folds,
)
from rapomdp.awareness.observation import MixtureObservationModel, ObservationModel
from rapomdp.awareness.shrinkage import (
    ShrinkageChoice,
    choose_wrong_label_shrinkage,
    shrink_wrong_labels,
    shrunk_folds,
)
from rapomdp.awareness.temperature import held_out_declared_confidence, held_out_temperatures
from rapomdp.awareness.transfer import (
    TransferKernel,
    configured_transfer_kernel,
    recorded_transfer_kernel,
)
from rapomdp.awareness.variants import (
    STACKED_VARIANTS,
    fit_observation_models,
    leave_one_group_out,
)
from rapomdp.config import ObserveConfig
from rapomdp.data.splits import class_seed
from rapomdp.io import load_npz, read_json
from rapomdp.recognition.belief import (
    TEMPERATURE_NEIGHBOURS,
    TEMPERATURE_WALK_LENGTH,
    TEMPERATURE_WALKS_PER_ROW,
    DeclaredConfidence,
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
    #: RA-POMDP's model (``observe.ra_model``) and why.
    choice: VariantChoice
    #: Each model's wrong-label shrinkage and why.
    shrinkage: dict[str, ShrinkageChoice]
    #: The single-view models: fitted and shrunk, not tempered.
    single_view: dict[str, ObservationModel]
    #: Each held-out group's rows and the models fitted without it (shrunk, not tempered).
    belief_folds: Folds
    #: The belief's correction per model (``temperature`` where one was fitted, else
    #: ``none``) and its likelihood temperature (1 where none was fitted).
    corrections: dict[str, str]
    temperatures: dict[str, float]
    #: Per model, the held-out walks' calibration, naive and tempered.
    belief_calibration: dict[str, dict[str, float]]
    declared: dict[str, DeclaredConfidence] = field(default_factory=dict)

    @property
    def variant(self) -> str:
        """The chosen RA variant (``ra`` is ``ra_<variant>``)."""
        return self.choice.variant


def held_out_choices(evidence: Evidence, scores: dict[str, np.ndarray], classes: Sequence[str],
                     cfg: ObserveConfig, directions: np.ndarray, seed: int) -> HeldOutChoices:
    """Every held-out choice of the observe stage, in the stage's order, and the models
    fitted with them.

    Args:
        evidence: the held-out outcomes (N objects, V viewpoints).
        scores: the viewpoint scores by kind (``mean``, ``area``: (C, V); ``similarity``:
            (C, V, V)).
        classes: the C class names, in order.
        cfg: the observe section.
        directions: (V, 3) unit viewpoint directions.
        seed: the run's seed (the walks' streams derive from it).

    Returns:
        The choices and models (:class:`HeldOutChoices`).

    Raises:
        ValueError: no evidence.
        StageError: a stacked variant named with fewer than two groups of evidence.
    """
    if len(evidence.labels) == 0:
        raise ValueError("no held-out evidence to choose on (an empty subset of the groups?)")
    kernel_start = time.perf_counter()  # ra_transfer's kernel (one group: the default)
    kernel, kernel_grid = configured_transfer_kernel(evidence, scores, directions,
                                                     cfg.confusion_pseudo_count)
    kernel_s = time.perf_counter() - kernel_start
    folds = leave_one_group_out(evidence, scores, classes, cfg, directions, kernel)
    validation = validation_quality(evidence, folds)
    choice = choose_ra_variant(evidence, folds, cfg.ra_model, classes)
    variant = choice.variant
    if variant == MIXTURE_VARIANT:  # its held-out row: each fold's weights without its group
        name = f"ra_{MIXTURE_VARIANT}"
        validation += validation_quality(evidence, [
            (held, {name: models[name]})
            for held, models in ra_mixture_folds(evidence, folds, classes)[1]])
    if variant in STACKED_VARIANTS and len(np.unique(evidence.groups)) < 2:
        raise StageError(f"observe.ra_model '{variant}' stacks over groups of held-out "
                         "evidence: use two or more volume models per class "
                         "(dataset.split.volume)")
    fitted = fit_observation_models(evidence, scores, classes, cfg, directions, kernel)
    # where each model's mistakes go, shrunk toward uniform by the held-out choice; the folds
    # too, so that the belief's temperature is fitted on the models the belief uses
    shrinkage = {name: choose_wrong_label_shrinkage(evidence, folds, name) for name in fitted}
    fitted = {name: _with_probabilities(m, shrink_wrong_labels(
                  m.probabilities, shrinkage[name].amount))
              for name, m in fitted.items()}
    folds = shrunk_folds(folds, {name: c.amount for name, c in shrinkage.items()})
    if variant == MIXTURE_VARIANT:  # the shrunk variants averaged, weighted held out
        weights, folds = ra_mixture_folds(evidence, folds, classes)
        name = f"ra_{MIXTURE_VARIANT}"
        fitted[name] = MixtureObservationModel(fitted, weights, classes)
        shrinkage[name] = ShrinkageChoice(0.0, "configured", "a mixture of its variants' "
                                          "shrunk rows")
    ra = f"ra_{variant}"
    single_view = {"ra": fitted[ra], **fitted}
    shrinkage["ra"] = shrinkage[ra]
    # the belief's likelihood temperature, fitted on held-out walks; the same walks fit the
    # temperature of the views after the first alone, recorded for comparison only
    walks = {kind: held_out_temperatures(
        evidence, folds, directions, TEMPERATURE_WALK_LENGTH, TEMPERATURE_WALKS_PER_ROW,
        TEMPERATURE_NEIGHBOURS, class_seed(seed, "observe/temperature"),
        after_first=kind == "after_first") for kind in ("temperature", "after_first")}
    fitted_t, reports = walks["temperature"]
    belief_calibration = {name: {**report, **{f"after_first_{k}": v for k, v in
                                              walks["after_first"][1][name].items()}}
                          for name, report in reports.items()}
    temperatures = {name: fitted_t.get(name, 1.0) for name in single_view}
    corrections = {name: "temperature" if name in fitted_t else "none" for name in single_view}
    corrections["ra"] = corrections.get(ra, "none")
    temperatures["ra"] = temperatures.get(ra, 1.0)
    # what a policy reports after its views: its belief ** a, a fitted where held-out walks
    # stop; the belief it acts on is unchanged
    declared = held_out_declared_confidence(
        evidence, folds, temperatures, directions, TEMPERATURE_WALKS_PER_ROW,
        TEMPERATURE_NEIGHBOURS, class_seed(seed, "observe/declared"))
    if ra in declared:
        declared["ra"] = declared[ra]
    return HeldOutChoices(kernel, kernel_grid, kernel_s, validation, choice, shrinkage,
                          single_view, folds, corrections, temperatures, belief_calibration,
                          declared)


def _with_probabilities(model: ObservationModel, probabilities: np.ndarray
                        ) -> ObservationModel:
    """``model``'s rows replaced (its score calibration kept, for the records)."""
    out = ObservationModel(probabilities, model.classes)
    out.calibration = getattr(model, "calibration", None)  # type: ignore[attr-defined]
    return out


@dataclass
class RecordedObservation:
    """What an observe stage recorded, read back for a refit of its models on its held-out
    evidence (the held-out closed loop and walks).

    Attributes:
        arrays: the arrays of ``observation_models.npz``.
        calibration: ``calibration.json``.
        classes: the class names, in order.
        evidence: the held-out evidence the models were fitted on.
        scores: the viewpoint scores by kind (:func:`~rapomdp.awareness.evidence.
            recorded_scores`).
        transfer_kernel: ``ra_transfer``'s kernel.
        variant: the model ``ra`` is (``ra_<name>``).
    """

    arrays: dict[str, np.ndarray]
    calibration: dict[str, Any]
    classes: list[str]
    evidence: Evidence
    scores: dict[str, np.ndarray]
    transfer_kernel: TransferKernel
    variant: str

    @classmethod
    def load(cls, observe_dir: str | Path) -> RecordedObservation:
        """The record of the observe stage folder ``observe_dir``."""
        arrays = load_npz(Path(observe_dir) / OBSERVATION_FILE)
        calibration = read_json(Path(observe_dir) / CALIBRATION_FILE)
        return cls(arrays, calibration, [str(c) for c in arrays["classes"]],
                   recorded_evidence(arrays), recorded_scores(arrays),
                   recorded_transfer_kernel(calibration), f"ra_{calibration['ra_model']}")

    def belief_folds(self, cfg: ObserveConfig) -> Folds:
        """The held-out folds the stage fitted its belief's temperature on, refitted.

        Args:
            cfg: the observe section the stage ran with.

        Returns:
            Every model fitted without each volume group, its wrong labels shrunk by the
            stage's choices, and ``ra`` the chosen variant's.
        """
        folds = leave_one_group_out(self.evidence, self.scores, self.classes, cfg,
                                    self.arrays["directions"], self.transfer_kernel)
        amounts = {name: float(choice["amount"])
                   for name, choice in self.calibration.get("wrong_labels", {}).items()}
        folds = shrunk_folds(folds, amounts)
        if self.variant == f"ra_{MIXTURE_VARIANT}":
            folds = ra_mixture_folds(self.evidence, folds, self.classes)[1]
        return [(held, {**models, "ra": models[self.variant]}) for held, models in folds]
