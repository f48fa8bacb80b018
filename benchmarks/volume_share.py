"""A larger volume role, judged held out on the volume objects two splits share
(rule: ``benchmarks/results/volume_share_rule.md``).

Two workspaces of one seed whose splits draw the same permutation of each class (the same
seed and dataset) hold the same first volume models: groups 0 .. K-1 of the held-out evidence
are the same physical objects, and neither classifier trained on them (asserted on the model
ids and on the evidence's labels). Their held-out closed loops
(``held_out_closed_loop.py --save F``; starts seeded by seed, group and row) are paired on
those groups, pooled over the seeds, and the interval resamples (seed, object) clusters.

    python benchmarks/volume_share.py --variant V0 V1 V2 --baseline B0 B1 B2 \\
        --variant-runs v0.npz v1.npz v2.npz --baseline-runs b0.npz b1.npz b2.npz [--common 3]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from rapomdp.awareness.evidence import RecordedObservation
from rapomdp.data.dataset import load_dataset
from rapomdp.io import load_npz
from rapomdp.workspace import Workspace

sys.path.insert(0, str(Path(__file__).parent))
from held_out_closed_loop import HELD_OUT_ID_STRIDE  # noqa: E402
from held_out_paired import pooled_difference  # noqa: E402


def role_ids(workspace: Path, role: str) -> dict[str, list[str]]:
    """Each class's model ids of one role, in the split's order (volume: group k = the k-th)."""
    out: dict[str, list[str]] = {}
    for m in load_dataset(Workspace(workspace).require("dataset")).with_role(role):
        out.setdefault(m.class_name, []).append(m.id)
    return out


def check_common(variant: Path, baseline: Path, common: int) -> None:
    """Groups 0 .. common-1 are the same objects in both, trained on by neither classifier,
    with the same labels row for row."""
    v, b = role_ids(variant, "volume"), role_ids(baseline, "volume")
    v_train, b_train = role_ids(variant, "train"), role_ids(baseline, "train")
    for name in b:
        shared = b[name][:common]
        if v.get(name, [])[:common] != shared:
            raise SystemExit(f"{variant} / {baseline}: class {name}'s first {common} volume "
                             f"models differ ({v.get(name, [])[:common]} vs {shared})")
        trained = set(v_train.get(name, [])) | set(b_train.get(name, []))
        if trained & set(shared):
            raise SystemExit(f"class {name}: a shared volume model was trained on: "
                             f"{sorted(trained & set(shared))}")
    ev_v = RecordedObservation.load(Workspace(variant).require("observe")).evidence
    ev_b = RecordedObservation.load(Workspace(baseline).require("observe")).evidence
    for g in range(common):
        if not np.array_equal(ev_v.labels[ev_v.groups == g], ev_b.labels[ev_b.groups == g]):
            raise SystemExit(f"group {g}: the evidence's class labels differ between "
                             f"{variant} and {baseline}")


def common_rows(runs: dict[str, np.ndarray], key: str, common: int) -> np.ndarray:
    rows = runs[key]
    return rows[rows[:, 4] < common * HELD_OUT_ID_STRIDE]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", type=Path, nargs="+", required=True)
    parser.add_argument("--baseline", type=Path, nargs="+", required=True)
    parser.add_argument("--variant-runs", type=Path, nargs="+", required=True)
    parser.add_argument("--baseline-runs", type=Path, nargs="+", required=True)
    parser.add_argument("--common", type=int, default=3, help="volume groups both hold")
    parser.add_argument("--keys", nargs="+",
                        default=["ra@8", "classifier@8", "random@0", "static@0"])
    args = parser.parse_args()
    n = len(args.variant)
    if not n == len(args.baseline) == len(args.variant_runs) == len(args.baseline_runs):
        raise SystemExit("give one variant, baseline and run file of each per seed")
    for v, b in zip(args.variant, args.baseline, strict=True):
        check_common(v, b, args.common)
    runs = [(load_npz(v), load_npz(b)) for v, b in
            zip(args.variant_runs, args.baseline_runs, strict=True)]
    print(f"held-out objects of volume groups 0-{args.common - 1}, the same in both splits; "
          f"{n} seed(s) pooled; 95 % interval over (seed, object) clusters")
    figures: dict[str, dict[str, float]] = {}
    for key in args.keys:
        pairs = [(common_rows(v, key, args.common), common_rows(b, key, args.common))
                 for v, b in runs]
        try:
            estimate, low, high = pooled_difference(pairs)
        except ValueError as exc:
            raise SystemExit(f"{key}: {exc}") from None
        xs, ys = [p[0] for p in pairs], [p[1] for p in pairs]
        x, y = np.concatenate(xs), np.concatenate(ys)
        per_seed = " / ".join(f"{a[:, 0].mean():.3f}→{c[:, 0].mean():.3f}"
                              for a, c in zip(ys, xs, strict=True))
        figures[key] = {"variant": float(x[:, 0].mean()), "low": low,
                        "energy_v": float(x[:, 1].mean()), "energy_b": float(y[:, 1].mean())}
        print(f"{key:13s} baseline {y[:, 0].mean():.3f} → variant {x[:, 0].mean():.3f}: "
              f"{estimate:+.3f} [{low:+.3f}, {high:+.3f}] ({len(x)} episodes); per seed "
              f"{per_seed}; energy {y[:, 1].mean():.3f} → {x[:, 1].mean():.3f} m")
    if {"ra@8", "random@0"} <= set(figures):
        ra, rnd = figures["ra@8"], figures["random@0"]
        checks = {"1. RA-POMDP's interval above 0": ra["low"] > 0,
                  "2. RA-POMDP's energy at most 10 % above": ra["energy_v"]
                  <= 1.10 * ra["energy_b"],
                  "3. RA-POMDP at least Random under the variant":
                  ra["variant"] >= rnd["variant"]}
        for name, ok in checks.items():
            print(f"{name}: {'yes' if ok else 'no'}")
        print("verdict: " + ("adopt the candidate as split: auto's rule" if all(checks.values())
                             else "split: auto unchanged; the variant reported as measured"))


if __name__ == "__main__":
    main()
