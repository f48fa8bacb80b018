"""The declared confidence by the number of images taken, held out (round five of
docs/awareness.md §4.8; rule: benchmarks/results/declared_views_rule.md).

For each workspace it runs every moving method's held-out closed loop as the evaluate stage
does (``experiment.held_out.closed_loop_declared``, Random included) and scores, at the stops,
each group's declared confidence by what the *other* groups' stops fit:
- reference (``evaluate.declared_form: scalar``): one a per method (Random: the walks' a at its
  threshold, which the observe stage fitted on every group: in-sample, favouring it);
- candidate (``views``): a(n) = s · n^−β after n images.
It prints confidence − accuracy and ECE for both, by workspace, by episode length and as the
mean over each folder's workspaces (a study configuration), then the rule's three conditions,
then (not part of the rule, added after its decision) the ECE of each folder's held-out stops
pooled over its workspaces, whose sampling floor is lower (``benchmarks/ece_floor.py``).
With ``--auto`` (round six, ``declared_form_auto_rule.md``) it scores
``evaluate.declared_form: auto`` too, nested: each group's stops are declared by the form chosen
on the other groups' stops alone (their own leave-one-group-out criterion) and fitted on them,
and it checks that rule's conditions on the pooled stops instead. A method the configuration
does not evaluate is run where the solve stage has its plan.
Only volume models and their recorded labels are read, never the test models.

    python benchmarks/declared_views.py -w W [W ...] [--methods ...] [--pooled] [--auto]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from rapomdp.context import RunContext
from rapomdp.experiment.held_out import ClosedLoopFit, closed_loop_declared
from rapomdp.pipeline import get_stage
from rapomdp.planning.artefacts import policy_file
from rapomdp.planning.stage import declared_temperatures, offered_observation_models
from rapomdp.recognition.belief import (
    DeclaredConfidence,
    choose_declared_form,
    declared_log_beliefs,
    expected_calibration_error,
    stops_declared_confidence,
)
from rapomdp.workspace import Workspace

LENGTHS = ((1, 2), (3, 4), (5, 7), (8, 10_000))
"""Episode lengths (images taken) the calibration is also shown by."""
PAIRS = ("ra", "classifier")
"""The methods condition 1 of the rule names."""


def held_out_confidence(fit: ClosedLoopFit, declared: DeclaredConfidence | None,
                        walk_a: float | None = None) -> np.ndarray:
    """Each stop's declared confidence, its group's by the fit on the other groups
    (``declared``'s held-out readouts; ``walk_a``: one a for every stop instead)."""
    if declared is None:
        return np.exp(declared_log_beliefs(fit.log_beliefs, walk_a).max(axis=1))
    out = np.empty(len(fit.truth))
    for g, a in declared.held_out_readouts.items():
        mine = fit.groups == g
        out[mine] = np.exp(declared_log_beliefs(fit.log_beliefs[mine],
                                                a.at(fit.images[mine])).max(axis=1))
    return out


def nested_auto_confidence(fit: ClosedLoopFit, walk_a: float | None, margin_se: float = 0.0
                           ) -> tuple[np.ndarray, dict[int, str]]:
    """Each stop's declared confidence under ``declared_form: auto``, scored held out: its
    group's stops are declared by the form chosen on the other groups' stops alone (with
    their own leave-one-group-out criterion; Random's scalar: the walks' ``walk_a``; views
    asked to win by ``margin_se`` standard errors, clustered by object) and fitted on those
    groups; per group, the form chosen."""
    out = np.empty(len(fit.truth))
    forms = {}
    objects = fit.run.objects()
    for g in np.unique(fit.groups):
        mine = fit.groups == g
        rest = ~mine
        choice = choose_declared_form(fit.log_beliefs[rest], fit.truth[rest], fit.groups[rest],
                                      fit.images[rest], fixed_scalar=walk_a,
                                      margin_se=margin_se, objects=objects[rest])
        forms[int(g)] = choice.form
        a = (walk_a if choice.declared is None
             else choice.declared.readout.at(fit.images[mine]))
        out[mine] = np.exp(declared_log_beliefs(fit.log_beliefs[mine], a).max(axis=1))
    return out, forms


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    parser.add_argument("--methods", nargs="+",
                        default=["ra", "classifier", "vptree", "random", "learned"])
    parser.add_argument("--pooled", action="store_true",
                        help="decide on each folder's held-out stops pooled over its "
                             "workspaces (declared_views_rule_v2.md)")
    parser.add_argument("--auto", action="store_true",
                        help="score declared_form auto too, nested, and check "
                             "declared_form_auto_rule.md's conditions")
    parser.add_argument("--margins", type=float, nargs="*", default=[],
                        help="with --auto, after the rule (deciding nothing): the pooled ECE "
                             "when views must win by each of these many standard errors")
    args = parser.parse_args()
    margins: dict[tuple[str, str], list[np.ndarray]] = {}
    candidate = "auto (nested)" if args.auto else "views"
    rows: dict[tuple[str, str], list[tuple[float, float, float, float]]] = {}
    stops: dict[tuple[str, str], list[np.ndarray]] = {}
    print(f"{'workspace':44s} {'method':10s} {'stops':>5s} {'acc':>6s} "
          f"{'scalar: c-a / ECE':>18s} {candidate + ': c-a / ECE':>17s} {'s':>6s} "
          f"{'beta':>6s}" + ("  (s, beta: views fitted on every group)" if args.auto else ""))
    for root in args.workspace:
        ws = Workspace(root)
        config = ws.config()
        inputs = ws.inputs(get_stage("evaluate"))
        methods = [m for m in args.methods if m in config.evaluate.methods
                   or args.auto and (inputs.solve / policy_file(m)).is_file()]
        with tempfile.TemporaryDirectory() as tmp:
            fits = closed_loop_declared(config, inputs, methods, Path(tmp),
                                        RunContext(progress=False), form="views")
        walk = config.evaluate.random
        observation, _ = offered_observation_models(inputs.observe, inputs.vptree_dir)
        for name, fit in fits.items():
            right = (fit.log_beliefs.argmax(axis=1) == fit.truth).astype(float)
            walk_a = (declared_temperatures(
                inputs.observe, {walk.observation_model: observation[walk.observation_model]},
                inputs.vptree_dir, walk.belief_threshold)[walk.observation_model]
                      if name == "random" else None)
            scalar = held_out_confidence(
                fit, None if walk_a is not None else
                stops_declared_confidence(fit.log_beliefs, fit.truth, fit.groups), walk_a)
            views = held_out_confidence(fit, fit.declared)
            if args.auto:  # the candidate of declared_form_auto_rule.md in the third column
                views, forms = nested_auto_confidence(fit, walk_a)
                margins.setdefault((root.parent.name, name), []).append(np.stack(
                    [right, scalar, *(nested_auto_confidence(fit, walk_a, k)[0]
                                      for k in args.margins)]))
            gaps = (scalar.mean() - right.mean(), expected_calibration_error(scalar, right),
                    views.mean() - right.mean(), expected_calibration_error(views, right))
            rows.setdefault((root.parent.name, name), []).append(gaps)
            stops.setdefault((root.parent.name, name), []).append(
                np.stack([right, scalar, views]))
            d = fit.declared
            print(f"{str(root):44s} {name:10s} {fit.episodes:5d} {right.mean():6.3f} "
                  f"{gaps[0]:+8.3f} / {gaps[1]:.3f} {gaps[2]:+8.3f} / {gaps[3]:.3f} "
                  f"{d.temperature:6.3f} {d.views_exponent:+6.3f}"
                  + (f"  auto, by held-out group: {forms}" if args.auto else ""))
            for low, high in LENGTHS:
                k = (fit.images >= low) & (fit.images <= high)
                if k.sum() >= 10:
                    print(f"{'':44s}   {low}-{min(high, 99)} images: {int(k.sum()):4d} stops, "
                          f"accuracy {right[k].mean():.3f}, confidence scalar "
                          f"{scalar[k].mean():.3f} views {views[k].mean():.3f}")
    print(f"\nmean over each folder's workspaces (held out): scalar c-a / ECE -> {candidate} "
          "c-a / ECE")
    mean = {key: np.mean(np.array(v), axis=0) for key, v in rows.items()}
    for (folder, name), m in mean.items():
        print(f"{folder:24s} {name:10s} {m[0]:+.3f} / {m[1]:.3f} -> {m[2]:+.3f} / {m[3]:.3f}  "
              f"({len(rows[folder, name])} workspaces)")
    pooled = {}
    for key, parts in stops.items():
        right, scalar, views = np.concatenate(parts, axis=1)
        pooled[key] = np.array([scalar.mean() - right.mean(),
                                expected_calibration_error(scalar, right),
                                views.mean() - right.mean(),
                                expected_calibration_error(views, right), right.size])
    over_pooled = "each folder's held-out stops pooled over its workspaces"
    if args.auto:  # declared_form_auto_rule.md: its conditions on the pooled stops
        print_pooled(pooled, f"{over_pooled}:", candidate)
        print_auto_rule(pooled)
        if args.margins:
            print("\nafter the rule, deciding nothing: pooled ECE, scalar and auto with views "
                  "asked to win by k standard errors (clustered by object)")
            for (folder, name), parts in margins.items():
                right, *confidences = np.concatenate(parts, axis=1)
                eces = [expected_calibration_error(c, right) for c in confidences]
                print(f"{folder:24s} {name:10s} scalar {eces[0]:.3f}  " + "  ".join(
                    f"k={k:g}: {e:.3f}" for k, e in zip(args.margins, eces[1:], strict=True)))
        return
    if args.pooled:  # declared_views_rule_v2.md: the conditions on the pooled stops
        print_pooled(pooled, f"{over_pooled}:")
        print_rule(pooled, over_pooled)
        return
    print_rule(mean, "the mean over each folder's workspaces (declared_views_rule.md)")
    print_pooled(pooled, f"not part of the rule: {over_pooled},")


def print_pooled(pooled: dict[tuple[str, str], np.ndarray], title: str,
                 candidate: str = "views") -> None:
    """Per (folder, method) the pooled stops' scalar and candidate c − a / ECE, and their
    count."""
    print(f"\n{title} scalar c-a / ECE -> {candidate} c-a / ECE")
    for (folder, name), m in pooled.items():
        print(f"{folder:24s} {name:10s} {m[0]:+.3f} / {m[1]:.3f} -> {m[2]:+.3f} / {m[3]:.3f}"
              f"  ({int(m[4])} stops)")


def print_rule(figures: dict[tuple[str, str], np.ndarray], over: str) -> None:
    """The rule's three conditions on ``figures`` (per (folder, method): scalar c − a, ECE,
    views c − a, ECE); a folder named like ``mesh`` is checked by condition 3 only."""
    folders = sorted({folder for folder, _ in figures})
    decisive = [f for f in folders if "mesh" not in f]
    one = all(figures[f, n][3] < figures[f, n][1] for f in decisive for n in PAIRS
              if (f, n) in figures)
    moving = [key for key in figures if key[0] in decisive]
    drop = float(np.mean([figures[k][1] - figures[k][3] for k in moving])) if moving else 0.0
    worst = max((abs(m[2]) - abs(m[0]) for m in figures.values()), default=0.0)
    print(f"\nthe rule on {over}")
    print(f"rule 1 (RA and Classifier ECE fall on {', '.join(decisive)}): {one}")
    print(f"rule 2 (mean ECE falls by >= 0.01 over the methods and those sets): {drop:+.4f} "
          f"-> {drop >= 0.01}")
    print(f"rule 3 (no |c-a| grows by > 0.02 on any set): largest growth {worst:+.4f} -> "
          f"{worst <= 0.02}")


def print_auto_rule(figures: dict[tuple[str, str], np.ndarray]) -> None:
    """declared_form_auto_rule.md's three conditions on the pooled ``figures`` (per (folder,
    method): scalar c − a, ECE, auto c − a, ECE); a folder named like ``mesh`` is checked by
    condition 3 only."""
    decisive = [key for key in figures if "mesh" not in key[0]]
    rises = {key: figures[key][3] - figures[key][1] for key in decisive}
    one = all(rise <= (0.002 if key[1] == "ra" else 0.01) for key, rise in rises.items())
    drop = -float(np.mean(list(rises.values()))) if rises else 0.0
    worst = max((abs(m[2]) - abs(m[0]) for m in figures.values()), default=0.0)
    print("\nthe rule on each folder's held-out stops pooled over its workspaces "
          "(declared_form_auto_rule.md)")
    print("rule 1 (RA's ECE rises by <= 0.002, any other's by <= 0.01, on the sets other than "
          f"the mesh set): {one}; largest rise "
          + ", ".join(f"{f} {n} {r:+.4f}" for (f, n), r in
                      sorted(rises.items(), key=lambda kv: -kv[1])[:3]))
    print(f"rule 2 (mean ECE falls by >= 0.01 over those methods and sets): {drop:+.4f} -> "
          f"{drop >= 0.01}")
    print(f"rule 3 (no |c-a| grows by > 0.02 on any set): largest growth {worst:+.4f} -> "
          f"{worst <= 0.02}")


if __name__ == "__main__":
    main()
