"""Run a snippet with another source tree's ``rapomdp`` and read back what it printed: the
before/after benchmarks (solve_speed, train_speed, stage_speed) measure two trees this way, each
in a fresh process, so neither tree's modules leak into the other's run.

    python benchmarks/tree_run.py --src /tmp/before/src "print('{}')"
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path


def tree_env(src: Path, threads: int = 1) -> dict[str, str]:
    """The environment of a process that imports ``rapomdp`` from ``src`` on ``threads``."""
    return {**os.environ, "PYTHONPATH": str(src.resolve()), "OMP_NUM_THREADS": str(threads)}


def run_json(src: Path, code: str, *args: str, threads: int = 1) -> dict[str, object]:
    """``python -c code args`` with ``src``'s code; the JSON object of its last output line."""
    out = subprocess.run([sys.executable, "-c", code, *args], env=tree_env(src, threads),
                         check=True, capture_output=True, text=True).stdout
    return dict(json.loads(out.strip().splitlines()[-1]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--src", type=Path, required=True, help="the source tree (its src/)")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("code", help="Python code that prints a JSON object on its last line")
    args = parser.parse_args()
    print(json.dumps(run_json(args.src, args.code, threads=args.threads)))


if __name__ == "__main__":
    main()
