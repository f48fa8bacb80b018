"""Where the POMDPs' declared confidence is fitted, held out only: the stages' walk-fitted a
against the a fitted at each method's own held-out closed-loop stops
(``evaluate.declared_fit``, docs/awareness.md §4.8). Never reads the test models.

For each workspace and POMDP method it runs the held-out closed loop as the evaluate stage
does (``experiment.held_out.closed_loop_declared``: each volume group's models from 4 starts,
the belief and the lookahead by the model fitted without the group; the plan the solve
stage's, or each fold's own with ``--per-fold``) and prints, at those stops, confidence −
accuracy / ECE of the belief, of the belief raised to the walks' a (the stages', fitted on
every group's walks; for ``learned``, the learned baseline, a = 1: its belief as it reported
it) and of the belief raised to the loop's a fitted on the other groups' episodes
(leave-one-group-out); then the mean of each over the workspaces.

    python benchmarks/declared_fit.py -w W [W ...] [--methods ra classifier vptree]
        [--per-fold] [--test]

``--test`` instead prints, per workspace and method, what the evaluate stage's test episodes
reported (confidence − accuracy / ECE of the final confidence): a diagnostic read after the
choice, never a choice.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from rapomdp.context import RunContext
from rapomdp.experiment.episode_table import EPISODES_FILE, EpisodeTable
from rapomdp.experiment.held_out import closed_loop_declared
from rapomdp.experiment.sections import LEARNED
from rapomdp.pipeline import get_stage
from rapomdp.planning.stage import declared_temperatures, offered_observation_models
from rapomdp.recognition.belief import declared_log_beliefs, expected_calibration_error
from rapomdp.workspace import Workspace


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    parser.add_argument("--methods", nargs="+", default=["ra", "classifier", "vptree"])
    parser.add_argument("--per-fold", action="store_true",
                        help="solve each fold's model (closed_loop_per_fold): minutes a run")
    parser.add_argument("--test", action="store_true",
                        help="the test episodes' reported calibration (after the choice)")
    args = parser.parse_args()
    if args.test:
        test_diagnostic(args.workspace)
        return
    rows: dict[str, list[tuple[float, ...]]] = {}
    print(f"{'workspace':48s} {'method':10s} {'n':>4s} {'accuracy':>8s} {'belief':>15s} "
          f"{'walk a':>6s} {'walk a':>15s} {'loop a':>6s} {'loop a, held out':>16s}")
    for root in args.workspace:
        ws = Workspace(root)
        config = ws.config()
        inputs = ws.inputs(get_stage("evaluate"))
        with tempfile.TemporaryDirectory() as tmp:
            fits = closed_loop_declared(config, inputs, args.methods, Path(tmp),
                                        RunContext(progress=False), per_fold=args.per_fold)
        offered, _ = offered_observation_models(inputs.observe, inputs.vptree_dir)
        walk = declared_temperatures(inputs.observe, {m: offered[m] for m in fits
                                                      if m != LEARNED}, inputs.vptree_dir)
        walk[LEARNED] = 1.0  # the learned baseline reported its belief (round four's rule)
        for name, fit in fits.items():
            log_b, truth = fit.log_beliefs, fit.truth
            right = log_b.argmax(axis=1) == truth
            belief = np.exp(log_b.max(axis=1))
            walked = np.exp(declared_log_beliefs(log_b, walk[name]).max(axis=1))
            d = fit.declared
            figures = (belief.mean() - right.mean(), expected_calibration_error(belief, right),
                       walked.mean() - right.mean(), expected_calibration_error(walked, right),
                       d.declared_confidence - d.accuracy, d.declared_ece)
            rows.setdefault(name, []).append(figures)
            print(f"{str(root):48s} {name:10s} {d.stops:4d} {d.accuracy:8.3f} "
                  f"{figures[0]:+.3f} / {figures[1]:.3f} {walk[name]:6.3f} "
                  f"{figures[2]:+.3f} / {figures[3]:.3f} {d.temperature:6.3f} "
                  f"{figures[4]:+.3f} / {figures[5]:.3f}")
    print("\nmean over the workspaces: confidence - accuracy / ECE")
    print(f"{'method':10s} {'belief':>15s} {'walk a':>15s} {'loop a, held out':>16s}")
    for name, values in rows.items():
        m = np.mean(np.array(values), axis=0)
        print(f"{name:10s} {m[0]:+.3f} / {m[1]:.3f} {m[2]:+.3f} / {m[3]:.3f} "
              f"{m[4]:+.3f} / {m[5]:.3f}")


def test_diagnostic(workspaces: list[Path]) -> None:
    """Per workspace and method: confidence − accuracy / ECE the test episodes reported, and
    the evaluate stage's declared_fit kind."""
    for root in workspaces:
        ws = Workspace(root)
        table = EpisodeTable.load(ws.require("evaluate") / EPISODES_FILE)
        kind = ws.config().evaluate.declared_fit
        confidence = table.final_confidence()
        cells = []
        for method in table.methods:
            mine = table.method == method
            right = table.correct[mine].astype(float)
            cells.append(f"{method} {confidence[mine].mean() - right.mean():+.3f} / "
                         f"{expected_calibration_error(confidence[mine], right):.3f}")
        print(f"{str(root):48s} ({kind}) " + "; ".join(cells))


if __name__ == "__main__":
    main()
