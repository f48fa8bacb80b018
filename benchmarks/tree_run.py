"""Run a snippet with another source tree's ``rapomdp`` and read back what it printed: the
before/after benchmarks (solve_speed, train_speed, stage_speed) measure two trees this way, each
in a fresh process, so neither tree's modules leak into the other's run."""

from __future__ import annotations

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
