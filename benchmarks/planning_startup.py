"""Start-up of ``rapomdp pomdp solve``: time from launching the command to its first bound.

Runs ``python -m rapomdp.cli pomdp solve Tiger.pomdp`` (the ``rapomdp`` entry point) several
times, reads its output as it comes, and prints the wall time to the first ``t=`` line (what a
user waits for; the machine is shared, so the median of the runs), the process's CPU time and
its peak memory. ``--src`` runs another source tree (e.g. a checkout before a change) for a
before/after figure in the same run.

    OMP_NUM_THREADS=1 python benchmarks/planning_startup.py [--runs 5] [--src OTHER/src]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TIGER = REPO / "tests" / "planning" / "data" / "Tiger.pomdp"


def first_bound_s(src: Path, problem: Path) -> tuple[float, float, float]:
    """Seconds to the first bound line, CPU seconds of the whole run, its max RSS in MB."""
    env = dict(os.environ, PYTHONPATH=str(src), OMP_NUM_THREADS="1")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "rapomdp.cli", "pomdp", "solve",
                             str(problem), "--timeout", "5"],
                            stdout=subprocess.PIPE, text=True, env=env)
    first = float("nan")
    assert proc.stdout is not None
    for line in proc.stdout:
        if line.lstrip().startswith("t=") and first != first:
            first = time.perf_counter() - start
    proc.wait()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return first, cpu, after.ru_maxrss / 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--problem", type=Path, default=TIGER)
    ap.add_argument("--src", type=Path, action="append", default=None,
                    help="source trees to time (default: this checkout's src)")
    args = ap.parse_args()
    for src in args.src or [REPO / "src"]:
        runs = [first_bound_s(src, args.problem) for _ in range(args.runs)]
        firsts = [r[0] for r in runs]
        print(f"{src}: first bound after {statistics.median(firsts):.2f} s (median of "
              f"{args.runs}; min {min(firsts):.2f}, max {max(firsts):.2f}), CPU "
              f"{statistics.median(r[1] for r in runs):.2f} s per run, max RSS "
              f"{max(r[2] for r in runs):.0f} MB (largest child so far)", flush=True)


if __name__ == "__main__":
    main()
