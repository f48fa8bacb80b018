"""How far can the classifier's labels take any planner? Held-out volume objects only (the
test models are not read).

For each workspace and each method's held-out folds (``experiment.held_out.held_out_folds``:
the model fitted without the object's volume group and tempered by the belief's t, the belief
the POMDP acts on) it prints the single-view accuracy over the held-out objects' views, how
many objects the classifier gets right from under 10 %, 10–30 %, 30–50 %, 50–70 % and at
least 70 % of their views, the accuracy of the belief after *every* one of the V views (no
planner can feed it more evidence), of the majority label over all views, and the share of
objects right from at least one view (a planner that knew in hindsight where to look).

    python benchmarks/evidence_ceiling.py -w W [W ...] [--methods ra classifier]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rapomdp.experiment.held_out import held_out_folds
from rapomdp.pipeline import get_stage
from rapomdp.workspace import Workspace

VIEW_ACCURACY_BINS = (0.0, 0.1, 0.3, 0.5, 0.7, 1.01)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    parser.add_argument("--methods", nargs="+", default=["ra", "classifier"])
    args = parser.parse_args()
    print(f"{'workspace':44s} {'method':10s} {'objects':>7s} {'view acc':>8s} "
          f"{'objects by view accuracy':>26s} {'all views':>9s} {'majority':>8s} "
          f"{'any view':>8s}")
    for root in args.workspace:
        ws = Workspace(root)
        folds = held_out_folds(ws.config(), ws.inputs(get_stage("evaluate")), args.methods)
        for name, parts in folds.items():
            if not parts:
                print(f"{str(root):44s} {name:10s} (no held-out folds)")
                continue
            view_acc, all_views, majority = [], [], []
            for fold in parts:
                views, classes = fold.model.shape[0], fold.model.shape[2]
                right = fold.predicted == fold.labels[:, None]  # (M, V)
                view_acc.append(right.mean(axis=1))
                log_p = np.log(np.maximum(fold.model, 1e-300))  # (V, C, O)
                total = log_p[np.arange(views)[None, :], :, fold.predicted].sum(axis=1)  # (M, C)
                all_views.append(total.argmax(axis=1) == fold.labels)
                counts = (fold.predicted[..., None] == np.arange(classes)).sum(axis=1)
                majority.append(counts.argmax(axis=1) == fold.labels)
            acc = np.concatenate(view_acc)
            hist = np.histogram(acc, VIEW_ACCURACY_BINS)[0]
            print(f"{str(root):44s} {name:10s} {acc.size:7d} {acc.mean():8.3f} "
                  f"{' '.join(f'{h:4d}' for h in hist):>26s} "
                  f"{np.concatenate(all_views).mean():9.3f} "
                  f"{np.concatenate(majority).mean():8.3f} {(acc > 0).mean():8.3f}")


if __name__ == "__main__":
    main()
