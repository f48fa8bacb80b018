"""``rapomdp study``: the pipeline over seeds and configurations, and the pooled report."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from rapomdp.cli.common import (
    SchedulerOption,
    ThreadsOption,
    WorkersOption,
    _context,
    _guard,
    _report,
    console,
)

if TYPE_CHECKING:
    from rapomdp.study.report import StudyReport
    from rapomdp.study.spec import StudySpec
    from rapomdp.workspace import StageResult


def study(
    folder: Annotated[Path, typer.Option(
        "--study", "-s", help="Study folder: one workspace per configuration and seed "
                              "(`S/CONFIGURATION/seed-N`), the report in `S/report`.")],
    config: Annotated[list[Path] | None, typer.Option(
        "--config", "-c", help="A configuration (dataset) of a new study; repeatable, each "
                               "named by its file's stem. Default: the study's study.yaml, "
                               "else the embedded default.")] = None,
    seeds: Annotated[int | None, typer.Option(
        min=1, help="How many seeds (default 3, or the study's own): first-seed, "
                    "first-seed + 1, ...")] = None,
    first_seed: Annotated[int, typer.Option(min=0, help="The first seed.")] = 0,
    vary: Annotated[str | None, typer.Option(
        help="What a seed changes: 'all' (the run seed: split, models, classifier, starts) "
             "or 'train' (the classifier's own seed: the same models and starts). "
             "Default: all, or the study's own.")] = None,
    reconfigure: Annotated[bool, typer.Option(
        "--reconfigure", help="Accept configurations or seeds that differ from the study's "
                              "study.yaml (changed seeds' stages are redone).")] = False,
    report_only: Annotated[bool, typer.Option(
        "--report-only", help="Only rewrite the report from the finished seeds.")] = False,
    readme: Annotated[Path | None, typer.Option(
        "--readme", help="Also replace this README's generated study block with the "
                         "study's pooled results.")] = None,
    workers: WorkersOption = None,
    threads: ThreadsOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """Run the pipeline over seeds and configurations, then write the pooled report.

    Each seed is a normal cached, resumable workspace; stages whose key another seed or
    configuration already holds are shared (hard links), so `--vary train` trains only the
    classifiers again, and configurations that differ from the train stage on share what
    comes before it. The
    report pools Table 1 over seeds with intervals that resample seeds and test models. With
    --scheduler each seed is one Dask task.
    """
    context = _context(threads, workers, scheduler)

    def resolve() -> StudySpec:
        from rapomdp.config import ConfigError
        from rapomdp.study.spec import StudyDataset, StudySpec, read_study

        recorded = read_study(folder)
        base = recorded or StudySpec()
        given = StudySpec(
            tuple(StudyDataset.from_file(c) for c in config) if config else base.datasets,
            tuple(range(first_seed, first_seed + seeds)) if seeds is not None else base.seeds,
            vary or base.vary)
        if recorded is not None and given != recorded and not reconfigure:
            raise ConfigError(
                f"{folder}: the study was made with seeds {list(recorded.seeds)}, vary "
                f"{recorded.vary} and configurations "
                f"{', '.join(d.name for d in recorded.datasets)}; pass --reconfigure to change "
                "them, or use another study folder")
        return given

    def action() -> StudyReport:
        from rapomdp.study.report import update_study_readme, write_study_report
        from rapomdp.study.runner import run_study

        spec = resolve()
        if not report_only:
            def show(dataset: str, seed: int, result: StageResult) -> None:
                console.print(f"[dim]{dataset} seed {seed}[/]", end=" ", highlight=False)
                _report(result)

            run_study(spec, folder, context, on_result=show)
        written = write_study_report(spec, folder)
        if readme is not None:
            sys.stdout.write(f"{update_study_readme(spec, folder, readme)}\n")
        return written

    written = _guard(action)
    for story in written.stories.values():
        console.print(story, highlight=False)
    sys.stdout.write(f"{written.html}\n{written.markdown}\n")


