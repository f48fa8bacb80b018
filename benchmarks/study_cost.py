"""What a study cost against one run: stage seconds from the manifests, shared stages once.

    python benchmarks/study_cost.py -s runs/study-default [--demo runs/demo]

Prints, per configuration and seed, the stage seconds each workspace spent (a shared stage
counts 0 where it was taken, its full time where it was made) and what sharing saved; with
``--demo``, the study's total against that one workspace's (the target: a 3-seed study of the
default costs at most 3x one ``make demo``). Seconds are as each stage recorded them, so they
carry the machine's noise: on 2 shared cores compare ratios of one session.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rapomdp.study.pooled import load_seed_results
from rapomdp.study.report import study_seconds
from rapomdp.study.spec import read_study
from rapomdp.workspace import Workspace


def workspace_seconds(root: Path) -> float:
    return sum(float(r.get("seconds", 0.0)) for r in Workspace(root).manifest()["stages"].values())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("-s", "--study", type=Path, required=True)
    parser.add_argument("--demo", type=Path, help="one plain workspace to compare with")
    args = parser.parse_args()
    spec = read_study(args.study)
    if spec is None:
        parser.error(f"{args.study}: no study.yaml; run `rapomdp study -s {args.study}` first")
    demo = workspace_seconds(args.demo) if args.demo else None
    for name, seeds in load_seed_results(spec, args.study).items():
        print(f"configuration '{name}', vary {spec.vary}:")
        for result in seeds:
            print(f"  seed {result.seed}: {workspace_seconds(result.workspace):7.1f} s")
        spent, saved = study_seconds(seeds)
        print(f"  study: {spent:.1f} s of stage time for {len(seeds)} seeds (sharing saved "
              f"{saved:.1f} s)")
        if demo:
            print(f"  one run ({args.demo}): {demo:.1f} s; study / run = {spent / demo:.2f} "
                  f"(target <= {len(seeds)})")


if __name__ == "__main__":
    main()
