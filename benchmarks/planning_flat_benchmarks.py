"""Bounds against time on the classic .pomdp problems, against the reference SARSOP.

For each problem in tests/planning/data/: the bounds at b0 at a few times, and the time at
which the lower bound first comes within 1 % of the reference's lower bound listed in the
README there (and when it reaches that bound itself).

    OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/planning_flat_benchmarks.py [--seconds 60]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rapomdp.planning.io_pomdp import read_pomdp
from rapomdp.planning.sarsop import Progress, solve_pomdp

# problem: (reference lower bound, reference upper bound, reference seconds, its 1 % time)
REFERENCE = {
    "Tiger": (19.3711, 19.3721, 0.0, 0.0),
    "Hallway": (0.9956, 1.2055, 120.0, 25.0),
    "Hallway2": (0.3670, 0.9035, 120.0, 93.0),
}
CHECKPOINTS = (1.0, 3.0, 10.0, 30.0, 60.0, 120.0)


def first_time(history: list[Progress], threshold: float) -> float | None:
    for h in history:
        if h.lower >= threshold:
            return h.elapsed
    return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--folder", default=str(Path(__file__).resolve().parents[1] / "tests"
                                            / "planning" / "data"))
    ap.add_argument("--seconds", type=float, default=60.0)
    args = ap.parse_args()
    print(f"flat SARSOP-style solver, one core, precision 1e-3, timeout {args.seconds:g} s")
    for name, (ref_low, ref_up, ref_t, ref_1pct) in REFERENCE.items():
        path = Path(args.folder) / f"{name}.pomdp"
        pomdp = read_pomdp(path)
        result = solve_pomdp(pomdp, precision=1e-3, timeout=args.seconds, report_every=0.25)
        cells = []
        for c in CHECKPOINTS:
            if c > args.seconds + 1:
                break
            snap = [h for h in result.history if h.elapsed <= c][-1]
            cells.append(f"{c:g}s [{snap.lower:.4f}, {snap.upper:.4f}]")
        t1 = first_time(result.history, ref_low - 0.01 * abs(ref_low))
        t0 = first_time(result.history, ref_low)
        print(f"{name}: " + "; ".join(cells))
        print(
            f"  final [{result.lower:.4f}, {result.upper:.4f}] at {result.elapsed:.1f} s "
            f"({'converged' if result.converged else 'time limit'}), {len(result.policy)} "
            f"alpha vectors; reference [{ref_low}, {ref_up}] at {ref_t:g} s"
        )
        print(
            "  within 1 % of the reference lower bound at "
            + (f"{t1:.1f} s" if t1 is not None else "never")
            + f" (reference: {ref_1pct:g} s); reaches it at "
            + (f"{t0:.1f} s" if t0 is not None else "never"),
            flush=True,
        )


if __name__ == "__main__":
    main()
