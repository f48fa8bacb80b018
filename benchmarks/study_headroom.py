"""The headroom decomposition of a finished workspace: RA-POMDP's planner and belief (the
evaluate stage's solver settings, λ, lookahead, (test model, start) pairs and seeds) with the
learned observation model and with oracle models read off the test models (in-sample,
cross-object, oracle P(correct) on the learned wrong-label rows, an oracle-fitted belief
temperature). Oracle rows are diagnostics: oracle: never used for any choice.

Checks that the learned row reproduces the evaluate stage's RA-POMDP episodes one for one,
prints the table and the seconds per row, and writes ``headroom.md|csv|json`` into ``--out``
(default ``W/headroom/``; nothing else in the workspace is written).

    OMP_NUM_THREADS=1 python benchmarks/study_headroom.py -w W [--out DIR] [--workers 2]
        [--rows learned oracle_in_sample ...]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from rapomdp.context import RunContext
from rapomdp.study.headroom import HEADROOM_DIR, ROWS, headroom_markdown, run_headroom


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, required=True)
    parser.add_argument("--out", type=Path, default=None,
                        help=f"folder of the outputs (default: W/{HEADROOM_DIR}/)")
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--rows", nargs="+", choices=list(ROWS), default=None,
                        help="rows to run (the learned row always runs); default: all")
    args = parser.parse_args()
    began = time.perf_counter()
    result = run_headroom(args.workspace, args.out, RunContext(workers=args.workers),
                          args.rows)
    wall = time.perf_counter() - began
    assert result.evaluate_mismatches == 0, (
        f"{result.evaluate_mismatches} episodes of the learned row differ from the evaluate "
        "stage's RA-POMDP ones")
    print(f"workspace {args.workspace}: {len(result.test_models)} test models, "
          f"{result.rows[0].episodes} episodes a row")
    print("the learned row reproduces the evaluate stage's RA-POMDP episode for episode "
          "(0 differ)")
    print(f"labels at X_rho equal to the observe stage's record: {result.label_agreement:.4f}")
    fitted = "".join(f", {row}: t = {t:.3f}" for row, t in result.temperatures.items())
    print(f"belief correction '{result.correction}': learned t = "
          f"{result.learned_temperature:.3f} (held out); fitted on the test models{fitted}")
    for note in result.notes:
        print(note)
    print()
    print(headroom_markdown(result.rows))
    print("seconds per row (solve CPU, episodes CPU; the learned row reuses the solve stage's "
          "policy):")
    for row in result.rows:
        print(f"  {row.name:30s} {row.solve_s:7.1f} + {row.episodes_cpu_s:6.1f} = "
              f"{row.seconds:7.1f} s")
    s = result.seconds
    print(f"wall: labels {s['labels_wall']:.1f} s, solves {s['solve_wall']:.1f} s, "
          f"episodes {s['episodes_wall']:.1f} s, total {wall:.1f} s "
          f"({wall / len(result.rows):.1f} s a row)")


if __name__ == "__main__":
    main()
