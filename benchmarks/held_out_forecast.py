"""How well the evaluate stage's held-out comparison forecasts Table 1.

For every workspace, each method's paired accuracy difference to RA-POMDP on the held-out
volume models (``evaluate/held_out/comparison.json``, written before any test model is read)
beside the same difference on the test models (``evaluate/paired.csv``, Table 1's Δ column),
each with its 95 % interval; then, per method, on how many workspaces the two have the same
sign, and on how many a held-out interval that excludes 0 is followed by a test difference of
the same sign. Then, for the workspaces that share a parent folder (one set's seeds), both
differences pooled over the seeds as ``rapomdp study`` pools them (its report shows the same
two columns): seeds × held-out objects, and seeds × test models. A diagnostic: it reads the
test models' results, so nothing here may drive a choice.

    python benchmarks/held_out_forecast.py -w W [W ...] [--gaps]

``--gaps``: the forecast's error per workspace and method, e = test Δ − held-out Δ, and per set
(the workspaces' parent folder) its mean over the seeds with a Student-t 95 % interval over
seeds, then the same over every seed of the sets whose folder name starts with ``real-cad``
(benchmarks/results/forecast_gap_rule.md). Each seed's held-out objects and test models are
different objects, so its e carries both samples' noise and the seeds are its replicates.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np
from scipy import stats

from rapomdp.config import METHOD_NAMES
from rapomdp.experiment.episode_table import EPISODES_FILE, PAIRED_CSV, EpisodeTable
from rapomdp.experiment.held_out import load_held_out_comparison
from rapomdp.study.pooled import SeedResult, held_out_table, pooled_table
from rapomdp.workspace import Workspace


def table1_differences(evaluate: Path) -> dict[str, tuple[float, float, float]]:
    """Table 1's paired differences to RA-POMDP: method -> (difference, low, high)."""
    with open(evaluate / PAIRED_CSV, newline="") as handle:
        return {row["method"]: (float(row["accuracy_difference"]), float(row["ci95_low"]),
                                float(row["ci95_high"])) for row in csv.DictReader(handle)}


def sign(value: float) -> int:
    return (value > 0) - (value < 0)


def seed_results(roots: list[Path]) -> list[SeedResult]:
    """One set's workspaces as ``rapomdp study`` pools them (their evaluated episodes)."""
    return [SeedResult(root.parent.name, i, root,
                       EpisodeTable.load(root / "evaluate" / EPISODES_FILE), [],
                       str(Workspace(root).manifest()["stages"]["dataset"]["key"]))
            for i, root in enumerate(roots)]


def t_interval(values: list[float]) -> tuple[float, float, float]:
    """Mean and Student-t 95 % interval over replicates."""
    x = np.asarray(values, dtype=np.float64)
    half = (float(stats.t.ppf(0.975, x.size - 1) * x.std(ddof=1) / np.sqrt(x.size))
            if x.size > 1 else float("inf"))
    return float(x.mean()), float(x.mean() - half), float(x.mean() + half)


def print_gaps(errors: dict[Path, dict[str, list[float]]]) -> None:
    """``--gaps``: the forecast's error e per set and method over its seeds, then pooled over
    the real-CAD sets."""
    print("\nthe forecast's error e = test Δ − held-out Δ per seed; mean over seeds, Student-t "
          "95 % over seeds")
    pooled: dict[str, list[float]] = {}
    for parent, by_method in errors.items():
        for method, values in by_method.items():
            mean, low, high = t_interval(values)
            print(f"  {parent.name:22s} {METHOD_NAMES.get(method, method):12s} e {mean:+.3f} "
                  f"[{low:+.3f}, {high:+.3f}] over {len(values)} seeds (per seed "
                  + " / ".join(f"{v:+.3f}" for v in values) + ")")
            if parent.name.startswith("real-cad"):
                pooled.setdefault(method, []).extend(values)
    for method, values in pooled.items():
        mean, low, high = t_interval(values)
        print(f"  {'real-CAD sets together':22s} {METHOD_NAMES.get(method, method):12s} e "
              f"{mean:+.3f} [{low:+.3f}, {high:+.3f}] over {len(values)} seeds")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    parser.add_argument("--gaps", action="store_true",
                        help="the forecast's error per set over seeds (above)")
    args = parser.parse_args()
    errors: dict[Path, dict[str, list[float]]] = {}
    print("Δ: a method's accuracy minus RA-POMDP's over the same (object, start) pairs; "
          "held out: the volume models; test: Table 1's test models")
    print(f"{'workspace':44s} {'method':12s} {'held-out Δ [95 %]':>28s} "
          f"{'test Δ [95 %]':>28s}")
    same: dict[str, list[bool]] = {}
    confident: dict[str, list[bool]] = {}
    for root in args.workspace:
        record = load_held_out_comparison(root / "evaluate")
        if record is None:
            print(f"{str(root):44s} no held-out comparison (rerun its evaluate stage)")
            continue
        tested = table1_differences(root / "evaluate")
        for method, held in record["paired"].items():
            if method not in tested:
                continue
            d, low, high = tested[method]
            h = held["difference"]
            print(f"{str(root):44s} {METHOD_NAMES.get(method, method):12s} "
                  f"{h:+8.3f} [{held['low']:+.3f}, {held['high']:+.3f}]  "
                  f"{d:+8.3f} [{low:+.3f}, {high:+.3f}]")
            same.setdefault(method, []).append(sign(h) == sign(d))
            errors.setdefault(root.parent, {}).setdefault(method, []).append(d - h)
            if held["low"] > 0 or held["high"] < 0:
                confident.setdefault(method, []).append(sign(h) == sign(d))
    print("\nper method: workspaces whose held-out and test differences have the same sign; "
          "of those whose held-out interval excludes 0, how many the test follows")
    for method, agree in same.items():
        sure = confident.get(method, [])
        print(f"  {METHOD_NAMES.get(method, method):12s} same sign {sum(agree)} of "
              f"{len(agree)}; held-out interval clear of 0 on {len(sure)}, test the same "
              f"sign on {sum(sure)}")

    sets: dict[Path, list[Path]] = {}
    for root in args.workspace:
        sets.setdefault(root.parent, []).append(root)
    print("\npooled over each set's seeds (95 %: seeds x held-out objects | seeds x test models)")
    for parent, roots in sets.items():
        results = seed_results(roots)
        pooled_test = {r.method: r.difference for r in pooled_table(results)}
        for row in held_out_table(results):
            held, test = row.difference, pooled_test.get(row.method)
            if held is None or test is None:
                continue
            print(f"  {parent.name:16s} {row.name:12s} held out {held.estimate:+.3f} "
                  f"[{held.low:+.3f}, {held.high:+.3f}]   test {test.estimate:+.3f} "
                  f"[{test.low:+.3f}, {test.high:+.3f}]   ({len(roots)} seeds)")
    if args.gaps:
        print_gaps(errors)


if __name__ == "__main__":
    main()
