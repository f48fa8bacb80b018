"""A mixture of the RA variants against ``observe.ra_model: auto``'s one pick, held out (rules:
benchmarks/results/ra_mixture_rule.md, ra_mixture_rule_v2.md).

For each workspace (observed with the naive belief) the observe stage's held-out folds are
refitted from its record (``RecordedObservation.belief_folds``: every model fitted without each
volume group, shrunk as the stage chose) and each fold gets the mixture
``observe.ra_model: mixture`` would fit (``evidence.ra_mixture_folds``: weighted on the *other*
groups' labels). Each group's objects are then scored, mean log-likelihood per label, by the
fold's mixture and by the fold's ``ra`` (the stage's choice); printed: the mixture's advantage
per object, per workspace and per set (the workspaces' parent folder: mean of seeds, smallest).

``--test`` (afterwards, a diagnostic that chooses nothing): the test models' log-likelihood and
AUC per observation of the mixture weighted on every group, against the stage's choice, the
best RA variant there, the black box and the Classifier (as ``ra_choice_transfer.py`` reads
them from the stage's quality table).

    python benchmarks/ra_mixture.py -w W [W ...] [--test]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rapomdp.awareness.artefacts import load_quality
from rapomdp.awareness.choices import RecordedObservation
from rapomdp.awareness.evidence import held_out_object_log_likelihoods
from rapomdp.awareness.mixture import MIXTURE_VARIANT, ra_mixture_folds
from rapomdp.awareness.observation import MixtureObservationModel, ObservationModel
from rapomdp.awareness.quality import awareness_quality
from rapomdp.awareness.report import single_view_models
from rapomdp.workspace import Workspace

MIXTURE = f"ra_{MIXTURE_VARIANT}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    parser.add_argument("--test", action="store_true",
                        help="afterwards: the test models' figures (a diagnostic)")
    args = parser.parse_args()
    per_set: dict[str, list[float]] = {}
    for root in args.workspace:
        ws = Workspace(root)
        recorded = RecordedObservation.load(ws.require("observe"))
        evidence = recorded.evidence
        folds = recorded.belief_folds(ws.config().observe)
        weights, mixed = ra_mixture_folds(evidence, folds, recorded.classes)
        scored = held_out_object_log_likelihoods(evidence, [
            (held, {"ra": models["ra"], MIXTURE: models[MIXTURE]}) for held, models in mixed])
        covered = ~np.isnan(scored["ra"])
        advantage = (scored[MIXTURE] - scored["ra"])[covered]
        per_set.setdefault(root.parent.name, []).append(float(advantage.mean()))
        print(f"{root}: chosen {recorded.variant}; nested mixture − chosen "
              f"{advantage.mean():+.4f} per label per object ({advantage.size} objects, "
              f"≥ 0 on {np.mean(advantage >= 0):.2f}); weights on every group "
              + ", ".join(f"{n.removeprefix('ra_')} {w:.2f}" for n, w in weights.items()),
              flush=True)
        if args.test:
            print_test(ws, recorded, weights)
    print("\nper set: the nested mixture's advantage per label, mean of the workspaces "
          "(smallest)")
    for name, values in per_set.items():
        print(f"  {name:24s} {np.mean(values):+.4f} ({min(values):+.4f}) over {len(values)} "
              "workspaces")


def print_test(ws: Workspace, recorded: RecordedObservation, weights: dict[str, float]) -> None:
    """The test models' figures of the mixture against the stage's quality table."""
    observe = ws.require("observe")
    quality = {str(row["model"]): row for row in load_quality(observe)}
    models = {name: ObservationModel(p, recorded.classes)
              for name, p in single_view_models(dict(recorded.arrays)).items()}
    labels, predicted = recorded.arrays["test_labels"], recorded.arrays["test_predictions"]
    chosen = awareness_quality(models[recorded.variant], labels, predicted)
    recorded_ll = float(quality[recorded.variant]["log_likelihood"])
    if abs(chosen["log_likelihood"] - recorded_ll) > 1e-4:
        raise SystemExit(f"{ws.root}: the untempered {recorded.variant} does not reproduce the "
                         f"quality table ({chosen['log_likelihood']:.5f} against "
                         f"{recorded_ll:.5f})")
    mixture = awareness_quality(MixtureObservationModel(models, weights, recorded.classes),
                                labels, predicted)
    variants = {n: r for n, r in quality.items() if n.startswith("ra_")}
    best_ll = max(variants, key=lambda n: float(variants[n]["log_likelihood"]))
    best_auc = max(variants, key=lambda n: float(variants[n]["auc"]))
    print(f"    test: mixture LL {mixture['log_likelihood']:.3f} AUC {mixture['auc']:.3f}; "
          f"chosen LL {chosen['log_likelihood']:.3f} AUC {chosen['auc']:.3f}; best variant LL "
          f"{float(variants[best_ll]['log_likelihood']):.3f} ({best_ll}) AUC "
          f"{float(variants[best_auc]['auc']):.3f} ({best_auc}); mixture's gap to it LL "
          f"{float(variants[best_ll]['log_likelihood']) - mixture['log_likelihood']:+.3f} AUC "
          f"{float(variants[best_auc]['auc']) - mixture['auc']:+.3f}; black box LL "
          f"{float(quality['blackbox']['log_likelihood']):.3f} AUC "
          f"{float(quality['blackbox']['auc']):.3f}; Classifier LL "
          f"{float(quality['classifier']['log_likelihood']):.3f} AUC "
          f"{float(quality['classifier']['auc']):.3f}", flush=True)


if __name__ == "__main__":
    main()
