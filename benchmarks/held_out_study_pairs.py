"""Two study configurations side by side in the evaluate stage's held-out closed loop only
(``evaluate/held_out/declared_fit.json``: each volume group by the models and policies fitted
without it; no test episode is read): each method's accuracy, energy and declared ECE per seed
and their means. The two may be different configurations, or datasets, of different studies:
the seeds are not paired objects, so only means are compared.

    python benchmarks/held_out_study_pairs.py --first runs/study-5seeds/learned \\
        --second runs/study-instances/more-instances [--seeds 0 1 2] [--methods ra classifier]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rapomdp.experiment.held_out import load_declared_fit

FIGURES = ("accuracy", "energy", "declared_ece")


def held_out_figures(workspace: Path, method: str) -> dict[str, float]:
    """One method's held-out closed-loop accuracy, energy (m) and declared ECE."""
    record = load_declared_fit(workspace / "evaluate")
    if record is None:
        raise SystemExit(f"{workspace}: no held-out closed loop (run the evaluate stage first)")
    fit = record["methods"].get(method)
    if fit is None:
        raise SystemExit(f"{workspace}: no method {method!r} in the held-out closed loop")
    return {"accuracy": float(fit["accuracy"]), "energy": float(fit["energy"]),
            "declared_ece": float(fit["declared_confidence"]["declared_ece"])}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=Path, required=True, help="S/CONFIGURATION folder")
    parser.add_argument("--second", type=Path, required=True, help="S/CONFIGURATION folder")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--methods", nargs="+", default=["ra", "classifier", "vptree"])
    args = parser.parse_args()
    print(f"held-out closed loop, {args.first} → {args.second}, seeds {args.seeds}")
    for method in args.methods:
        rows = [np.array([[held_out_figures(root / f"seed-{s}", method)[f] for f in FIGURES]
                          for s in args.seeds]) for root in (args.first, args.second)]
        for name, values in zip(FIGURES, np.stack(rows).transpose(2, 0, 1), strict=True):
            first, second = values
            print(f"  {method:10s} {name:12s} per seed " +
                  " / ".join(f"{a:.3f}→{b:.3f}" for a, b in zip(first, second, strict=True)) +
                  f"; mean {first.mean():.3f} → {second.mean():.3f}"
                  f" ({second.mean() - first.mean():+.3f})")


if __name__ == "__main__":
    main()
