"""Per-fold plans for the held-out closed loop (``evaluate.declared_fit: closed_loop_per_fold``)
against the solve stage's plan (``closed_loop``), on workspaces that differ only in that
setting; rule ``benchmarks/results/per_fold_plans_rule.md``.

Per set (the workspaces that share a parent folder, paired with the other side by set and
seed name), it prints:

- **D1, held out only**: the POMDP methods' leave-one-group-out ECE of the declared confidence
  at their held-out closed-loop stops (``evaluate/held_out/declared_fit.json``), pooled over
  the seeds weighted by stops, for both settings; the evaluate stage's seconds; and the rule's
  verdict over the sets. Then, held out too, each planned method's held-out accuracy and
  energy (``evaluate/held_out/comparison.json``, mean of the seeds) under both settings: what
  taking the held-out group out of the plan costs each.
- **M1, with ``--test`` only** (it reads the test models, so it chooses nothing): each method's
  held-out Δ to RA-POMDP pooled over the seeds as ``rapomdp study`` pools it, for both
  settings, beside the test Δ; and the mean |held-out Δ − test Δ| of each setting. Then the
  test episodes' confidence − accuracy and ECE of every method under each setting (the actions
  are the same; only the declared confidence's a differs).

    python benchmarks/per_fold_plans.py --stage S/set/seed-0 ... --per-fold P/set/seed-0 ...
        [--test]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from rapomdp.config import METHOD_NAMES
from rapomdp.experiment.held_out import load_held_out_comparison
from rapomdp.study.pooled import held_out_table, pooled_table
from rapomdp.workspace import Workspace

sys.path.insert(0, str(Path(__file__).parent))
from held_out_forecast import seed_results  # noqa: E402

POMDPS = ("ra", "classifier")
PLANNED = (*POMDPS, "vptree")


def held_out_means(roots: list[Path], method: str) -> tuple[float, float]:
    """(held-out accuracy, energy in m) of ``method``, the mean of the workspaces'."""
    rows = []
    for root in roots:
        record = load_held_out_comparison(root / "evaluate")
        if record is None:
            raise SystemExit(f"{root}: no held-out comparison (rerun its evaluate stage)")
        rows.append((record["methods"][method]["accuracy"],
                     record["methods"][method]["energy_m"]))
    accuracy, energy = np.mean(rows, axis=0)
    return float(accuracy), float(energy)


def by_set(roots: list[Path]) -> dict[str, dict[str, Path]]:
    """set name -> seed folder name -> workspace."""
    sets: dict[str, dict[str, Path]] = {}
    for root in roots:
        sets.setdefault(root.parent.name, {})[root.name] = root
    return sets


def held_out_ece(roots: list[Path], method: str) -> tuple[float, int]:
    """(the held-out declared ECE pooled over the workspaces weighted by stops, stops)."""
    eces, stops = [], []
    for root in roots:
        record = json.loads((root / "evaluate" / "held_out" / "declared_fit.json").read_text())
        fit = record["methods"][method]["declared_confidence"]
        eces.append(float(fit["declared_ece"]))
        stops.append(int(fit["stops"]))
    return float(np.average(eces, weights=stops)), int(sum(stops))


def evaluate_seconds(roots: list[Path]) -> float:
    return sum(float(Workspace(r).manifest()["stages"]["evaluate"].get("seconds", 0.0))
               for r in roots)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stage", type=Path, nargs="+", required=True,
                        help="workspaces run with evaluate.declared_fit: closed_loop")
    parser.add_argument("--per-fold", type=Path, nargs="+", required=True,
                        help="the same workspaces run with closed_loop_per_fold")
    parser.add_argument("--test", action="store_true",
                        help="also M1: read the test models (chooses nothing)")
    args = parser.parse_args()
    stage, per_fold = by_set(args.stage), by_set(args.per_fold)
    if stage.keys() != per_fold.keys() or any(stage[s].keys() != per_fold[s].keys()
                                              for s in stage):
        raise SystemExit("--stage and --per-fold must name the same sets and seeds")
    names = {s: sorted(stage[s]) for s in stage}
    sides = {"closed_loop": stage, "closed_loop_per_fold": per_fold}

    print("D1 (held out only): POMDP methods' leave-one-group-out ECE of the declared "
          "confidence at their held-out stops, pooled over seeds (weighted by stops)")
    print(f"{'set':22s} {'method':12s} {'stops':>6s} {'closed_loop':>12s} {'per_fold':>10s}")
    means: dict[str, dict[str, float]] = {}
    for name in stage:
        ece = {side: {m: held_out_ece([sets[name][s] for s in names[name]], m)
                      for m in POMDPS} for side, sets in sides.items()}
        means[name] = {side: float(np.mean([e for e, _ in by.values()]))
                       for side, by in ece.items()}
        for method in POMDPS:
            (a, stops), (b, _) = ece["closed_loop"][method], ece["closed_loop_per_fold"][method]
            print(f"{name:22s} {METHOD_NAMES[method]:12s} {stops:6d} {a:12.3f} {b:10.3f}")
        seconds = {side: evaluate_seconds([sets[name][s] for s in names[name]])
                   for side, sets in sides.items()}
        print(f"{name:22s} {'mean of two':12s} {'':6s} {means[name]['closed_loop']:12.3f} "
              f"{means[name]['closed_loop_per_fold']:10.3f}   evaluate stage "
              f"{seconds['closed_loop']:.0f} s -> {seconds['closed_loop_per_fold']:.0f} s "
              f"over {len(names[name])} seeds")
    lower_everywhere = all(m["closed_loop_per_fold"] < m["closed_loop"] for m in means.values())
    fall = float(np.mean([m["closed_loop"] - m["closed_loop_per_fold"]
                          for m in means.values()]))
    adopt = lower_everywhere and fall >= 0.01
    print(f"per_fold lower on every set: {lower_everywhere}; mean fall over the sets "
          f"{fall:+.4f} (the rule asks >= 0.01): "
          f"{'adopt closed_loop_per_fold' if adopt else 'closed_loop stays the default'}")

    print("\nheld out: each planned method's accuracy and energy (m), mean of the seeds, with the "
          "solve stage's plan -> each fold's own plan")
    for name in stage:
        for method in PLANNED:
            a, ea = held_out_means([stage[name][s] for s in names[name]], method)
            b, eb = held_out_means([per_fold[name][s] for s in names[name]], method)
            print(f"{name:22s} {METHOD_NAMES[method]:12s} {a:.3f} -> {b:.3f} ({b - a:+.3f})   "
                  f"energy {ea:.2f} -> {eb:.2f}")
    if not args.test:
        return

    print("\nM1 (reads the test models; chooses nothing): Δ = method − RA-POMDP, pooled over "
          "seeds (95 %: seeds x held-out objects | seeds x test models)")
    errors: dict[str, list[float]] = {side: [] for side in sides}
    for name in stage:
        results = {side: seed_results([sets[name][s] for s in names[name]])
                   for side, sets in sides.items()}
        tested = {r.method: r.difference for r in pooled_table(results["closed_loop"])}
        held = {side: {r.method: r.difference for r in held_out_table(res)}
                for side, res in results.items()}
        for method, t in tested.items():
            x, y = held["closed_loop"].get(method), held["closed_loop_per_fold"].get(method)
            if t is None or x is None or y is None:
                continue
            errors["closed_loop"].append(abs(x.estimate - t.estimate))
            errors["closed_loop_per_fold"].append(abs(y.estimate - t.estimate))
            print(f"  {name:22s} {METHOD_NAMES.get(method, method):12s} held out: stage plan "
                  f"{x.estimate:+.3f} [{x.low:+.3f}, {x.high:+.3f}]  per fold "
                  f"{y.estimate:+.3f} [{y.low:+.3f}, {y.high:+.3f}]   test {t.estimate:+.3f} "
                  f"[{t.low:+.3f}, {t.high:+.3f}]")
    for side, values in errors.items():
        print(f"  mean |held-out Δ − test Δ| over {len(values)} (set, method) cells, {side}: "
              f"{np.mean(values):.4f}")
    print("\ntest episodes' confidence − accuracy / ECE, pooled over seeds (same actions)")
    for name in stage:
        rows = {side: {r.method: r for r in pooled_table(
            seed_results([sets[name][s] for s in names[name]]))}
            for side, sets in sides.items()}
        for method, row in rows["closed_loop"].items():
            other = rows["closed_loop_per_fold"][method]
            print(f"  {name:22s} {row.name:14s} accuracy {row.accuracy:.3f} | "
                  f"{other.accuracy:.3f}   stage plan {row.overconfidence:+.3f} / "
                  f"{row.ece:.3f}   per fold {other.overconfidence:+.3f} / {other.ece:.3f}")


if __name__ == "__main__":
    main()
