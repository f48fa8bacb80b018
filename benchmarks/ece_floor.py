"""How large is the ECE of a perfectly calibrated confidence on N stops? (docs/awareness.md
§4.8, round five: what a held-out rule on 132–420 stops can tell apart.)

For each workspace's method it takes the confidences the method reported at its test stops
(``evaluate/episodes.npz``: only the confidences, never whether they were right), draws
each stop's outcome as a coin of that probability, so the confidence is calibrated by
construction, and computes the ECE (10 bins, as the study reports it) on N stops drawn from
them. It prints the mean and the 95th percentile over draws per N. Any ECE up to that
percentile is what sampling alone gives a calibrated method at that N.

The reports show the same floor at their own number of stops (the column "ECE if calibrated
(95 %)", ``recognition.belief.calibrated_ece``).

    python benchmarks/ece_floor.py -w W [W ...] [--stops 132 144 420 960 2800] [--method ra]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rapomdp.experiment.episode_table import EPISODES_FILE, EpisodeTable
from rapomdp.recognition.belief import expected_calibration_error

DRAWS = 2000


def ece_floor(confidence: np.ndarray, stops: int, rng: np.random.Generator,
              draws: int = DRAWS) -> np.ndarray:
    """(draws,) the ECE of ``stops`` confidences drawn from ``confidence`` with outcomes drawn
    as coins of those confidences (calibrated by construction)."""
    out = np.empty(draws)
    for k in range(draws):
        c = rng.choice(confidence, stops, replace=True)
        out[k] = expected_calibration_error(c, rng.random(stops) < c)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    parser.add_argument("--stops", type=int, nargs="+", default=[132, 144, 420, 960, 2800])
    parser.add_argument("--method", default="ra")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    by_folder: dict[str, list[np.ndarray]] = {}
    for root in args.workspace:
        table = EpisodeTable.load(root / "evaluate" / EPISODES_FILE)
        mine = table.method == args.method
        by_folder.setdefault(root.parent.name, []).append(table.final_confidence()[mine])
    print(f"ECE of a calibrated {args.method} confidence on N stops (10 bins, {DRAWS} draws): "
          "mean / 95th percentile")
    print(f"{'set':24s} " + " ".join(f"{'N = ' + str(n):>15s}" for n in args.stops))
    for folder, parts in by_folder.items():
        confidence = np.concatenate(parts)
        cells = []
        for n in args.stops:
            ece = ece_floor(confidence, n, rng)
            cells.append(f"{ece.mean():.3f} / {np.percentile(ece, 95):.3f}")
        print(f"{folder:24s} " + " ".join(f"{c:>15s}" for c in cells))


if __name__ == "__main__":
    main()
