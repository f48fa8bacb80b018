"""Paired accuracy differences RA-POMDP − other methods from one evaluate stage's episodes:
the mean over the shared (test model, start) pairs and a 95 % interval from a cluster bootstrap
over test models (an object's episodes are not independent).

    python benchmarks/awareness_paired.py W/evaluate/episodes.csv
"""

from __future__ import annotations

import csv
import sys

import numpy as np


def main(path: str, resamples: int = 10_000) -> None:
    with open(path) as handle:
        rows = list(csv.DictReader(handle))
    right: dict[str, dict[tuple[str, str], int]] = {}
    for r in rows:
        right.setdefault(r["method"], {})[(r["model"], r["start"])] = int(r["correct"])
    pairs = sorted(right["ra"])
    models = sorted({m for m, _ in pairs})
    of_model = np.array([models.index(m) for m, _ in pairs])
    rng = np.random.default_rng(0)
    for other in (m for m in right if m != "ra"):
        d = np.array([right["ra"][p] - right[other][p] for p in pairs], dtype=np.float64)
        per_model = np.bincount(of_model, weights=d) / np.bincount(of_model)
        draws = rng.integers(0, len(models), size=(resamples, len(models)))
        low, high = np.percentile(per_model[draws].mean(axis=1), [2.5, 97.5])
        print(f"RA-POMDP - {other}: {d.mean():+.3f} [{low:+.3f}, {high:+.3f}] "
              f"({len(pairs)} pairs, cluster bootstrap over {len(models)} test models)")


if __name__ == "__main__":
    main(sys.argv[1])
