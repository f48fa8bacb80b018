"""Is the held-out walk temperature calibrated where the episodes stop? Held-out random walks
that stop as Random stops (max belief >= ``evaluate.random.belief_threshold`` or
``evaluate.random.max_moves`` moves), on the volume models only, never the test models.

The observe stage fits each model's temperature t on the mean log loss over every step of
fixed-length walks. An episode is judged where it stops, and a threshold stop selects the walks
whose evidence ran ahead of the truth. For each t this prints, at the stop: the mean moves, the
accuracy, the mean confidence (belief in the declared class), confidence − accuracy and the log
loss of the belief in the true class; then the t of least log loss at the stop. Each group's
walks use the models fitted without it, as the observe stage fits them.

    python benchmarks/stopped_walk_calibration.py --workspace W [--walks-per-row 16]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rapomdp.awareness.choices import RecordedObservation
from rapomdp.awareness.variants import leave_one_group_out
from rapomdp.data.splits import class_seed
from rapomdp.recognition.belief import (
    fold_of_rows,
    held_out_walks,
    stop_steps,
    walk_log_beliefs,
)
from rapomdp.workspace import Workspace

TEMPERATURES = (1.0, 0.75, 0.6, 0.5, 0.4, 0.3, 0.25, 0.2, 0.15)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, required=True)
    parser.add_argument("--walks-per-row", type=int, default=16)
    parser.add_argument("--neighbours", type=int, default=8)
    parser.add_argument("--models", nargs="+", default=["ra", "classifier"])
    args = parser.parse_args()
    ws = Workspace(args.workspace)
    config = ws.config()
    recorded = RecordedObservation.load(ws.require("observe"))
    observe, calibration, evidence = recorded.arrays, recorded.calibration, recorded.evidence
    variant = recorded.variant
    folds = leave_one_group_out(evidence, recorded.scores, recorded.classes, config.observe,
                                observe["directions"], recorded.transfer_kernel)
    if not folds:
        raise SystemExit(f"{args.workspace}: one group of evidence, nothing held out")
    row_model = fold_of_rows([held for held, _ in folds], len(evidence.labels))
    random_cfg = config.evaluate.random
    walks, walk_row = held_out_walks(row_model, observe["directions"],
                                     class_seed(config.seed, "benchmarks/stopped_walks"),
                                     random_cfg.max_moves + 1, args.walks_per_row,
                                     args.neighbours)
    true = evidence.labels[walk_row]
    episodes = np.arange(len(walks))
    print(f"{len(walks)} held-out walks over {len(folds)} groups, stop at max belief >= "
          f"{random_cfg.belief_threshold:g} or after {random_cfg.max_moves} moves "
          f"(neighbours {args.neighbours}); RA model {variant}")
    for name in args.models:
        key = variant if name == "ra" else name
        models = [fold[key].probabilities for _, fold in folds]
        walk_t = calibration["held_out_belief"][key]["temperature"]
        print(f"\n{name} ({key}); the observe stage's walk-fitted t = {walk_t:.3f}")
        print(f"{'t':>6s} {'moves':>6s} {'accuracy':>8s} {'confid.':>7s} {'conf-acc':>8s} "
              f"{'stop log loss':>13s}")
        losses = {}
        for t in sorted({*TEMPERATURES, round(walk_t, 3)}, reverse=True):
            log_belief = walk_log_beliefs(t, models, row_model, evidence.predicted, walks,
                                          walk_row)
            stop = stop_steps(log_belief, random_cfg.belief_threshold)
            final = log_belief[episodes, stop]
            right = final.argmax(axis=1) == true
            confidence = np.exp(final.max(axis=1))
            losses[t] = float(-final[episodes, true].mean())
            print(f"{t:6.3f} {stop.mean():6.2f} {right.mean():8.3f} {confidence.mean():7.3f} "
                  f"{confidence.mean() - right.mean():+8.3f} {losses[t]:13.3f}")
        best = min(losses, key=losses.__getitem__)
        print(f"least log loss at the stop: t = {best:g}")


if __name__ == "__main__":
    main()
