"""Bounds against time, memory and simulated return on synthetic active-recognition problems.

Problems of the family in ../shared/pomdp-benchmarks/README.md (own random draws, seed 0).
For each size: both bounds at 10, 30 and 100 s of CPU time of one core (``time.process_time``:
the machine is shared, so wall time would measure the neighbours too), peak memory (max RSS of
the process), and the discounted return of the policy over 1000 simulated episodes.

    OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/planning_active_recognition.py \
        [--sizes 16x4,64x10,128x10,128x35] [--seconds 100] [--memory-gb 4]

The solver runs under the memory cap (``--memory-gb``, the solve stage's ``solve.memory_gb``);
each row ends with the solver's note (which bounds the cap and the budget left in use).

Each size runs in its own process so that the memory figure is its own.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys

CHECKPOINTS = (10.0, 30.0, 100.0)


def run_one(n_v: int, n_c: int, seconds: float, seed: int, memory_gb: float
            ) -> dict[str, object]:
    from rapomdp.planning.ar_solver import solve_active_recognition
    from rapomdp.planning.momdp import benchmark_problem, simulate_policy

    problem = benchmark_problem(n_v, n_c, seed)
    checks = tuple(c for c in CHECKPOINTS if c <= seconds)
    result = solve_active_recognition(
        problem, precision=1e-3, timeout=seconds, report_every=1e9, checkpoints=checks,
        clock="process", memory_gb=memory_gb,
    )
    at: dict[str, list[float]] = {}
    for c in checks:
        before = [h for h in result.history if h.elapsed <= c + 1e-9]
        after = [h for h in result.history if h.elapsed >= c]
        snap = after[0] if after else before[-1]
        at[f"{c:g}"] = [round(snap.lower, 4), round(snap.upper, 4), round(snap.elapsed, 1)]
    sim = simulate_policy(problem, result.policy, n_runs=1000, seed=1).summary()
    return {
        "size": f"{n_v}x{n_c}",
        "bounds_at": at,
        "final": [round(result.lower, 4), round(result.upper, 4), round(result.elapsed, 1)],
        "converged": result.converged,
        "vectors": int(len(result.policy.targets)),
        "max_rss_gb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6, 3),
        "sim": {k: round(v, 4) for k, v in sim.items()},
        "declare_at_once": round(-10.0 * (n_c - 1) / n_c, 4),
        "note": result.note,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", default="16x4,64x10,128x10,128x35")
    ap.add_argument("--seconds", type=float, default=100.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--memory-gb", type=float, default=4.0)
    ap.add_argument("--one", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        n_v, n_c = (int(x) for x in args.one.split("x"))
        print(json.dumps(run_one(n_v, n_c, args.seconds, args.seed, args.memory_gb)))
        return
    print(f"active-recognition MOMDP, seed {args.seed}, one core, up to {args.seconds:g} s of "
          f"CPU time (process_time; wall time is unreliable on the shared machine), memory cap "
          f"{args.memory_gb:g} GB")
    print("size     | bounds [lower, upper] at 10 s | at 30 s | at 100 s | memory | "
          "simulated return (1000 runs) ± s.e. | accuracy | steps")
    for size in args.sizes.split(","):
        out = subprocess.run(
            [sys.executable, __file__, "--one", size, "--seconds", str(args.seconds),
             "--seed", str(args.seed), "--memory-gb", str(args.memory_gb)],
            capture_output=True, text=True, check=True,
        )
        r = json.loads(out.stdout.strip().splitlines()[-1])
        cells = " | ".join(
            f"[{v[0]:.3f}, {v[1]:.3f}] (t={v[2]:.0f}s)" for v in r["bounds_at"].values()
        )
        s = r["sim"]
        print(
            f"{r['size']:8s} | {cells} | {r['max_rss_gb']:.2f} GB | "
            f"{s['mean_discounted_return']:.3f} ± {s['stderr']:.3f} | "
            f"{s['accuracy']:.3f} | {s['mean_steps']:.2f} | vectors {r['vectors']}, "
            f"converged {r['converged']}, declare-at-once {r['declare_at_once']}; "
            f"{r['note']}",
            flush=True,
        )


if __name__ == "__main__":
    main()
