"""Seconds of the stages that read the test viewpoints' images, before and after sharing them:
two source trees run the same stages on hard-linked copies of one finished workspace, one
after the other in one session, so the ratios compare like with like.

The copies keep the stages upstream of the X_rho images (dataset, render, train, saliency,
volume, robot, crossfit) and redo classifier_eval, observe, vptree, solve, evaluate and report
(and, in a tree that has it, the xrho stage). Solve's code is the same in both trees: its
ratio is the control for the machine's load; the commands' CPU seconds (user + system of all
their processes) change least with it.

    python benchmarks/shared_views_timing.py --workspace runs/demo \
        --before /path/to/old/src --after src [--threads 2]
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np
import stage_speed  # benchmarks/, the script's own folder

REDONE = ("xrho", "classifier_eval", "observe", "vptree", "solve", "evaluate", "report")


def run_tree(src: Path, workspace: Path, threads: int
             ) -> tuple[dict[str, float], float, float]:
    """Redo the stages of :data:`REDONE` in ``workspace`` with the code of ``src``; each
    stage's own seconds from its record, the command's wall time and its CPU seconds (its
    processes' user + system time: what the load of other programs changes least)."""
    seconds, wall, cpu = stage_speed.run_tree(src, workspace,
                                              [n for n in REDONE if n != "xrho"], threads)
    return {n: t for n, t in seconds.items() if n in REDONE}, wall, cpu


def compare_episodes(before: Path, after: Path) -> str:
    """Whether the two runs' episodes took the same moves and declarations, and how far their
    beliefs and Table 1 rows are apart."""
    from rapomdp.io import load_npz

    a = load_npz(before / "evaluate" / "episodes.npz")
    b = load_npz(after / "evaluate" / "episodes.npz")
    lines = []
    for name in ("step_viewpoints", "declared", "correct", "offsets"):
        if name in a:
            lines.append(f"{name}: {'identical' if np.array_equal(a[name], b[name]) else 'DIFFER'}")
    for name in ("step_beliefs", "step_outputs"):
        if name in a:
            lines.append(f"{name}: max |difference| {np.abs(a[name] - b[name]).max():.2e}")
    same_table = ((before / "evaluate" / "table1.md").read_text()
                  == (after / "evaluate" / "table1.md").read_text())
    lines.append(f"table1.md: {'identical' if same_table else 'DIFFERS'}")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", type=Path, required=True)
    parser.add_argument("--before", type=Path, required=True, help="the old tree's src/")
    parser.add_argument("--after", type=Path, required=True, help="the new tree's src/")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    trees = {"before": args.before, "after": args.after}
    with stage_speed.workspace_copies(args.workspace, list(trees)) as copies:
        results = {label: run_tree(src, copies[label], args.threads)
                   for label, src in trees.items()}
        identity = compare_episodes(copies["before"], copies["after"])
    (before, wall_before, cpu_before), (after, wall_after, cpu_after) = (results["before"],
                                                                         results["after"])
    print(f"{'stage':<16}{'before s':>10}{'after s':>10}{'after/before':>14}")
    for name in REDONE:
        b, a = before.get(name), after.get(name)
        ratio = f"{a / b:.2f}" if a is not None and b else "-"
        shown_b = f"{b:.1f}" if b is not None else "-"
        shown_a = f"{a:.1f}" if a is not None else "-"
        print(f"{name:<16}{shown_b:>10}{shown_a:>10}{ratio:>14}")
    total_b, total_a = sum(before.values()), sum(after.values())
    print(f"{'total':<16}{total_b:>10.1f}{total_a:>10.1f}{total_a / total_b:>14.2f}")
    print(f"{'command wall':<16}{wall_before:>10.1f}{wall_after:>10.1f}"
          f"{wall_after / wall_before:>14.2f}")
    print(f"{'command CPU':<16}{cpu_before:>10.1f}{cpu_after:>10.1f}"
          f"{cpu_after / cpu_before:>14.2f}")
    print(identity)
    try:
        load = os.getloadavg()[0]
        print(f"load average at the end: {load:.2f} on {os.cpu_count()} CPUs")
    except OSError:
        pass


if __name__ == "__main__":
    main()
