"""Calibration of every method's final belief in the closed loop: accuracy, mean final belief,
their gap and the expected calibration error (10 equal-width bins) per method, for one or more
evaluate stages (e.g. before / after a belief correction).

    python benchmarks/awareness_belief_calibration.py LABEL=W/evaluate [LABEL=W2/evaluate ...]
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np

from rapomdp.recognition.belief import expected_calibration_error, reliability


def main(arguments: list[str]) -> None:
    for argument in arguments:
        label, _, folder = argument.rpartition("=")
        with open(Path(folder) / "episodes.csv") as handle:
            rows = list(csv.DictReader(handle))
        print(f"\n{label or folder}: {len(rows)} episodes")
        print("| method | accuracy | mean final belief | belief - accuracy | ECE | reliability "
              "(bin: belief -> accuracy, n) |")
        print("|---|---|---|---|---|---|")
        for method in dict.fromkeys(r["method"] for r in rows):
            mine = [r for r in rows if r["method"] == method]
            belief = np.array([float(r["belief"]) for r in mine])
            correct = np.array([int(r["correct"]) for r in mine])
            conf, acc, count = reliability(belief, correct, 10)
            bins = ", ".join(f"{c:.2f}->{a:.2f} ({int(n)})" for c, a, n in
                             zip(conf, acc, count, strict=True) if n > 0)
            print(f"| {method} | {correct.mean():.3f} | {belief.mean():.3f} | "
                  f"{belief.mean() - correct.mean():+.3f} | "
                  f"{expected_calibration_error(belief, correct, 10):.3f} | {bins} |")


if __name__ == "__main__":
    main(sys.argv[1:])
