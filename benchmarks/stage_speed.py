"""Seconds of chosen stages with two source trees on one finished workspace, and which of their
artefacts differ: both trees redo the same stages on hard-linked copies of the workspace, one
after the other in one session, so the ratios compare like with like on a shared machine.

    git archive <commit> src | tar -x -C /tmp/before            # the tree to compare against
    python benchmarks/stage_speed.py -w W --before /tmp/before/src \
        [--after src] [--stages volume observe solve evaluate] [--threads 2] \
        [--native-threads unset]

Each stage's seconds come from its record; the command's CPU seconds (user + system of its
processes) are what the load of other programs changes least. Artefacts are compared by
``benchmarks/artefact_hashes.py``'s digest (``.npz`` array by array, JSON without its timing
fields, text without its times).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from artefact_hashes import digest  # noqa: E402
from tree_run import tree_env  # noqa: E402

DEFAULT_STAGES = ("volume", "observe", "solve", "evaluate")


def stage_finished(workspace: Path) -> dict[str, str]:
    """When each stage of ``workspace`` last finished, from its record."""
    return {record.parent.name: str(json.loads(record.read_text()).get("finished"))
            for record in workspace.glob("*/stage.json")}


def run_tree(src: Path, workspace: Path, stages: list[str], threads: int,
             native_threads: str = "1") -> tuple[dict[str, float], float, float]:
    """Redo ``stages`` in ``workspace`` with the code of ``src`` (as a run does, so the stages
    that read them are redone where their inputs changed), ``OMP_NUM_THREADS`` set to
    ``native_threads`` (``unset``: left out, as a plain command in a shell gets it); the seconds
    of every stage that ran (its record's ``finished`` changed), the command's wall and CPU
    seconds."""
    env = tree_env(src)
    if native_threads == "unset":
        env.pop("OMP_NUM_THREADS")
    else:
        env["OMP_NUM_THREADS"] = native_threads
    finished = stage_finished(workspace)
    redo = [arg for name in stages for arg in ("--redo", name)]
    start = time.perf_counter()
    used = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-c", "from rapomdp.cli import main; main()", "run",
                    "-w", str(workspace), "--threads", str(threads), *redo],
                   env=env, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - used.ru_utime) + (after.ru_stime - used.ru_stime)
    seconds = {name: float(json.loads((workspace / name / "stage.json").read_text())["seconds"])
               for name, when in stage_finished(workspace).items()
               if when != finished.get(name)}
    return seconds, wall, cpu


@contextmanager
def workspace_copies(workspace: Path, labels: Sequence[str]) -> Iterator[dict[str, Path]]:
    """Hard-linked copies of ``workspace`` (each with its own lock), one per label, in a
    temporary folder beside it that is removed on leaving. Artefacts are replaced whole,
    never edited, so a run in a copy cannot change the original."""
    with tempfile.TemporaryDirectory(dir=workspace.parent) as scratch:
        copies = {label: Path(scratch) / label for label in labels}
        for copy in copies.values():
            shutil.copytree(workspace, copy, copy_function=os.link,
                            ignore=shutil.ignore_patterns(".lock"))
        yield copies


def differing(before: Path, after: Path, stages: list[str]) -> tuple[int, list[str]]:
    """How many artefacts of ``stages`` were compared, and the ones whose digests differ."""
    names = sorted({p.relative_to(root) for root in (before, after) for stage in stages
                    for p in (root / stage).rglob("*") if p.is_file()
                    and p.name != "stage.json"})
    differ = [str(n) for n in names
              if not (before / n).is_file() or not (after / n).is_file()
              or digest(before / n, before) != digest(after / n, after)]
    return len(names), differ


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, required=True)
    parser.add_argument("--before", type=Path, required=True, help="the old tree's src/")
    parser.add_argument("--after", type=Path, default=Path("src"), help="the new tree's src/")
    parser.add_argument("--stages", nargs="+", default=list(DEFAULT_STAGES))
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--native-threads", default="1",
                        help="OMP_NUM_THREADS of both runs: a number (default 1, as make sets "
                        "it) or 'unset' (as a plain rapomdp command in a shell gets it)")
    args = parser.parse_args()
    trees = {"before": args.before, "after": args.after}
    with workspace_copies(args.workspace, list(trees)) as copies:
        results = {label: run_tree(src, copies[label], args.stages, args.threads,
                                   args.native_threads)
                   for label, src in trees.items()}
        redone = sorted(set(results["before"][0]) & set(results["after"][0]))
        compared, differ = differing(copies["before"], copies["after"], redone)
    (before, wall_b, cpu_b), (after, wall_a, cpu_a) = results["before"], results["after"]
    print(f"{'stage':<16}{'before s':>10}{'after s':>10}{'after/before':>14}")
    for name in redone:
        print(f"{name:<16}{before[name]:>10.1f}{after[name]:>10.1f}"
              f"{after[name] / before[name]:>14.2f}")
    total_b, total_a = sum(before[n] for n in redone), sum(after[n] for n in redone)
    print(f"{'total':<16}{total_b:>10.1f}{total_a:>10.1f}{total_a / total_b:>14.2f}")
    print(f"{'command wall':<16}{wall_b:>10.1f}{wall_a:>10.1f}{wall_a / wall_b:>14.2f}")
    print(f"{'command CPU':<16}{cpu_b:>10.1f}{cpu_a:>10.1f}{cpu_a / cpu_b:>14.2f}")
    print(f"artefacts of the redone stages ({', '.join(redone)}): {compared} compared, "
          f"{len(differ)} differ" + "".join(f"\n  DIFFERS {name}" for name in differ))
    try:
        print(f"load average at the end: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    except OSError:
        pass


if __name__ == "__main__":
    main()
