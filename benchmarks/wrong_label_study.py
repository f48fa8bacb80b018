"""``observe.wrong_labels``: one study before (none) and one after (auto), the same seeds and
workspaces up to the observe stage. Per configuration and seed, the held-out choice for
RA-POMDP's model and the Classifier's (amount, rule; made on the held-out objects only), then
on the test models each method's accuracy, energy and confidence − accuracy in both studies
and the paired difference after − before over the same (test model, start) pairs, pooled over
seeds with the study's interval (resampling seeds and test models).

    rapomdp study -s S_AFTER -c C1 -c C2 ...      (workspaces hard-linked from S_BEFORE's)
    python benchmarks/wrong_label_study.py --before S_BEFORE --after S_AFTER \\
        --pair default=learned --pair real-cad-dev=real-cad-dev-learned
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from rapomdp.config import METHOD_NAMES
from rapomdp.experiment.episode_table import EpisodeTable
from rapomdp.study.bootstrap import SeedClusters, hierarchical_bootstrap

EPISODES = Path("evaluate") / "episodes.npz"
METHODS = ("ra", "classifier", "random", "vptree", "static", "learned")


def paired_sums(after: EpisodeTable, before: EpisodeTable, method: str
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per test model: summed correct(after) − correct(before) of ``method`` over the same
    (model, start) pairs, and the pair counts (an error if the pairs differ)."""
    rows = []
    for table in (after, before):
        sel = np.flatnonzero(table.method == method)
        keys = np.char.add(np.char.add(table.model[sel].astype(str), "#"),
                           table.start[sel].astype(str))
        order = np.argsort(keys, kind="stable")
        rows.append((keys[order], sel[order], table))
    (keys_a, sel_a, _), (keys_b, sel_b, _) = rows
    if keys_a.shape != keys_b.shape or np.any(keys_a != keys_b):
        raise SystemExit(f"{method}: the two studies did not run the same (model, start) pairs")
    diff = after.correct[sel_a].astype(float) - before.correct[sel_b].astype(float)
    models, cluster = np.unique(after.model[sel_a], return_inverse=True)
    return (models, np.bincount(cluster, weights=diff, minlength=models.size),
            np.bincount(cluster, minlength=models.size).astype(float))


def summary(table: EpisodeTable, method: str) -> tuple[float, float, float]:
    """Accuracy, mean energy (m) and mean confidence (the final belief in the declared
    class) − accuracy."""
    sel = table.method == method
    return (float(table.correct[sel].mean()), float(table.energy[sel].mean()),
            float(table.final_confidence()[sel].mean() - table.correct[sel].mean()))


def choices(workspace: Path) -> str:
    record = json.loads((workspace / "observe" / "calibration.json").read_text())
    made = record.get("wrong_labels", {})
    return "; ".join(f"{name} {made[name]['amount']:g} ({made[name]['rule']})"
                     for name in ("ra", "classifier") if name in made) or "none recorded"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, required=True)
    parser.add_argument("--after", type=Path, required=True)
    parser.add_argument("--pair", action="append", required=True,
                        help="AFTER_CONFIGURATION=BEFORE_CONFIGURATION (repeatable)")
    parser.add_argument("--resamples", type=int, default=10_000)
    args = parser.parse_args()
    print("held-out choice (observe.wrong_labels: auto) and the test models, before (none) → "
          "after (auto); Δ: after − before over the same (test model, start) pairs")
    for pair in args.pair:
        after_name, before_name = pair.split("=")
        seeds = sorted(p.name for p in (args.after / after_name).glob("seed-*"))
        per_method: dict[str, list[SeedClusters]] = {m: [] for m in METHODS}
        print(f"\n{after_name} (before: {before_name}), seeds {', '.join(seeds)}")
        for seed in seeds:
            a_ws, b_ws = args.after / after_name / seed, args.before / before_name / seed
            after, before = (EpisodeTable.load(w / EPISODES) for w in (a_ws, b_ws))
            print(f"  {seed}: chosen {choices(a_ws)}")
            for method in METHODS:
                if method not in after.methods or method not in before.methods:
                    continue
                per_method[method].append(SeedClusters(*paired_sums(after, before, method)))
                (acc_b, e_b, c_b), (acc_a, e_a, c_a) = (summary(t, method)
                                                       for t in (before, after))
                print(f"    {METHOD_NAMES.get(method, method):<12} accuracy {acc_b:.3f} → "
                      f"{acc_a:.3f}, energy {e_b:.2f} → {e_a:.2f} m, conf − acc {c_b:+.3f} → "
                      f"{c_a:+.3f}")
        for method, clusters in per_method.items():
            if len(clusters) == len(seeds) and clusters:
                d = hierarchical_bootstrap(clusters, args.resamples, 0)
                print(f"  pooled Δ accuracy {METHOD_NAMES.get(method, method):<12} "
                      f"{d.estimate:+.3f} [{d.low:+.3f}, {d.high:+.3f}] over {len(clusters)} "
                      "seeds")


if __name__ == "__main__":
    main()
