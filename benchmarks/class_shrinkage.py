"""Held out: would ``ra_class`` transfer better with its class intercepts shrunk toward their
mean? (benchmarks/results/class_shrinkage_rule.md; a diagnostic, it changes no setting.)

In each leave-one-group-out fold of the observe stage's evidence, ``ra_class`` is fitted on the
other groups and its intercepts a_c moved to a_c + w (mean(a) − a_c): P(correct | c, x) moved by
w (mean(a) − a_c) on the logit scale, the wrong labels rescaled to keep their proportions
(``evidence.shrink_class_intercepts``); each held-out object is scored by its mean
log-likelihood per label, as ``observe.ra_model: auto`` scores it. Per dataset (the workspaces'
parent folder), pooled over its workspaces: the mean per object at each w, the best w's paired
difference to w = 0 with its standard error over objects, and the stage's chosen variant for
reference.

    python benchmarks/class_shrinkage.py -w W [W ...]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rapomdp.awareness.evidence import (
    CLASS_SHRINKAGES,
    Evidence,
    Folds,
    RecordedObservation,
    held_out_object_log_likelihoods,
    leave_one_group_out,
    shrink_class_intercepts,
)
from rapomdp.workspace import Workspace


def per_object(evidence: Evidence, folds: Folds, amount: float) -> np.ndarray:
    """Each held-out object's mean log-likelihood per label under shrunk ``ra_class``."""
    shrunk = [(held, {"ra_class": shrink_class_intercepts(models["ra_class"], amount)})
              for held, models in folds]
    return held_out_object_log_likelihoods(evidence, shrunk)["ra_class"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    args = parser.parse_args()
    pooled: dict[str, dict[float, list[np.ndarray]]] = {}
    chosen: dict[str, list[np.ndarray]] = {}
    for root in args.workspace:
        ws = Workspace(root)
        recorded = RecordedObservation.load(ws.require("observe"))
        evidence = recorded.evidence
        folds = leave_one_group_out(evidence, recorded.scores, recorded.classes,
                                    ws.config().observe, recorded.arrays["directions"],
                                    recorded.transfer_kernel)
        covered = np.zeros(len(evidence.labels), dtype=bool)
        for held, _ in folds:
            covered |= held
        scored = {w: per_object(evidence, folds, w)[covered] for w in CLASS_SHRINKAGES}
        name = root.parent.name
        for w, ll in scored.items():
            pooled.setdefault(name, {}).setdefault(w, []).append(ll)
        chosen.setdefault(name, []).append(
            held_out_object_log_likelihoods(evidence, folds)[recorded.variant][covered])
        print(f"{root}: stage's variant {recorded.variant}; ra_class held out per w: "
              + ", ".join(f"{w:g} {ll.mean():+.4f}" for w, ll in scored.items()))
    print("\nper set, pooled: mean held-out log-likelihood per object of ra_class at each w; "
          "the best w against w = 0 (± one standard error over objects); the stage's variant")
    for name, by_amount in pooled.items():
        lls = {w: np.concatenate(parts) for w, parts in by_amount.items()}
        best = max(CLASS_SHRINKAGES, key=lambda w: lls[w].mean())
        d = lls[best] - lls[0.0]
        se = float(d.std(ddof=1) / np.sqrt(d.size))
        variant = np.concatenate(chosen[name])
        print(f"  {name:22s} " + ", ".join(f"w {w:g} {ll.mean():+.4f}" for w, ll in lls.items())
              + f"; best w {best:g}: {d.mean():+.4f} ± {se:.4f} over {d.size} objects"
              + f"{' (beyond one SE)' if d.mean() > se else ''}; stage's variant "
              f"{variant.mean():+.4f}")


if __name__ == "__main__":
    main()
