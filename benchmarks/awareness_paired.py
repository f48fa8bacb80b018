"""Paired accuracy differences from evaluate stages' episodes: RA-POMDP − every other method of
one run, or, given a second run, each method's accuracy in the first run minus in the second
(two workspaces of the same test models and starts, e.g. before and after a default changed).
The mean over the shared (test model, start) pairs and a 95 % interval from a cluster bootstrap
over test models (an object's episodes are not independent).

    python benchmarks/awareness_paired.py W/evaluate/episodes.csv [W2/evaluate/episodes.csv]
"""

from __future__ import annotations

import argparse
import csv

import numpy as np


def _correct(path: str) -> dict[str, dict[tuple[str, str], int]]:
    with open(path) as handle:
        rows = list(csv.DictReader(handle))
    right: dict[str, dict[tuple[str, str], int]] = {}
    for r in rows:
        right.setdefault(r["method"], {})[(r["model"], r["start"])] = int(r["correct"])
    return right


def _paired(a: dict[tuple[str, str], int], b: dict[tuple[str, str], int],
            rng: np.random.Generator, resamples: int) -> str:
    if set(a) != set(b):
        raise SystemExit("the runs do not share their (test model, start) pairs")
    pairs = sorted(a)
    models = sorted({m for m, _ in pairs})
    of_model = np.array([models.index(m) for m, _ in pairs])
    d = np.array([a[p] - b[p] for p in pairs], dtype=np.float64)
    per_model = np.bincount(of_model, weights=d) / np.bincount(of_model)
    draws = rng.integers(0, len(models), size=(resamples, len(models)))
    low, high = np.percentile(per_model[draws].mean(axis=1), [2.5, 97.5])
    return (f"{d.mean():+.3f} [{low:+.3f}, {high:+.3f}] ({len(pairs)} pairs, cluster "
            f"bootstrap over {len(models)} test models)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("episodes", help="an evaluate stage's episodes.csv")
    parser.add_argument("other", nargs="?", default=None,
                        help="a second run's episodes.csv: compare each method across the runs")
    parser.add_argument("--resamples", type=int, default=10_000)
    args = parser.parse_args()
    right = _correct(args.episodes)
    rng = np.random.default_rng(0)
    if args.other is None:
        for other in (m for m in right if m != "ra"):
            print(f"RA-POMDP - {other}: "
                  f"{_paired(right['ra'], right[other], rng, args.resamples)}")
        return
    second = _correct(args.other)
    for method in (m for m in right if m in second):
        a, b = right[method], second[method]
        print(f"{method}: {np.mean(list(a.values())):.3f} - {np.mean(list(b.values())):.3f} = "
              f"{_paired(a, b, rng, args.resamples)}")


if __name__ == "__main__":
    main()
