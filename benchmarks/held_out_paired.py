"""Paired difference between held-out closed-loop runs (``held_out_closed_loop.py --save``):
one method's accuracy under run A minus under run B over the same (held-out model, start) pairs,
with a cluster-bootstrap 95 % interval that resamples held-out models (never test models).
Several A B pairs (one a seed) are pooled, the interval resampling (seed, model) clusters.

    python benchmarks/held_out_paired.py A.npz B.npz [A2.npz B2.npz ...] [--key ra@8]
        [--versus random@0]

``--versus M``: compare a method's lead instead of its accuracy: key's accuracy minus M's on
the same (model, start) within each run, under A minus under B (a difference of paired
differences; the starts of every method of a run are the same).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rapomdp.experiment.metrics import cluster_bootstrap_difference
from rapomdp.io import load_npz
from rapomdp.recognition.belief import expected_calibration_error


def pooled_difference(pairs: list[tuple[np.ndarray, np.ndarray]]
                      ) -> tuple[float, float, float]:
    """Accuracy A − B over every pair's episodes (rows of ``--save``: correct, energy, belief,
    confidence, model id, draw), the interval resampling (pair, model) clusters; each pair's
    A and B must hold the same models and starts in the same order."""
    sums, counts = [], []
    for x, y in pairs:
        if x.shape != y.shape or np.any(x[:, 4] != y[:, 4]):
            raise ValueError("the runs did not use the same held-out models and starts")
        _, cluster = np.unique(x[:, 4], return_inverse=True)
        sums.append(np.bincount(cluster, weights=x[:, 0] - y[:, 0]))
        counts.append(np.bincount(cluster).astype(np.float64))
    return cluster_bootstrap_difference(np.concatenate(sums), np.concatenate(counts))


def describe(key: str, pairs: list[tuple[np.ndarray, np.ndarray]], names: tuple[str, str]
             ) -> str:
    """One line: both accuracies, the pooled difference, energy and calibration."""
    estimate, low, high = pooled_difference(pairs)
    x = np.concatenate([p[0] for p in pairs])
    y = np.concatenate([p[1] for p in pairs])
    models = sum(np.unique(p[0][:, 4]).size for p in pairs)
    per_run = (" (per run " + " / ".join(f"{b[:, 0].mean():.3f}→{a[:, 0].mean():.3f}"
                                        for a, b in pairs) + ")" if len(pairs) > 1 else "")
    known = np.isfinite(x[:, 3]) & np.isfinite(y[:, 3])
    calibration = (f"; confidence - accuracy {x[:, 3].mean() - x[:, 0].mean():+.3f} vs "
                   f"{y[:, 3].mean() - y[:, 0].mean():+.3f}; ECE "
                   f"{expected_calibration_error(x[known, 3], x[known, 0]):.3f} vs "
                   f"{expected_calibration_error(y[known, 3], y[known, 0]):.3f}"
                   if known.all() else "")
    return (f"{key}: accuracy {x[:, 0].mean():.3f} ({names[0]}) - {y[:, 0].mean():.3f} "
            f"({names[1]}) = {estimate:+.3f} [{low:+.3f}, {high:+.3f}] over {len(x)} "
            f"episodes of {models} held-out models{per_run}; energy {x[:, 1].mean():.3f} vs "
            f"{y[:, 1].mean():.3f} m{calibration}")


def lead(run: dict[str, np.ndarray], key: str, versus: str) -> np.ndarray:
    """``run[key]`` with its correct column replaced by key's minus ``versus``'s (same rows)."""
    x, y = run[key], run[versus]
    if x.shape != y.shape or np.any(x[:, 4] != y[:, 4]):
        raise ValueError(f"{key} and {versus} did not run the same held-out models and starts")
    out = x.copy()
    out[:, 0] = x[:, 0] - y[:, 0]
    return out


def describe_lead(key: str, versus: str, pairs: list[tuple[np.ndarray, np.ndarray]],
                  names: tuple[str, str]) -> str:
    """One line: key's lead over ``versus`` under A and B, and A's minus B's."""
    estimate, low, high = pooled_difference(pairs)
    a = np.concatenate([p[0][:, 0] for p in pairs])
    b = np.concatenate([p[1][:, 0] for p in pairs])
    per_run = (" (per run " + " / ".join(f"{y[:, 0].mean():+.3f}→{x[:, 0].mean():+.3f}"
                                        for x, y in pairs) + ")" if len(pairs) > 1 else "")
    return (f"{key} - {versus}: {a.mean():+.3f} ({names[0]}) vs {b.mean():+.3f} ({names[1]}); "
            f"change {estimate:+.3f} [{low:+.3f}, {high:+.3f}] over {len(a)} episodes"
            f"{per_run}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=Path, nargs="+", help="A.npz B.npz, one pair a seed")
    parser.add_argument("--key", nargs="+", default=["ra@8"],
                        help="method@λ rows to compare (as held_out_closed_loop.py saves them)")
    parser.add_argument("--versus", default=None, metavar="M@λ",
                        help="compare each key's lead over this row instead of its accuracy")
    args = parser.parse_args()
    if len(args.runs) % 2:
        raise SystemExit("give the runs in pairs: A.npz B.npz [A2.npz B2.npz ...]")
    loaded = [(load_npz(a), load_npz(b)) for a, b in zip(args.runs[::2], args.runs[1::2],
                                                          strict=True)]
    names = (args.runs[0].name, args.runs[1].name) if len(loaded) == 1 else ("A", "B")
    for key in args.key:
        if any(key not in a or key not in b for a, b in loaded):
            raise SystemExit(f"{key}: not in every run")
        try:
            if args.versus is not None:
                if any(args.versus not in a or args.versus not in b for a, b in loaded):
                    raise SystemExit(f"{args.versus}: not in every run")
                print(describe_lead(key, args.versus, [
                    (lead(a, key, args.versus), lead(b, key, args.versus))
                    for a, b in loaded], names))
                continue
            print(describe(key, [(a[key], b[key]) for a, b in loaded], names))
        except ValueError as exc:
            raise SystemExit(f"{key}: {exc}") from None


if __name__ == "__main__":
    main()
