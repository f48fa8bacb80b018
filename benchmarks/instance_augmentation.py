"""A training change judged on unseen instances: the volume models (never trained on; the test
models are not read). Rule: ``benchmarks/results/instance_augmentation_rule.md``.

Pairs each baseline workspace with the candidate workspace of the same name under
``--candidate`` (same seed, dataset, split and renders; another training) and prints, from
the classifier_eval stage's outputs on the volume models at X_rho (``volume_xrho``), the
single-view accuracy and the mean log-probability of the true class of each, then per folder
(a study's configuration) the mean of each over its seeds and the mean paired difference.

    python benchmarks/instance_augmentation.py --baseline S/cfg/seed-0 ... --candidate S2
        (each baseline W = S/<cfg>/<seed> is paired with S2/<cfg>/<seed>)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from train_recipe import volume_outputs  # noqa: E402  (reads the volume models only)


def volume_figures(workspace: Path) -> tuple[float, float]:
    """Single-view accuracy and mean true-class log-probability over the volume models'
    views at X_rho."""
    probabilities, labels = volume_outputs(workspace)  # (N, C), (N,): one row a view
    truth = np.take_along_axis(probabilities, labels[:, None], axis=1)[:, 0]
    right = probabilities.argmax(axis=1) == labels
    return float(right.mean()), float(np.log(np.maximum(truth, 1e-12)).mean())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", "-b", type=Path, nargs="+", required=True)
    parser.add_argument("--candidate", type=Path, required=True,
                        help="the study folder holding the candidate's <cfg>/<seed>")
    args = parser.parse_args()
    rows: dict[str, list[tuple[float, float, float, float]]] = {}
    print(f"{'workspace':44s} {'accuracy':>17s} {'log p(true)':>17s}")
    print(f"{'':44s} {'base':>8s} {'cand':>8s} {'base':>8s} {'cand':>8s}")
    for base in args.baseline:
        cand = args.candidate / base.parent.name / base.name
        b_acc, b_log = volume_figures(base)
        c_acc, c_log = volume_figures(cand)
        rows.setdefault(base.parent.name, []).append((b_acc, c_acc, b_log, c_log))
        print(f"{str(base):44s} {b_acc:8.3f} {c_acc:8.3f} {b_log:8.3f} {c_log:8.3f}")
    print("\nmean over each configuration's seeds: baseline → candidate (paired difference)")
    for name, values in rows.items():
        m = np.mean(np.array(values), axis=0)
        print(f"{name:24s} accuracy {m[0]:.3f} → {m[1]:.3f} ({m[1] - m[0]:+.3f}); "
              f"log p(true) {m[2]:.3f} → {m[3]:.3f} ({m[3] - m[2]:+.3f})  "
              f"({len(values)} seeds)")


if __name__ == "__main__":
    main()
