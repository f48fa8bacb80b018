"""A candidate study against its baseline in the evaluate stage's held-out closed loop only:
each method's accuracy, energy and held-out declared ECE on the volume objects (each group by
the models and policies fitted without it), read from ``evaluate/held_out/declared_fit.json``
seed by seed; no test episode is read. Rules: ``benchmarks/results/batch_norm_rule_v2.md``
and ``input_normals_rule_v2.md`` (the same three conditions; ``--rule`` names the one printed).

    python benchmarks/batch_norm_held_out.py --baseline S1 --candidate S2 [--seeds 0 1 2 3 4]
        [--configs learned real-cad-dev-learned] [--method ra] [--rule input_normals_rule_v2.md]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

HELD_OUT_FILE = Path("evaluate/held_out/declared_fit.json")
FIGURES = ("accuracy", "energy", "declared_ece")


def held_out_figures(workspace: Path, method: str) -> dict[str, float]:
    """One method's held-out closed-loop accuracy, energy (m) and declared ECE."""
    path = workspace / HELD_OUT_FILE
    if not path.is_file():
        raise SystemExit(f"{path}: no held-out closed loop (run the evaluate stage first)")
    record = json.loads(path.read_text())["methods"].get(method)
    if record is None:
        raise SystemExit(f"{path}: no method {method!r} in the held-out closed loop")
    return {"accuracy": float(record["accuracy"]), "energy": float(record["energy"]),
            "declared_ece": float(record["declared_confidence"]["declared_ece"])}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, required=True, help="baseline study folder")
    parser.add_argument("--candidate", type=Path, required=True, help="candidate study folder")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--configs", nargs="+", default=["learned", "real-cad-dev-learned"])
    parser.add_argument("--methods", nargs="+", default=["ra", "classifier", "vptree"])
    parser.add_argument("--rule", default="batch_norm_rule_v2.md",
                        help="the rule whose conditions are printed (its file name)")
    args = parser.parse_args()
    rule_holds = True
    for config in args.configs:
        print(f"## {config}  (held-out closed loop, baseline → candidate)")
        for method in args.methods:
            base = np.array([[held_out_figures(args.baseline / config / f"seed-{s}", method)[f]
                              for f in FIGURES] for s in args.seeds])
            cand = np.array([[held_out_figures(args.candidate / config / f"seed-{s}", method)[f]
                              for f in FIGURES] for s in args.seeds])
            for s, b, c in zip(args.seeds, base, cand, strict=True):
                print(f"  {method:10s} seed {s}: " + "; ".join(
                    f"{f} {b[i]:.3f} → {c[i]:.3f}" for i, f in enumerate(FIGURES)))
            mb, mc = base.mean(axis=0), cand.mean(axis=0)
            print(f"  {method:10s} mean  : " + "; ".join(
                f"{f} {mb[i]:.3f} → {mc[i]:.3f} ({mc[i] - mb[i]:+.3f})"
                for i, f in enumerate(FIGURES)))
            if method == "ra":
                checks = (mc[0] - mb[0] >= 0.02, mc[2] - mb[2] <= 0.02, mc[1] <= 1.1 * mb[1])
                rule_holds &= all(checks)
                print(f"  rule v2 on {config}: accuracy +0.02 {checks[0]}, ECE within +0.02 "
                      f"{checks[1]}, energy within +10 % {checks[2]}")
    if "ra" in args.methods:  # the rule is on RA-POMDP's figures
        print(f"rule v2 ({args.rule}): {'adopt' if rule_holds else 'do not adopt'}")


if __name__ == "__main__":
    main()
