"""CPU seconds of the solve stage's solves with two source trees, and whether they solve to the
same bits: each observation model of a finished workspace at its configured λ and iteration
budget, solved by the ``--before`` tree and by the ``--after`` tree one after the other (one
process each, one core), so each ratio compares like with like on a shared machine.

    git -C . archive <commit> src | tar -x -C /tmp/before     # the tree to compare against
    OMP_NUM_THREADS=1 python benchmarks/solve_speed.py --workspace W --before /tmp/before/src

A solve is the same when its lower and upper bounds and the SHA-256 of the policy's arrays
(plans, their targets, the upper bound's points and values) are equal.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tree_run import run_json  # benchmarks/, the script's own folder

#: Runs inside the tree's process: solve one model, print its CPU seconds, bounds and hash.
SOLVE_ONE = r"""
import hashlib, json, sys, time
from pathlib import Path
import numpy as np
from rapomdp.planning.ar_solver import solve_active_recognition
from rapomdp.planning.stage import workspace_problem
from rapomdp.workspace import Workspace
ws = Workspace(Path(sys.argv[1]))
cfg = ws.config()
vptree = ws.root / "vptree"
problem = workspace_problem(ws.require("observe"), ws.require("robot"), sys.argv[2],
                            vptree if vptree.is_dir() else None, cfg.solve)
start = time.process_time()
result = solve_active_recognition(problem, precision=cfg.solve.precision,
                                  timeout=cfg.solve.timeout_s,
                                  max_iterations=cfg.solve.iterations, clock="process")
cpu = time.process_time() - start
p = result.policy
digest = hashlib.sha256()
for a in (p.betas, p.targets, p.upper_points, p.upper_values):
    digest.update(np.ascontiguousarray(a).tobytes())
print(json.dumps({"cpu_s": cpu, "lower": result.lower, "upper": result.upper,
                  "iterations": result.iterations,
                  "timed_out": not result.converged and result.iterations < cfg.solve.iterations,
                  "sha256": digest.hexdigest(), "plans": int(p.betas.shape[0]),
                  "points": int(p.upper_points.shape[0])}))
"""


def solve_with(src: Path, workspace: Path, model: str) -> dict[str, object]:
    """One model's solve by the code of ``src`` in a fresh single-threaded process."""
    return run_json(src, SOLVE_ONE, str(workspace), model)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, required=True)
    parser.add_argument("--before", type=Path, required=True, help="the old tree's src/")
    parser.add_argument("--after", type=Path, default=Path("src"), help="the new tree's src/")
    parser.add_argument("--models", nargs="*", default=None,
                        help="observation models (default: the configuration's solve.models)")
    args = parser.parse_args()
    sys.path.insert(0, str(args.after.resolve()))
    from rapomdp.workspace import Workspace

    config = Workspace(args.workspace).config()
    models = args.models or list(config.solve.models or ["ra", "classifier", "vptree"])
    print(f"workspace {args.workspace}: λ = {config.solve.wrong_declaration_cost_m} m, "
          f"{config.solve.iterations} iterations, timeout {config.solve.timeout_s} CPU s")
    print(f"{'model':<12}{'before s':>10}{'after s':>10}{'ratio':>8}  same  bounds (after)")
    total_before = total_after = 0.0
    for model in models:
        before = solve_with(args.before, args.workspace, model)
        after = solve_with(args.after, args.workspace, model)
        same = all(before[k] == after[k] for k in ("lower", "upper", "sha256", "iterations"))
        b_s, a_s = float(before["cpu_s"]), float(after["cpu_s"])  # type: ignore[arg-type]
        total_before += b_s
        total_after += a_s
        flags = " (timed out)" if after["timed_out"] or before["timed_out"] else ""
        print(f"{model:<12}{b_s:>10.1f}{a_s:>10.1f}{b_s / a_s:>8.2f}  {'yes' if same else 'NO':<4}"
              f"  [{after['lower']:.4f}, {after['upper']:.4f}], {after['iterations']} "
              f"iterations, {after['plans']} plans, {after['points']} points{flags}")
    print(f"{'all':<12}{total_before:>10.1f}{total_after:>10.1f}"
          f"{total_before / total_after:>8.2f}")


if __name__ == "__main__":
    main()
