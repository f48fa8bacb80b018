"""Start-up of the command line: wall time of ``rapomdp --help`` and what importing the CLI loads.

Runs ``python -m rapomdp.cli --help`` (the ``rapomdp`` entry point) several times and prints the
median wall time (the machine is shared: compare trees measured in one run), then the heavy
libraries that ``import rapomdp.cli`` pulls in (none should be: every stage's code is imported
inside the command that runs it). ``--src`` times other source trees too (e.g. a branch, for a
before/after figure in the same run).

    OMP_NUM_THREADS=1 python benchmarks/cli_help_startup.py [--runs 7] [--src OTHER/src ...]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
HEAVY = ("torch", "trimesh", "matplotlib", "plotly", "roboticstoolbox", "gymnasium", "scipy",
         "sklearn", "captum", "embreex")
CHECK = ("import sys, rapomdp.cli; print(' '.join(m for m in {heavy!r} if m in sys.modules) "
         "or '-')")


def help_seconds(src: Path) -> float:
    env = dict(os.environ, PYTHONPATH=str(src), OMP_NUM_THREADS="1")
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "rapomdp.cli", "--help"], env=env, check=True,
                   stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def heavy_imports(src: Path) -> str:
    env = dict(os.environ, PYTHONPATH=str(src), OMP_NUM_THREADS="1")
    return subprocess.run([sys.executable, "-c", CHECK.format(heavy=HEAVY)], env=env,
                          check=True, capture_output=True, text=True).stdout.strip()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--src", type=Path, action="append", default=None,
                    help="source trees to time (default: this checkout's src)")
    args = ap.parse_args()
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", "pass"], check=True)
    bare = time.perf_counter() - start
    print(f"bare interpreter start: {bare:.2f} s")
    for src in args.src or [REPO / "src"]:
        times = [help_seconds(src) for _ in range(args.runs)]
        print(f"{src}: rapomdp --help {statistics.median(times):.2f} s (median of {args.runs}; "
              f"min {min(times):.2f}, max {max(times):.2f}); import rapomdp.cli loads: "
              f"{heavy_imports(src)}", flush=True)


if __name__ == "__main__":
    main()
