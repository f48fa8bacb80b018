"""The classifier's confusion on the volume models (objects it never trained on; the test
models are not read), pooled over workspaces of one dataset: row = true class, column = label,
each row the share of that class's views at X_rho.

    python benchmarks/volume_confusion.py -w runs/study-5seeds/real-cad-dev-learned/seed-{0,1,2,3,4}

Measured: ``benchmarks/results/volume_confusion_real_cad.txt``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from train_recipe import volume_outputs  # noqa: E402  (reads the volume models only)

from rapomdp.data.dataset import load_dataset  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    args = parser.parse_args()
    classes = load_dataset(args.workspace[0] / "dataset").classes
    counts = np.zeros((len(classes), len(classes)))
    for root in args.workspace:
        if load_dataset(root / "dataset").classes != classes:
            raise SystemExit(f"{root}: another class list than {args.workspace[0]}")
        probabilities, labels = volume_outputs(root)
        np.add.at(counts, (labels, probabilities.argmax(axis=1)), 1)
    shares = counts / counts.sum(axis=1, keepdims=True)
    print(f"{'':14s}" + " ".join(f"{name[:6]:>6s}" for name in classes))
    for name, row in zip(classes, shares, strict=True):
        print(f"{name:14s}" + " ".join(f"{v:6.2f}" for v in row))


if __name__ == "__main__":
    main()
