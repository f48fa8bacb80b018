"""The verdict of ``benchmarks/results/volume_group_crossfit_rule.md`` from the logs of
``held_out_closed_loop.py --volume-labels F --models ra --lambdas 8 --starts 4 --declared``,
one log per (workspace, labels), each headed by a line ``=== W baseline|crossfit``:
RA-POMDP's held-out accuracy, energy and declared ECE (the belief raised to the a fitted on the
other groups' episodes) per workspace, their means per set and the rule's three conditions.

    python benchmarks/volume_group_crossfit_summary.py LOG [LOG ...]
"""

from __future__ import annotations

import argparse
import re
from collections import defaultdict
from pathlib import Path

import numpy as np

LOOP_ROW = re.compile(r"^ra\s+8\s+(?P<accuracy>[\d.]+)\s+(?P<energy>[\d.]+)\s")
DECLARED_ROW = re.compile(r"^ra\s+8\s+\S+ / \S+\s+\S+\s+\S+ / \S+\s+\S+\s+\S+ / (?P<ece>[\d.]+)$")


def read_logs(paths: list[Path]) -> dict[tuple[str, str], dict[str, float]]:
    """(workspace, labels) -> RA-POMDP's held-out accuracy, energy and declared ECE."""
    out: dict[tuple[str, str], dict[str, float]] = {}
    key: tuple[str, str] | None = None
    for path in paths:
        for line in path.read_text().splitlines():
            if line.startswith("=== "):
                workspace, labels = line[4:].split()
                key = (workspace, labels)
                out[key] = {}
            elif key is not None and (match := LOOP_ROW.match(line)):
                out[key].update(accuracy=float(match["accuracy"]),
                                energy=float(match["energy"]))
            elif key is not None and (match := DECLARED_ROW.match(line)):
                out[key]["declared_ece"] = float(match["ece"])
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("logs", type=Path, nargs="+")
    parser.add_argument("--default", default="learned",
                        help="the study configuration held to a +0.02 gain (the others: "
                             "no fall over 0.01)")
    args = parser.parse_args()
    figures = read_logs(args.logs)
    by_set: dict[str, list[tuple[dict[str, float], dict[str, float]]]] = defaultdict(list)
    for (workspace, labels), base in sorted(figures.items()):
        if labels != "baseline":
            continue
        cand = figures.get((workspace, "crossfit"))
        if cand is None or len(cand) < 3 or len(base) < 3:
            print(f"{workspace}: incomplete (baseline {base}, cross-fitted {cand})")
            continue
        by_set[Path(workspace).parent.name].append((base, cand))
        print(f"{workspace}: " + "; ".join(f"{k} {base[k]:.3f} → {cand[k]:.3f}"
                                           for k in ("accuracy", "energy", "declared_ece")))
    holds = True
    for name, pairs in by_set.items():
        mean = {k: (np.mean([b[k] for b, _ in pairs]), np.mean([c[k] for _, c in pairs]))
                for k in ("accuracy", "energy", "declared_ece")}
        print(f"{name} ({len(pairs)} seeds): " + "; ".join(
            f"{k} {b:.3f} → {c:.3f} ({c - b:+.3f})" for k, (b, c) in mean.items()))
        gain = mean["accuracy"][1] - mean["accuracy"][0]
        checks = (gain >= 0.02 if name == args.default else gain >= -0.01,
                  mean["energy"][1] <= 1.1 * mean["energy"][0],
                  mean["declared_ece"][1] - mean["declared_ece"][0] <= 0.02)
        holds &= all(checks)
        print(f"  conditions: accuracy {checks[0]}, energy {checks[1]}, declared ECE {checks[2]}")
    print(f"verdict: {'build it as an option' if holds and by_set else 'not built'}")


if __name__ == "__main__":
    main()
