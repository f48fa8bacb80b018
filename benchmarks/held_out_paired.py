"""Paired difference between two held-out closed-loop runs (``held_out_closed_loop.py --save``):
one method's accuracy under run A minus under run B over the same (held-out model, start) pairs,
with a cluster-bootstrap 95 % interval that resamples held-out models (never test models).

    python benchmarks/held_out_paired.py A.npz B.npz [--key ra@8]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rapomdp.experiment.metrics import cluster_bootstrap_difference
from rapomdp.io import load_npz
from rapomdp.recognition.belief import expected_calibration_error


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("a", type=Path)
    parser.add_argument("b", type=Path)
    parser.add_argument("--key", nargs="+", default=["ra@8"],
                        help="method@λ rows to compare (as held_out_closed_loop.py saves them)")
    args = parser.parse_args()
    a, b = load_npz(args.a), load_npz(args.b)
    for key in args.key:
        if key not in a or key not in b:
            raise SystemExit(f"{key}: not in both runs (they hold {sorted(a)} and {sorted(b)})")
        x, y = a[key], b[key]
        if x.shape != y.shape or np.any(x[:, 4] != y[:, 4]):
            raise SystemExit(f"{key}: the runs did not use the same held-out models and starts")
        models, cluster = np.unique(x[:, 4], return_inverse=True)
        diff = x[:, 0] - y[:, 0]
        estimate, low, high = cluster_bootstrap_difference(
            np.bincount(cluster, weights=diff, minlength=models.size),
            np.bincount(cluster, minlength=models.size).astype(np.float64))
        print(f"{key}: accuracy {x[:, 0].mean():.3f} ({args.a.name}) - {y[:, 0].mean():.3f} "
              f"({args.b.name}) = {estimate:+.3f} [{low:+.3f}, {high:+.3f}] over {len(x)} "
              f"episodes of {models.size} held-out models; energy {x[:, 1].mean():.3f} vs "
              f"{y[:, 1].mean():.3f} m; confidence - accuracy "
              f"{x[:, 3].mean() - x[:, 0].mean():+.3f} vs {y[:, 3].mean() - y[:, 0].mean():+.3f}"
              f"; ECE {expected_calibration_error(x[:, 3], x[:, 0]):.3f} vs "
              f"{expected_calibration_error(y[:, 3], y[:, 0]):.3f}")


if __name__ == "__main__":
    main()
