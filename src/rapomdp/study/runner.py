"""Run a study: each (configuration, seed) is a normal cached, resumable workspace
``S/<configuration>/seed-<seed>``; a stage whose key another workspace of the study already
holds (another seed's, or another configuration's) is taken from it (hard links) instead of
being run again.

Seeds are independent tasks: with a Dask scheduler they run as one task each, after the stages
they share within their configuration have been made once; without one they run one after the
other, each stage using the local worker pool as a plain run does, and share across
configurations too. A killed study resumes where it stopped: finished seeds
are cached whole, and the seed it was in resumes at its first unfinished stage.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from rapomdp.config import Config, config_from_dict
from rapomdp.context import RunContext
from rapomdp.parallel import pooled, run_tasks
from rapomdp.pipeline import STAGE_NAMES, planned_keys, run_pipeline
from rapomdp.study.spec import StudyDataset, StudySpec, check_study_folder, write_study
from rapomdp.workspace import StageResult, Workspace


@dataclass(frozen=True)
class SeedRun:
    """One seed of one configuration: its workspace and what each stage did."""

    dataset: str
    seed: int
    workspace: Path
    results: list[StageResult]


def seed_workspace(root: str | Path, dataset: str, seed: int) -> Workspace:
    return Workspace(Path(root) / dataset / f"seed-{seed}")


def _first_makers(spec: StudySpec, runs: Sequence[tuple[StudyDataset, int]]
                  ) -> dict[tuple[str, int], dict[str, tuple[str, int]]]:
    """For each (configuration, seed) of ``runs``, in that order, the stages it shares and the
    first run that makes each (equal planned keys: :func:`rapomdp.pipeline.planned_keys`)."""
    first: dict[str, tuple[str, int]] = {}
    shared: dict[tuple[str, int], dict[str, tuple[str, int]]] = {}
    for dataset, seed in runs:
        mine = shared[(dataset.name, seed)] = {}
        for name, key in planned_keys(spec.config(dataset, seed)).items():
            if key in first:
                mine[name] = first[key]
            else:
                first[key] = (dataset.name, seed)
    return shared


def shared_stages(spec: StudySpec, dataset: StudyDataset) -> dict[int, dict[str, int]]:
    """For each seed of one configuration, the stages it shares and the first seed that makes
    each (equal planned keys; :func:`rapomdp.pipeline.planned_keys`)."""
    plan = _first_makers(spec, [(dataset, seed) for seed in spec.seeds])
    return {seed: {name: maker[1] for name, maker in plan[(dataset.name, seed)].items()}
            for seed in spec.seeds}


def shared_across(spec: StudySpec) -> dict[tuple[str, int], dict[str, tuple[str, int]]]:
    """For each (configuration, seed), in the order a study runs them, the stages it shares and
    the first (configuration, seed) that makes each: across seeds, and across configurations
    (two that differ from the train stage on make their dataset, renders, robot and VP-tree
    once)."""
    return _first_makers(spec, [(d, seed) for d in spec.datasets for seed in spec.seeds])


def _run_seed(config: Config, root: Path, dataset: str, seed: int,
              sources: Sequence[tuple[str, int]], context: RunContext, until: str | None = None,
              on_result: Callable[[StageResult], None] | None = None) -> SeedRun:
    ws = seed_workspace(root, dataset, seed)
    share = [seed_workspace(root, name, s) for name, s in sources]
    results = run_pipeline(config, ws, until=until, on_result=on_result, context=context,
                           share_from=share)
    return SeedRun(dataset, seed, ws.root, results)


def _seed_task(config_json: str, root: str, dataset: str, seed: int, sources: list[int],
               context: RunContext) -> SeedRun:
    """One seed as a task of a Dask worker (one thread, no bars of its own); it shares from
    its own configuration's seeds only (another configuration's may still be running)."""
    config = config_from_dict(json.loads(config_json))
    return _run_seed(config, Path(root), dataset, seed, [(dataset, s) for s in sources],
                     context.in_worker())


def run_study(spec: StudySpec, root: str | Path, context: RunContext = RunContext(),
              on_result: Callable[[str, int, StageResult], None] | None = None
              ) -> list[SeedRun]:
    """Every (configuration, seed) of ``spec`` under ``root``, in order; ``spec`` is recorded
    as the study's (``S/study.yaml``) before anything runs.

    Each seed is a normal cached, resumable workspace ``S/CONFIGURATION/seed-N``; a stage whose
    key another seed or configuration already holds is taken from it as hard links (so
    ``vary: train`` trains only the classifiers again). With ``context.scheduler`` the shared
    stages run here first, then each seed is one Dask task.

    Args:
        spec: The configurations and seeds.
        root: The study folder (new, empty, or a study: another folder is refused).
        context: Workers, threads, scheduler and progress bars.
        on_result: Called with (configuration, seed, stage result) as each stage finishes.

    Returns:
        One record per (configuration, seed), in order: its workspace and stage results.

    Raises:
        ConfigError: ``root`` is neither a study nor empty.

    Example:
        Three seeds of the default configuration, then the pooled report (minutes)::

            from rapomdp.study.report import write_study_report
            from rapomdp.study.runner import run_study
            from rapomdp.study.spec import StudySpec

            spec = StudySpec(seeds=(0, 1, 2))
            runs = run_study(spec, "runs/study")
            report = write_study_report(spec, "runs/study")
            print(report.stories["default"])  # who wins, pooled over the seeds
    """
    root = Path(root)
    check_study_folder(root)
    root.mkdir(parents=True, exist_ok=True)
    write_study(root, spec)
    plan = {d.name: shared_stages(spec, d) for d in spec.datasets}
    sources = {name: sorted({s for by in shared.values() for s in by.values()})
               for name, shared in plan.items()}

    def report(dataset: str, seed: int) -> Callable[[StageResult], None] | None:
        if on_result is None:
            return None
        return lambda result: on_result(dataset, seed, result)

    if context.scheduler is None:
        across = shared_across(spec)
        with pooled(context) as context:
            return [_run_seed(spec.config(d, seed), root, d.name, seed,
                              sorted(set(across[(d.name, seed)].values())), context,
                              on_result=report(d.name, seed))
                    for d in spec.datasets for seed in spec.seeds]
    # On a cluster: the shared stages once, here, then every seed as one task.
    for d in spec.datasets:
        makers: dict[int, set[str]] = {}
        for by in plan[d.name].values():
            for name, maker in by.items():
                makers.setdefault(maker, set()).add(name)
        for maker, names in makers.items():
            for name in sorted(names, key=STAGE_NAMES.index):
                _run_seed(spec.config(d, maker), root, d.name, maker, (), context, until=name,
                          on_result=report(d.name, maker))
    tasks = [(spec.config(d, seed).model_dump_json(), str(root), d.name, seed, sources[d.name],
              replace(context, progress=False))
             for d in spec.datasets for seed in spec.seeds]
    runs = run_tasks(_seed_task, tasks, context.worker_count, "study", context.progress,
                     context.scheduler, unit="seed runs")
    if on_result is not None:
        for run in runs:
            for result in run.results:
                on_result(run.dataset, run.seed, result)
    return runs
