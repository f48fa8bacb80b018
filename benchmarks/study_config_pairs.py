"""One configuration of a study against another, method by method, paired across them.

Two configurations of a study that differ only downstream of the dataset (e.g.
``configs/default.yaml`` and ``configs/ensemble.yaml``: the classifier alone) evaluate each
method from the same (test model, start) pairs of a seed, so a method's episodes pair across
the configurations. This prints, for every method both evaluated, its accuracy, energy and
calibration in each, and the paired accuracy difference variant − base pooled over seeds with
the study's two-stage bootstrap (seeds, and test models within them).

    python benchmarks/study_config_pairs.py -s runs/study-ensemble --base default \
        --variant ensemble

With ``--base-study S0`` the base configuration is read from another study (e.g. a copy of
the study with one training option changed: ``--base learned --variant learned``), its seeds
restricted to the variant's.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rapomdp.config import METHOD_NAMES
from rapomdp.experiment.metrics import paired_model_sums
from rapomdp.recognition.belief import expected_calibration_error
from rapomdp.study.bootstrap import SeedClusters, hierarchical_bootstrap
from rapomdp.study.pooled import SeedResult, common_methods, load_seed_results
from rapomdp.study.spec import read_study


def seed_clusters(base: SeedResult, variant: SeedResult, method: str) -> SeedClusters:
    """One seed's test models with their summed paired differences variant − base."""
    try:
        models, sums, pairs = paired_model_sums(variant.table, method, method, base.table)
    except ValueError as exc:
        raise SystemExit(f"seed {base.seed}, {method}: {exc}; the configurations are not "
                         "paired") from None
    return SeedClusters(models, sums, pairs)


def summary(results: list[SeedResult], method: str) -> tuple[float, float, float, float]:
    """Accuracy, energy (m), confidence − accuracy (means over seeds) and the pooled ECE."""
    accuracy, energy, gap, conf_all, correct_all = [], [], [], [], []
    for r in results:
        mine = r.table.method == method
        confidence = r.table.final_confidence()[mine]
        correct = r.table.correct[mine].astype(float)
        accuracy.append(correct.mean())
        energy.append(r.table.energy[mine].mean())
        gap.append(confidence.mean() - correct.mean())
        conf_all.append(confidence)
        correct_all.append(correct)
    return (float(np.mean(accuracy)), float(np.mean(energy)), float(np.mean(gap)),
            expected_calibration_error(np.concatenate(conf_all), np.concatenate(correct_all)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("-s", "--study", type=Path, required=True)
    parser.add_argument("--base", required=True, help="the reference configuration's name")
    parser.add_argument("--variant", required=True, help="the configuration compared with it")
    parser.add_argument("--base-study", type=Path, default=None,
                        help="the study holding the base configuration (default: --study)")
    parser.add_argument("--resamples", type=int, default=10_000)
    args = parser.parse_args()

    def configuration(study: Path, name: str) -> list[SeedResult]:
        spec = read_study(study)
        if spec is None:
            raise SystemExit(f"{study}: not a study folder (no study.yaml)")
        results = load_seed_results(spec, study)
        if name not in results:
            raise SystemExit(f"{study}: no configuration '{name}' (it has "
                             f"{', '.join(results)})")
        return results[name]

    base = configuration(args.base_study or args.study, args.base)
    variant = configuration(args.study, args.variant)
    if args.base_study is not None:  # another study may hold more seeds: the shared ones
        shared = {r.seed for r in variant}
        base = [r for r in base if r.seed in shared]
    if [r.seed for r in base] != [r.seed for r in variant]:
        raise SystemExit(f"the seeds differ: {[r.seed for r in base]} against "
                         f"{[r.seed for r in variant]}")
    seeds = [r.seed for r in base]
    crossed = len({r.dataset_key for r in base}) == 1
    names = ((f"{args.study}/{args.variant}", f"{args.base_study}/{args.base}")
             if args.base_study else (args.variant, args.base))
    print(f"{names[0]} − {names[1]}, seeds {seeds}, paired by (seed, test model, start); "
          "95 % intervals resample seeds and test models\n")
    print(f"| Method | Accuracy {args.base} | Accuracy {args.variant} | Δ accuracy [95 %] | "
          "Energy (m) | Confidence − accuracy | ECE |")
    print("|---|---|---|---|---|---|---|")
    for method in common_methods(base + variant):
        clusters = [seed_clusters(b, v, method) for b, v in zip(base, variant, strict=True)]
        pooled = hierarchical_bootstrap(clusters, args.resamples, 0,
                                        crossed=None if crossed else False)
        (acc_b, en_b, gap_b, ece_b), (acc_v, en_v, gap_v, ece_v) = (
            summary(base, method), summary(variant, method))
        print(f"| {METHOD_NAMES.get(method, method)} | {acc_b:.3f} | {acc_v:.3f} | "
              f"{pooled.estimate:+.3f} [{pooled.low:+.3f}, {pooled.high:+.3f}] | "
              f"{en_b:.3f} → {en_v:.3f} | {gap_b:+.3f} → {gap_v:+.3f} | "
              f"{ece_b:.3f} → {ece_v:.3f} |")


if __name__ == "__main__":
    main()
