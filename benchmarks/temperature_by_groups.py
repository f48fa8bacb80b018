"""Does the walk temperature depend on how much evidence the fold models are counted from?
The observe stage fits t on fold models counted from G − 1 of its G held-out groups and applies
it to the model counted from all G. This fits t with fold models counted from k = 1 … G − 1
groups (held-out group h scored by the models of the k groups after it, cyclically), on the
observe stage's walks; a trend in k says which way the deployed model's t would move. Held-out
volume models only, never the test models.

    OMP_NUM_THREADS=1 python benchmarks/temperature_by_groups.py --workspace W
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rapomdp.awareness.choices import RecordedObservation
from rapomdp.awareness.variants import fit_observation_models
from rapomdp.data.splits import class_seed
from rapomdp.recognition.belief import fit_temperature, fold_of_rows, held_out_walks
from rapomdp.workspace import Workspace


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, required=True)
    parser.add_argument("--models", nargs="+", default=["ra", "classifier"])
    args = parser.parse_args()
    ws = Workspace(args.workspace)
    config = ws.config()
    recorded = RecordedObservation.load(ws.require("observe"))
    evidence, directions = recorded.evidence, recorded.arrays["directions"]
    groups = np.unique(evidence.groups)
    if len(groups) < 3:
        raise SystemExit(f"{args.workspace}: {len(groups)} groups; a trend needs three or more")
    held = [evidence.groups == g for g in groups]
    row_model = fold_of_rows(held, len(evidence.labels))
    walks, walk_row = held_out_walks(row_model, directions,
                                     class_seed(config.seed, "observe/temperature"))
    stage_t = recorded.calibration["temperatures"]
    print(f"{len(groups)} groups, {len(evidence.labels)} rows, {len(walks)} walks; the observe "
          f"stage's t: " + ", ".join(f"{m} {stage_t[m]:.3f}" for m in args.models))
    for name in args.models:
        key = recorded.variant if name == "ra" else name
        fits = []
        for k in range(1, len(groups)):
            models = []
            for i in range(len(groups)):
                train = np.isin(evidence.groups,
                                [groups[(i + j) % len(groups)] for j in range(1, k + 1)])
                models.append(fit_observation_models(
                    evidence.subset(train), recorded.scores, recorded.classes, config.observe,
                    directions, recorded.transfer_kernel)[key].probabilities)
            t = fit_temperature(models, row_model, evidence.labels, evidence.predicted, walks,
                                walk_row)
            fits.append(f"k = {k}: t = {t:.3f}")
        print(f"{name} ({key}): " + "; ".join(fits))


if __name__ == "__main__":
    main()
