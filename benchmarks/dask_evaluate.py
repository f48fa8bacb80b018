"""The evaluate stage on a Dask LocalCluster of 2 workers against the local process pool of 2:
wall time and identical output (issue 13.6).

Builds (or reuses) a small workspace up to ``solve`` on the procedural dataset, then forces the
evaluate stage twice: over ``--workers`` local processes, then with its tasks sent to a
``distributed.LocalCluster`` of as many single-threaded worker processes (started beforehand;
its start-up is timed apart). Every artefact of the stage is compared byte for byte, except
the timing fields (``stage.json``, the episodes' planning CPU seconds).

The local pool runs twice (its start-up is inside the stage; the spread shows the noise of
this shared machine).

Usage: OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/dask_evaluate.py [--workspace W]
Writes benchmarks/results/dask_evaluate.txt.
"""

from __future__ import annotations

import argparse
import hashlib
import shutil
import sys
import tempfile
import time
from pathlib import Path

from rapomdp.config import config_from_dict
from rapomdp.context import RunContext
from rapomdp.io import load_npz, read_json, write_text_atomic
from rapomdp.pipeline import get_stage, run_pipeline
from rapomdp.workspace import Workspace

RESULTS = Path(__file__).parent / "results" / "dask_evaluate.txt"

#: Six procedural classes, two test models each (12 evaluation tasks), small renders.
CONFIG = {
    "seed": 1,
    "dataset": {"classes": ["bicycle", "teapot", "cup", "mug", "bottle", "car"],
                "split": {"train": 3, "volume": 1, "test": 2}},
    "camera": {"width": 64, "height": 48},
    "render": {"views": 24},
    "viewpoints": {"count": 32},
    "train": {"width": 0.125, "epochs": 4, "batch_size": 32, "preprocess": {"input_size_px": 32}},
    "saliency": {"iterations": 10},
    "volume": {"resolution": 16},
    "vptree": {"branching": 4, "levels": 2},
    "evaluate": {"starts_per_model": 5},
}
#: Measured times, which no two runs share: array and JSON keys holding them are left out.
TIMING_FIELDS = ("seconds", "_per_s")


def _untimed(value: object) -> object:
    if isinstance(value, dict):
        return {k: _untimed(v) for k, v in value.items()
                if not any(t in k for t in TIMING_FIELDS)}
    return value


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def compare(a: Path, b: Path) -> list[str]:
    """Files of two evaluate folders that differ (timing fields left out)."""
    names = sorted({p.relative_to(a).as_posix() for p in a.rglob("*") if p.is_file()}
                   | {p.relative_to(b).as_posix() for p in b.rglob("*") if p.is_file()})
    differ = []
    for name in names:
        if name == "stage.json":
            continue
        if not (a / name).exists() or not (b / name).exists():
            differ.append(f"{name} (missing)")
        elif name.endswith(".npz"):
            x, y = load_npz(a / name), load_npz(b / name)
            keys = [k for k in x.keys() | y.keys() if not any(t in k for t in TIMING_FIELDS)]
            if any(k not in x or k not in y or x[k].tobytes() != y[k].tobytes()
                   or x[k].dtype != y[k].dtype for k in keys):
                differ.append(name)
        elif name.endswith(".json"):
            if _untimed(read_json(a / name)) != _untimed(read_json(b / name)):
                differ.append(name)
        elif _digest(a / name) != _digest(b / name):
            differ.append(name)
    return differ


def timed_evaluate(ws: Workspace, config, copy_to: Path, context: RunContext) -> float:
    start = time.perf_counter()
    ws.run(get_stage("evaluate"), config, force=True, context=context)
    seconds = time.perf_counter() - start
    shutil.copytree(ws.require("evaluate"), copy_to)
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", type=Path, default=None,
                        help="a workspace to reuse (default: a new one in a temporary folder)")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    from distributed import LocalCluster

    config = config_from_dict(CONFIG)
    ws = Workspace(args.workspace or Path(tempfile.mkdtemp(prefix="dask-bench-")) / "ws")
    local = RunContext(workers=args.workers, progress=False)
    start = time.perf_counter()
    run_pipeline(config, ws, until="solve", context=local)
    print(f"workspace {ws.root} up to solve in {time.perf_counter() - start:.0f} s",
          file=sys.stderr)
    out = Path(tempfile.mkdtemp(prefix="dask-bench-out-"))
    local_s = timed_evaluate(ws, config, out / "local", local)
    local_again_s = timed_evaluate(ws, config, out / "local-again", local)
    start = time.perf_counter()
    with LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        startup_s = time.perf_counter() - start
        on_dask = RunContext(workers=args.workers, progress=False,
                             scheduler=cluster.scheduler_address)
        dask_s = timed_evaluate(ws, config, out / "dask", on_dask)
    differ = compare(out / "local", out / "dask") + compare(out / "local", out / "local-again")
    files = sum(1 for p in (out / "local").rglob("*") if p.is_file())
    episodes = len(load_npz(out / "local" / "episodes.npz")["correct"])
    lines = [
        f"evaluate stage: {episodes} episodes over "
        f"{len(CONFIG['dataset']['classes']) * 2} test models (tasks), {args.workers} workers",
        "",
        "| runner | wall s |",
        "|---|---|",
        f"| local process pool, {args.workers} processes (started by the stage) | {local_s:.1f} |",
        f"| the same, again | {local_again_s:.1f} |",
        f"| dask LocalCluster, {args.workers} worker processes (already running) | {dask_s:.1f} |",
        f"| dask LocalCluster start-up (once per cluster) | {startup_s:.1f} |",
        "",
        f"dask / local wall time: {dask_s / min(local_s, local_again_s):.2f} with the cluster "
        f"running; {(dask_s + startup_s) / min(local_s, local_again_s):.2f} counting its "
        "start-up. The local pool starts its processes (spawn, imports) in every stage; Dask "
        "workers stay up between stages and runs.",
        f"identical output: {'yes' if not differ else 'NO: ' + ', '.join(differ)} "
        f"({files} files compared, npz arrays and JSON values exactly, the rest byte for "
        "byte; measured times left out: stage.json, the episodes' planning CPU seconds, "
        "evaluate.json's seconds and images_per_s)",
    ]
    text = "\n".join(lines) + "\n"
    sys.stdout.write(text)
    write_text_atomic(RESULTS, text)
    if differ:
        sys.exit(1)


if __name__ == "__main__":
    main()
