"""Stage 2 of benchmarks/results/ra_mixture_rule_v2.md: RA-POMDP with ``observe.ra_model:
mixture`` against ``auto`` in the evaluate stage's held-out closed loop (the volume models,
each group by the models and plans fitted without it; no test episode is read).

Each workspace ``BASE/<set>/seed-<n>`` (as it is) is paired with ``CANDIDATE/<set>/seed-<n>``
(its hard-linked copy run with ``observe.ra_model=mixture``). Per workspace and pooled per set:
RA-POMDP's held-out accuracy and energy, and its paired change per object (the same objects
and starts: RA-POMDP's lead over Random, whose episodes are the same in both, under the
candidate minus under the base) with a bootstrap interval over the (seed, object) clusters;
then the rule's decision.

    python benchmarks/ra_mixture_closed_loop.py --base runs/fresh --candidate runs/fresh-mix \\
        [--sets learned real-cad-dev-learned real-cad-dev-2 mesh-set] [--seeds 5 6 7]
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from rapomdp.experiment.held_out import load_held_out_comparison
from rapomdp.experiment.metrics import cluster_bootstrap_difference


def held_out(workspace: Path) -> dict[str, Any]:
    """The evaluate stage's held-out comparison of ``workspace``."""
    record = load_held_out_comparison(workspace / "evaluate")
    if record is None:
        raise SystemExit(f"{workspace}: no held-out closed loop (run the evaluate stage first)")
    return record


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", type=Path, required=True)
    parser.add_argument("--candidate", type=Path, required=True)
    parser.add_argument("--sets", nargs="+",
                        default=["learned", "real-cad-dev-learned", "real-cad-dev-2", "mesh-set"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[5, 6, 7])
    args = parser.parse_args()
    changes = {}
    for name in args.sets:
        sums, pairs, accuracy = [], [], []
        for seed in args.seeds:
            base = held_out(args.base / name / f"seed-{seed}")
            cand = held_out(args.candidate / name / f"seed-{seed}")
            b, c = base["methods"], cand["methods"]
            if b["random"]["accuracy"] != c["random"]["accuracy"]:
                raise SystemExit(f"{name} seed {seed}: Random's held-out episodes differ")
            # paired sums are (method - RA-POMDP) per object: Random's under the base minus
            # under the candidate is RA-POMDP's change per object
            pb, pc = base["paired"]["random"]["per_object"], cand["paired"]["random"]["per_object"]
            if pb["objects"] != pc["objects"] or pb["pairs"] != pc["pairs"]:
                raise SystemExit(f"{name} seed {seed}: the held-out objects differ")
            sums.append(np.array(pb["sums"]) - np.array(pc["sums"]))
            pairs.append(np.array(pb["pairs"]))
            accuracy.append((b["ra"]["accuracy"], c["ra"]["accuracy"], b["ra"]["energy_m"],
                             c["ra"]["energy_m"], b["random"]["energy_m"]))
            print(f"{name:22s} seed {seed}: RA-POMDP accuracy {b['ra']['accuracy']:.3f} → "
                  f"{c['ra']['accuracy']:.3f}, energy {b['ra']['energy_m']:.2f} → "
                  f"{c['ra']['energy_m']:.2f} m (Random {b['random']['energy_m']:.2f} m; "
                  f"{b['ra']['episodes']} episodes)")
        a = np.array(accuracy).mean(axis=0)
        estimate, low, high = cluster_bootstrap_difference(np.concatenate(sums),
                                                           np.concatenate(pairs))
        changes[name] = a[1] - a[0]
        print(f"{name:22s} pooled : RA-POMDP {a[0]:.3f} → {a[1]:.3f} ({a[1] - a[0]:+.3f}; paired "
              f"{estimate:+.3f} [{low:+.3f}, {high:+.3f}] over (seed, object)), energy "
              f"{a[2]:.2f} → {a[3]:.2f} m (Random {a[4]:.2f} m)")
    worst, mean = min(changes.values()), float(np.mean(list(changes.values())))
    adopt = worst >= -0.01 and mean >= 0.0
    verdict = "adopt the mixture" if adopt else "the mixture stays an option"
    print(f"\nstage 2: largest fall {worst:+.3f} (may not pass -0.01), mean change over the "
          f"sets {mean:+.3f} (must be >= 0): {verdict}")


if __name__ == "__main__":
    main()
