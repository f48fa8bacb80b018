"""The flat solver keeps its word: time and memory limits on files that used to break it.

1. A 164-byte file declaring 4999 states: ``rapomdp pomdp solve FILE --timeout 10`` must end
   within its budget (every phase stoppable) and print bounds; CPU time and peak memory of
   the whole command are measured.
2. 3000 states x 40 actions x 40 observations: refused by its estimate before allocation.
3. The reader on 10^5 and 10^6 state names (linear; the dense arrays are then refused).

    OMP_NUM_THREADS=1 PYTHONPATH=src nice -n 5 python benchmarks/planning_flat_limits.py
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BIG = ("discount: 0.95\nvalues: reward\nstates: 4999\nactions: 2\nobservations: 2\n"
       "start: uniform\nT: 0 identity\nT: 1 uniform\nO: * uniform\nR: 0 : * : * : * 1\n"
       "R: 1 : 7 : * : * 50\n")
WIDE = ("discount: 0.95\nvalues: reward\nstates: 3000\nactions: 40\nobservations: 40\n"
        "start: uniform\nT: * uniform\nO: * uniform\nR: 0 : * : * : * 1\n")


def run_cli(path: Path, timeout_s: float) -> tuple[str, float, float, float]:
    """Output, wall seconds, CPU seconds and max RSS (MB) of ``rapomdp pomdp solve``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "rapomdp.cli", "pomdp", "solve", str(path),
                          "--timeout", str(timeout_s)], capture_output=True, text=True,
                         env=dict(os.environ, OMP_NUM_THREADS="1"))
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return (out.stdout + out.stderr).strip(), wall, cpu, after.ru_maxrss / 1e3


def main() -> None:
    from rapomdp.planning import MemoryCapError, PomdpParseError, parse_pomdp

    with tempfile.TemporaryDirectory() as tmp:
        big = Path(tmp) / "big4999.pomdp"
        big.write_text(BIG)
        text, wall, cpu, rss = run_cli(big, 10.0)
        lines = text.splitlines()
        print(f"1. {big.stat().st_size}-byte file, 4999 states, --timeout 10: whole command "
              f"{cpu:.2f} s CPU (start-up and reading included), {wall:.1f} s wall, max RSS "
              f"{rss:.0f} MB; last lines:")
        for line in lines[-2:]:
            print(f"   {line}")
        wide = Path(tmp) / "wide.pomdp"
        wide.write_text(WIDE)
        text, wall, cpu, rss = run_cli(wide, 10.0)
        print(f"2. 3000 x 40 x 40: exit after {cpu:.2f} s CPU, max RSS {rss:.0f} MB (largest "
              f"child so far): {text.splitlines()[-1]}")
    for n in (10**5, 10**6):
        names = " ".join(f"s{i}" for i in range(n))
        text = f"discount: 0.9\nstates: {names}\nactions: a b\nobservations: x y\n"
        start = time.process_time()
        try:
            parse_pomdp(text + "T: * identity\n")
        except MemoryCapError as exc:
            refused = str(exc)
        spent = time.process_time() - start
        dup = text.replace(f" s{n - 1}\n", " s5\n")
        start = time.process_time()
        try:
            parse_pomdp(dup)
        except PomdpParseError as exc:
            duplicate = str(exc)
        spent_dup = time.process_time() - start
        print(f"3. {n} state names ({len(text) / 1e6:.1f} MB): {spent:.2f} s CPU to "
              f"\"{refused[:90]}...\"; with a duplicate name: {spent_dup:.2f} s to "
              f"\"{duplicate}\"")


if __name__ == "__main__":
    argparse.ArgumentParser(description=__doc__,
                            formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    main()
