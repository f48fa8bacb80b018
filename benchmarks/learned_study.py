"""The learned baseline over a study's seeds: its training (time, plateau, held-out rows, which
are in-sample for it) per configuration and seed, and the pooled comparison on the test models
of Learned, RA-POMDP and Random (from the study report's ``table1_pooled.csv``).

    rapomdp study -s S -c configs/learned.yaml -c configs/real-cad-dev-learned.yaml
    python benchmarks/learned_study.py -s S
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

from rapomdp.config import METHOD_NAMES
from rapomdp.experiment.metrics import paired_model_sums
from rapomdp.study.bootstrap import SeedClusters, hierarchical_bootstrap
from rapomdp.study.pooled import load_seed_results
from rapomdp.study.spec import read_study

#: The methods of the comparison, by key.
COMPARED = ("learned", "ra", "random")


def training_lines(workspace: Path) -> list[str]:
    """One line per λ of a seed's learn stage, and its held-out rows."""
    record = json.loads((workspace / "learn" / "learn.json").read_text())
    seconds = record["seconds"]
    lines = [f"  learn stage {seconds['total']:.0f} s wall, {seconds['train_cpu']:.0f} s CPU "
             f"of training; evidence: {record['evidence']['models']} held-out models"]
    for lam, policy in sorted(record["policies"].items(), key=lambda kv: float(kv[0])):
        final = policy["final"]
        lines.append(f"  λ = {float(lam):g} m: {final['timesteps']:.0f} steps, "
                     f"{policy['cpu_seconds']:.0f} s CPU, plateau at "
                     f"{policy['plateau_timesteps']:.0f} steps; last update: accuracy "
                     f"{final['accuracy']:.3f}, energy {final['mean_energy']:.3f} m")
    lines.append(f"  held out ({record.get('held_out_note', '')}):")
    for row in record["held_out"]:
        lines.append(f"    {row['method']} {row['parameter']} {row['value']:g}: accuracy "
                     f"{row['accuracy']:.3f}, energy {row['mean_energy']:.3f} m, "
                     f"{row['mean_moves']:.2f} moves")
    return lines


def learned_minus_random(study: Path, resamples: int = 10_000) -> list[str]:
    """Per configuration, Learned's paired accuracy minus Random's over the same (test model,
    start) pairs, pooled over seeds with the study's interval (seeds and test models)."""
    spec = read_study(study)
    if spec is None:
        return []
    lines = []
    for name, seeds in load_seed_results(spec, study).items():
        if not all({"learned", "random"} <= set(r.table.methods) for r in seeds):
            continue
        clusters = [SeedClusters(*paired_model_sums(r.table, "learned", "random"))
                    for r in seeds]
        crossed = len({r.dataset_key for r in seeds}) == 1
        d = hierarchical_bootstrap(clusters, resamples, 0, crossed=None if crossed else False)
        lines.append(f"{name:<24}Learned − Random: {d.estimate:+.3f} [{d.low:+.3f}, "
                     f"{d.high:+.3f}] over {len(seeds)} seeds")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", "-s", type=Path, required=True)
    args = parser.parse_args()
    names = {METHOD_NAMES.get(k, k).lower(): k for k in COMPARED} | {k: k for k in COMPARED}
    pooled = args.study / "report" / "table1_pooled.csv"
    if not pooled.is_file():
        parser.error(f"{pooled}: no study report (run rapomdp study -s {args.study} first)")
    with open(pooled, newline="") as handle:
        rows = [r for r in csv.DictReader(handle) if r["method"].lower() in names]
    print("pooled over the study's seeds, on the test models (Δ: method − RA-POMDP, 95 % "
          "interval resampling seeds and test models)")
    print(f"{'configuration':<24}{'method':<16}{'accuracy':>9}{'energy m':>10}{'moves':>7}"
          f"{'conf-acc':>9}  Δ vs RA-POMDP")
    for r in rows:
        delta = (f"{float(r['difference_vs_ra']):+.3f} [{float(r['ci95_low']):+.3f}, "
                 f"{float(r['ci95_high']):+.3f}]" if r["difference_vs_ra"] else "—")
        print(f"{r['dataset']:<24}{r['method']:<16}{float(r['accuracy']):>9.3f}"
              f"{float(r['energy_m']):>10.3f}{float(r['moves']):>7.2f}"
              f"{float(r['confidence_minus_accuracy']):>+9.3f}  {delta}")
    print("\n".join(learned_minus_random(args.study)))
    print()
    for learn in sorted(args.study.glob("*/seed-*/learn/learn.json")):
        workspace = learn.parent.parent
        print(f"{workspace.parent.name} {workspace.name}:")
        print("\n".join(training_lines(workspace)))


if __name__ == "__main__":
    main()
