"""The observe stage's held-out choices made again on part of its evidence: for a nested
held-out closed loop, in which each held-out group's RA variant, ``ra_transfer`` kernel,
wrong-label shrinkage and belief temperatures are chosen without that group
(``held_out_closed_loop.py --nested``).

The stage chooses them on every volume group, so its held-out closed loop scores each group
by knobs that saw it. :func:`observe_choices` makes the stage's choices with the function the
stage calls (``rapomdp.awareness.choices.held_out_choices``; the naive belief on volume
evidence, the default); :func:`check_reproduces` asserts that on the whole evidence they are
what the workspace recorded, so a workspace observed by older code is refused. The saliency
scores stay the stage's: they are geometry over every volume model, no label enters them.

    python benchmarks/nested_choices.py -w W...   # per workspace: the check, then each
                                                  # group's nested choices against the stage's
        [--score]

``--score``: per volume group g, the RA variant picked without g and the robust default
``ra_class``, both fitted without g (wrong labels shrunk as chosen there), score g's objects by
their mean log-likelihood per label (as ``auto`` scores them); per dataset (the workspaces'
parent folder), over the folds whose pick is not ``ra_class``, the pick's mean advantage per
object, with a bootstrap interval over objects (benchmarks/results/choice_stability_rule.md).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rapomdp.awareness.choices import RecordedObservation, held_out_choices
from rapomdp.awareness.evidence import Evidence, held_out_object_log_likelihoods
from rapomdp.awareness.mixture import ROBUST_RA_VARIANT
from rapomdp.awareness.observation import ObservationModel
from rapomdp.awareness.transfer import TransferKernel
from rapomdp.config import ObserveConfig
from rapomdp.experiment.metrics import cluster_bootstrap_difference
from rapomdp.workspace import Workspace


@dataclass
class ObserveChoices:
    """What the observe stage chooses on held-out groups (:func:`held_out_choices`), and the
    single-view models it fits with them (``models``: shrunk, not tempered; ``ra`` is
    ``ra_<variant>``), as the closed loop and this script read them."""

    variant: str
    variant_rule: str
    kernel: TransferKernel
    shrinkage: dict[str, float]
    corrections: dict[str, str]
    temperatures: dict[str, float]
    models: dict[str, np.ndarray]


def observe_choices(evidence: Evidence, scores: dict[str, np.ndarray], classes: Sequence[str],
                    cfg: ObserveConfig, directions: np.ndarray, seed: int) -> ObserveChoices:
    """The observe stage's choices on ``evidence`` (the naive belief on volume evidence, whose
    models the held-out closed loop replays)."""
    chosen = held_out_choices(evidence, scores, classes, cfg, directions, seed)
    return ObserveChoices(
        f"ra_{chosen.variant}", chosen.choice.rule, chosen.kernel,
        {name: c.amount for name, c in chosen.shrinkage.items()}, chosen.corrections,
        chosen.temperatures, {name: m.probabilities for name, m in chosen.single_view.items()})


def check_reproduces(recorded: RecordedObservation, choices: ObserveChoices) -> None:
    """Raise unless ``choices`` (made on the whole evidence) are what the stage recorded."""
    calibration = recorded.calibration
    found = {
        "variant": (choices.variant, recorded.variant),
        "kernel": (choices.kernel.to_dict(), recorded.transfer_kernel.to_dict()),
        "shrinkage": (choices.shrinkage, {n: float(c["amount"]) for n, c in
                                          calibration["wrong_labels"].items()}),
        "corrections": (choices.corrections, calibration["belief_corrections"]),
    }
    wrong = [k for k, (ours, theirs) in found.items() if ours != theirs]
    t_ours, t_stage = choices.temperatures, calibration["temperatures"]
    if set(t_ours) != set(t_stage) or not np.allclose(
            [t_ours[n] for n in t_stage], [t_stage[n] for n in t_stage], rtol=1e-9):
        wrong.append("temperatures")
    if wrong:
        raise SystemExit(f"the workspace's recorded choices are not this code's "
                         f"({', '.join(wrong)} differ): rerun its observe stage")


def nested_choices(ws: Workspace, recorded: RecordedObservation
                   ) -> dict[int, ObserveChoices]:
    """Per volume group g: the observe stage's choices made on the other groups only, after
    checking that on every group they are the stage's own."""
    config = ws.config()
    evidence, scores = recorded.evidence, recorded.scores
    classes, directions = recorded.classes, recorded.arrays["directions"]
    check_reproduces(recorded, observe_choices(evidence, scores, classes, config.observe,
                                               directions, config.seed))
    return {int(g): observe_choices(evidence.subset(evidence.groups != g), scores, classes,
                                    config.observe, directions, config.seed)
            for g in np.unique(evidence.groups)}


def pick_advantages(evidence: Evidence, per_group: dict[int, ObserveChoices],
                    classes: Sequence[str]) -> np.ndarray:
    """Per object of the groups whose pick without them is not ``ra_class``: the pick's
    log-likelihood minus ``ra_class``'s (both fitted without the object's group)."""
    out = []
    for g, choices in per_group.items():
        if choices.variant == ROBUST:
            continue
        held = evidence.groups == g
        scored = held_out_object_log_likelihoods(evidence, [(held, {
            name: ObservationModel(choices.models[name], classes)
            for name in (choices.variant, ROBUST)})])
        out.append((scored[choices.variant] - scored[ROBUST])[held])
    return np.concatenate(out) if out else np.zeros(0)


#: The robust default of ``observe.ra_model: auto``, as a model's name.
ROBUST = f"ra_{ROBUST_RA_VARIANT}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    parser.add_argument("--score", action="store_true",
                        help="score each group's pick against ra_class on that group (above)")
    args = parser.parse_args()
    advantages: dict[str, list[np.ndarray]] = {}
    folds: dict[str, list[int]] = {}
    for root in args.workspace:
        ws = Workspace(root)
        recorded = RecordedObservation.load(ws.require("observe"))
        per_group = nested_choices(ws, recorded)
        t = recorded.calibration["temperatures"]
        shrink = recorded.calibration["wrong_labels"]
        print(f"{root}: the stage's choices reproduced; stage: {recorded.variant}, kernel "
              f"{recorded.transfer_kernel.to_dict()}, shrinkage ra "
              f"{shrink['ra']['amount']:g} classifier {shrink['classifier']['amount']:g}, t ra "
              f"{t['ra']:.3f} classifier {t['classifier']:.3f}")
        for g, c in per_group.items():
            print(f"  without group {g}: {c.variant} ({c.variant_rule}), kernel "
                  f"{c.kernel.to_dict()}, shrinkage ra {c.shrinkage['ra']:g} classifier "
                  f"{c.shrinkage['classifier']:g}, t ra {c.temperatures['ra']:.3f} classifier "
                  f"{c.temperatures['classifier']:.3f}")
        if args.score:
            d = pick_advantages(recorded.evidence, per_group, recorded.classes)
            advantages.setdefault(root.parent.name, []).append(d)
            picks = [c.variant for c in per_group.values() if c.variant != ROBUST]
            folds.setdefault(root.parent.name, []).append(len(picks))
            print(f"  picks other than {ROBUST}: {picks or 'none'}"
                  + (f"; their advantage on the unseen group {d.mean():+.4f} per object "
                     f"({d.size} objects)" if d.size else ""))
    for name, parts in advantages.items():
        d = np.concatenate(parts)
        if not d.size:
            print(f"{name}: every pick without a group is {ROBUST}")
            continue
        estimate, low, high = cluster_bootstrap_difference(d, np.ones_like(d))
        print(f"{name}: {sum(folds[name])} of {3 * len(parts)} folds pick another variant "
              f"than {ROBUST}; its advantage on the group it did not see {estimate:+.4f} "
              f"[{low:+.4f}, {high:+.4f}] per object over {d.size} objects")


if __name__ == "__main__":
    main()
