"""Does the declared-confidence a depend on how much evidence the model was counted on?
Held out only (volume models; never the test models).

The closed-loop a (``evaluate.declared_fit: closed_loop``) is fitted on models counted on two
of the three volume groups and applied to the test-time model counted on all three. If a
model counted on more objects is sharper, its belief is more overconfident and needs a
smaller a, and the two-group a under-corrects at test time. This prints, per workspace and
method, the a fitted at the held-out closed-loop stops of models counted on *one* group (run
on each of the other groups' models) beside the pipeline's two-group a: a one-group a above
the two-group a says a grows with less evidence, so a three-group model would want less.

    python benchmarks/declared_fold_size.py -w W [W ...] [--methods ra classifier]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from rapomdp.awareness.choices import RecordedObservation
from rapomdp.awareness.shrinkage import shrink_wrong_labels
from rapomdp.awareness.variants import fit_observation_models
from rapomdp.context import RunContext
from rapomdp.experiment.episode import Motion
from rapomdp.experiment.held_out import (
    HeldOutFold,
    closed_loop_declared,
    held_out_stops,
)
from rapomdp.experiment.methods import POMDPPolicy
from rapomdp.pipeline import get_stage
from rapomdp.planning.artefacts import policy_file
from rapomdp.planning.policy import ActiveRecognitionPolicy
from rapomdp.recognition.belief import stops_declared_confidence, temper
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import Workspace


def one_group_a(ws: Workspace, name: str) -> tuple[float, int]:
    """The a fitted at the closed-loop stops of ``name``'s models counted on one volume group
    each, run on every other group's models (the solve stage's plan), and the stops."""
    config = ws.config()
    inputs = ws.inputs(get_stage("evaluate"))
    recorded = RecordedObservation.load(inputs.observe)
    evidence, calibration = recorded.evidence, recorded.calibration
    key = recorded.variant if name == "ra" else name
    t = float(calibration["temperatures"][name])
    amount = float(calibration.get("wrong_labels", {}).get(key, {}).get("amount", 0.0))
    motion = Motion.from_robot(load_robot(inputs.robot))
    plan = ActiveRecognitionPolicy.load(inputs.solve / policy_file(name))
    groups = np.unique(evidence.groups)
    finals, truths, run_groups = [], [], []
    for k in groups:
        mine = evidence.groups == k
        single = fit_observation_models(evidence.subset(mine), recorded.scores,
                                        recorded.classes, config.observe,
                                        recorded.arrays["directions"],
                                        recorded.transfer_kernel, [key])[key].probabilities
        model = temper(shrink_wrong_labels(single, amount), t)
        for g in groups[groups != k]:
            rows = evidence.groups == g
            fold = HeldOutFold(int(g), evidence.labels[rows], evidence.predicted[rows], model)
            log_b, truth, *_ = held_out_stops(
                config, POMDPPolicy.configured(config.evaluate, plan, model, name,
                                               motion.reachable),
                fold, motion)
            finals.append(log_b)
            truths.append(truth)
            run_groups.append(np.full(len(truth), k))
    fit = stops_declared_confidence(np.concatenate(finals), np.concatenate(truths),
                                    np.concatenate(run_groups))
    return fit.temperature, fit.stops


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    parser.add_argument("--methods", nargs="+", default=["ra", "classifier"])
    args = parser.parse_args()
    print(f"{'workspace':48s} {'method':10s} {'a, 1 group':>10s} {'stops':>5s} "
          f"{'a, 2 groups':>11s} {'stops':>5s}")
    pairs = []
    for root in args.workspace:
        ws = Workspace(root)
        with tempfile.TemporaryDirectory() as tmp:
            fits = closed_loop_declared(ws.config(), ws.inputs(get_stage("evaluate")),
                                        args.methods, Path(tmp), RunContext(progress=False))
        for name in args.methods:
            a1, n1 = one_group_a(ws, name)
            a2 = fits[name].declared.temperature
            pairs.append((a1, a2))
            print(f"{str(root):48s} {name:10s} {a1:10.3f} {n1:5d} {a2:11.3f} "
                  f"{fits[name].episodes:5d}")
    a = np.array(pairs)
    print(f"\none group's a above two groups' in {int((a[:, 0] > a[:, 1]).sum())} of {len(a)}; "
          f"mean a: one group {a[:, 0].mean():.3f}, two groups {a[:, 1].mean():.3f}")


if __name__ == "__main__":
    main()
