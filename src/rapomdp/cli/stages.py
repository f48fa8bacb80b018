"""``rapomdp run``, ``rapomdp demo`` and one command per pipeline stage, each running the
pipeline up to its stage and printing what it made."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich import box
from rich.console import Console
from rich.markup import escape
from rich.measure import Measurement
from rich.table import Table

from rapomdp.cli.common import (
    ConfigOption,
    ForceOption,
    OverridesArgument,
    ReconfigureOption,
    SchedulerOption,
    ThreadsOption,
    WorkersOption,
    WorkspaceOption,
    _context,
    _duration,
    _guard,
    _run,
    _workspace_path,
    console,
)
from rapomdp.cli.dataset import _write_preview
from rapomdp.context import RunContext

if TYPE_CHECKING:
    from rapomdp.workspace import Workspace


def run(
    workspace: WorkspaceOption,
    config: ConfigOption = None,
    force: Annotated[bool, typer.Option(
        "--force", "-f", help="Redo every stage it runs even if cached (as --force on a "
                              "stage's command redoes that stage).")] = False,
    redo: Annotated[
        list[str] | None,
        typer.Option("--redo", help="Redo this stage (by name, as `rapomdp status` lists "
                     "them) even if cached; repeatable."),
    ] = None,
    until: Annotated[
        str | None, typer.Option(help="Stop after this stage (and the stages it needs).")
    ] = None,
    workers: WorkersOption = None,
    reconfigure: ReconfigureOption = False,
    scheduler: SchedulerOption = None,
    overrides: OverridesArgument = None,
    threads: ThreadsOption = None,
) -> None:
    """Run every stage in order, skipping those whose inputs are unchanged; prints Table 1.

    The workspace keeps its configuration (W/config.yaml): `rapomdp run -w W` reruns what
    changed, `rapomdp run -w W train.epochs=5` changes one value.
    """
    if force:
        from rapomdp.pipeline import STAGE_NAMES as every_stage
    _run_and_summarise(config, workspace, until,
                       list(every_stage) if force else list(redo or []),
                       _context(threads, workers, scheduler), overrides, reconfigure)


def _run_and_summarise(config_path: Path | None, workspace: Path, until: str | None,
                       force: list[str], context: RunContext,
                       overrides: list[str] | None = None, reconfigure: bool = False,
                       began: float | None = None) -> None:
    """:func:`_run`, then Table 1 and the end-of-run summary (:func:`run_summary_lines`)."""
    began = time.perf_counter() if began is None else began
    _run(config_path, workspace, until, force, context, overrides, reconfigure)
    if until is None:
        _print_table1(workspace)
    lines = _guard(lambda: run_summary_lines(workspace, time.perf_counter() - began,
                                             peak_memory_gb(), until is None))
    for line in lines:
        console.print(escape(line), highlight=False)


def peak_memory_gb() -> tuple[float, float]:
    """The peak resident memory so far of this process and of its largest finished child
    process (a stage's worker), in GB (``resource.getrusage``; 0 where it cannot tell)."""
    try:
        import resource
    except ImportError:  # not a POSIX system
        return 0.0, 0.0
    scale = 1 if sys.platform == "darwin" else 1024  # ru_maxrss: bytes on macOS, else KiB
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return own * scale / 1e9, children * scale / 1e9


def _memory(gb: float) -> str:
    return f"{gb:.1f} GB" if gb >= 1 else f"{gb * 1000:.0f} MB"


def run_summary_lines(workspace: Path, seconds: float, peak_gb: tuple[float, float],
                      whole: bool = True) -> list[str]:
    """The lines that end a run: the report's path, the generated sentences of who won (the
    report's own story, ``metrics.table1_story``, from the same episodes and seed) and the
    paired differences with their 95 % intervals, when the run went to the end (``whole``)
    and made them; then the wall time and the peak memory (this process, its largest worker
    process)."""
    from rapomdp.workspace import Workspace

    lines = []
    root = Path(workspace)
    report_html = root / "report" / "report.html"
    if whole and report_html.is_file():
        lines.append(f"report: {report_html}")
        lines += _story(Workspace(root))
    own, worker = peak_gb
    memory = f"peak memory {_memory(own)}" + (
        f" (its largest worker process {_memory(worker)})" if worker > 0 else "")
    lines.append(f"wall time {_duration(seconds)}, {memory}")
    return lines


def _story(ws: Workspace) -> list[str]:
    """What Table 1 says, as the report says it (who won, which paired differences exclude 0),
    each paired difference with its interval, and the held-out comparison's sentence."""
    from rapomdp.config import METHOD_NAMES, Config
    from rapomdp.experiment.episode_table import EPISODES_FILE, EpisodeTable
    from rapomdp.experiment.held_out import load_held_out_comparison
    from rapomdp.experiment.metrics import table1_story
    from rapomdp.experiment.report import evaluation_summaries, held_out_comparison_story

    folder = ws.stage_dir("evaluate")
    if not (folder / EPISODES_FILE).is_file():
        return []
    rows, paired, points, _ = evaluation_summaries(EpisodeTable.load(folder / EPISODES_FILE),
                                                   folder, ws.config(default=Config()).seed)
    lines = [table1_story(rows, paired, points)]
    if paired:
        reference = next(iter(paired.values())).reference
        lines.append(f"accuracy minus {METHOD_NAMES.get(reference, reference)}'s over the same "
                     "pairs [95 % interval]: " + "; ".join(
                         f"{METHOD_NAMES.get(m, m)} {p.difference:+.3f} "
                         f"[{p.low:+.3f}, {p.high:+.3f}]" for m, p in paired.items()))
    held_out = load_held_out_comparison(folder)
    if held_out is not None and held_out["methods"]:
        lines.append("held out, the forecast made before any test model was read: "
                     + held_out_comparison_story(held_out))
    return lines


def demo(
    workspace: Annotated[Path, typer.Option(
        "--workspace", "-w", parser=_workspace_path, metavar="DIR",
        help="Workspace folder of the demo.")] = Path("runs/demo"),
    threads: ThreadsOption = None,
    workers: WorkersOption = None,
) -> None:
    """Run the demo: the dataset, its contact sheet, then every stage (what `make demo` runs).

    On the embedded procedural dataset with the default configuration (a workspace that has
    its own configuration keeps it). Writes W/contact_sheet.png and W/report/report.html, and
    ends like `rapomdp run`: Table 1, the report's path, who won, the wall time and memory.
    A second run finds every stage cached.
    """
    began = time.perf_counter()
    context = _context(threads, workers)
    _run(None, workspace, "dataset", [], context)
    _write_preview(workspace, None)
    _run_and_summarise(None, workspace, None, [], context, began=began)

def render(workspace: WorkspaceOption, config: ConfigOption = None,
           force: ForceOption = False, reconfigure: ReconfigureOption = False,
           overrides: OverridesArgument = None, workers: WorkersOption = None) -> None:
    """Render every model's depth images over the training viewsphere (and build the dataset)."""
    _run(config, workspace, "render", ["render"] if force else [], _context(workers=workers),
         overrides, reconfigure)


def xrho(workspace: WorkspaceOption, config: ConfigOption = None,
         force: ForceOption = False, reconfigure: ReconfigureOption = False,
         overrides: OverridesArgument = None, workers: WorkersOption = None) -> None:
    """Render the volume and test models at X_rho once, for every stage that reads them."""
    _run(config, workspace, "xrho", ["xrho"] if force else [], _context(workers=workers),
         overrides, reconfigure)


def train(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
          reconfigure: ReconfigureOption = False, overrides: OverridesArgument = None,
          threads: ThreadsOption = None, workers: WorkersOption = None) -> None:
    """Train the depth classifier on the training renders (and build what it needs); an
    ensemble (train.ensemble > 1) trains a share of its members per worker process."""
    _run(config, workspace, "train", ["train"] if force else [], _context(threads, workers),
         overrides, reconfigure)


def classifier_eval(workspace: WorkspaceOption, config: ConfigOption = None,
                    force: ForceOption = False, reconfigure: ReconfigureOption = False,
                    overrides: OverridesArgument = None,
                    threads: ThreadsOption = None, workers: WorkersOption = None) -> None:
    """Single-view accuracy on the test models: per class, confusion, per viewpoint."""
    _run(config, workspace, "classifier_eval", ["classifier_eval"] if force else [],
         _context(threads, workers), overrides, reconfigure)
    from rapomdp.recognition.artefacts import load_single_view_metrics
    from rapomdp.workspace import Workspace

    metrics = _guard(lambda: load_single_view_metrics(
        Workspace(workspace).require("classifier_eval")))
    for part, label in ((metrics.xrho, "test viewpoints X_rho"), (metrics.sphere, "whole sphere")):
        console.print(f"  single-view accuracy, {label}: {part.accuracy:.1%} "
                      f"(chance {part.chance:.1%})", highlight=False)


def saliency(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
             reconfigure: ReconfigureOption = False, overrides: OverridesArgument = None,
             threads: ThreadsOption = None, scheduler: SchedulerOption = None) -> None:
    """2D saliency maps of each class's volume model (method: config saliency.method)."""
    _run(config, workspace, "saliency", ["saliency"] if force else [],
         _context(threads, scheduler=scheduler), overrides, reconfigure)


def volume(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
           reconfigure: ReconfigureOption = False, overrides: OverridesArgument = None,
           threads: ThreadsOption = None) -> None:
    """The 3D dense saliency volume of every class (and the stages it needs)."""
    _run(config, workspace, "volume", ["volume"] if force else [], _context(threads), overrides,
         reconfigure)


def observe(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
            reconfigure: ReconfigureOption = False, overrides: OverridesArgument = None,
            threads: ThreadsOption = None) -> None:
    """Observation models P(o | class, viewpoint) and the self-awareness quality table."""
    _run(config, workspace, "observe", ["observe"] if force else [], _context(threads),
         overrides, reconfigure)
    from rapomdp.awareness.artefacts import QUALITY_MD

    table = Path(workspace) / "observe" / QUALITY_MD
    if table.exists():
        sys.stdout.write(table.read_text())


def vptree(workspace: WorkspaceOption, config: ConfigOption = None,
           force: ForceOption = False, reconfigure: ReconfigureOption = False,
           overrides: OverridesArgument = None, workers: WorkersOption = None) -> None:
    """The VP-tree baseline: vocabulary-tree classifier and its per-viewpoint confusion."""
    _run(config, workspace, "vptree", ["vptree"] if force else [], _context(workers=workers),
         overrides, reconfigure)
    from rapomdp.recognition.artefacts import load_vptree_summary
    from rapomdp.workspace import Workspace

    data = _guard(lambda: load_vptree_summary(Workspace(workspace).require("vptree")))
    test = data.accuracy_test_xrho
    shown = "n/a (no test models)" if test is None else f"{test:.1%}"
    console.print(f"  VP-tree single-view accuracy, test models at X_rho: {shown} "
                  f"(volume models {data.accuracy_volume_xrho:.1%}, chance "
                  f"{data.chance:.1%})", highlight=False)
    if data.temperature is not None:
        console.print(f"  its belief's likelihood temperature (held out): "
                      f"{data.temperature:.3f}", highlight=False)


def robot(workspace: WorkspaceOption, config: ConfigOption = None,
          force: ForceOption = False, reconfigure: ReconfigureOption = False,
          overrides: OverridesArgument = None) -> None:
    """Solve the Panda's IK at every test viewpoint: reachability, manipulability, energy."""
    _run(config, workspace, "robot", ["robot"] if force else [], None, overrides, reconfigure)

    def summary() -> str:
        from rapomdp.robot.artefacts import describe, load_robot_summary
        from rapomdp.workspace import Workspace

        return describe(load_robot_summary(Workspace(workspace).require("robot")))

    console.print(f"  {_guard(summary)}", highlight=False, soft_wrap=True)


def solve(workspace: WorkspaceOption, config: ConfigOption = None,
          force: ForceOption = False, reconfigure: ReconfigureOption = False,
          overrides: OverridesArgument = None, scheduler: SchedulerOption = None) -> None:
    """Solve one active-recognition POMDP per observation model (policies as .npz)."""
    _run(config, workspace, "solve", ["solve"] if force else [], _context(scheduler=scheduler),
         overrides, reconfigure)

    def summary() -> dict:
        from rapomdp.planning.artefacts import load_solve_summary
        from rapomdp.workspace import Workspace

        return load_solve_summary(Workspace(workspace).require("solve"))

    for name, bounds in _guard(summary).items():
        console.print(
            f"  {name:<11} value in [{bounds['lower']:.4f}, {bounds['upper']:.4f}] after "
            f"{bounds['seconds']:.1f} s of CPU time, {bounds['vectors']} vectors"
            + (f"; {bounds['note']}" if bounds.get("note") else ""), highlight=False)


def learn(workspace: WorkspaceOption, config: ConfigOption = None, force: ForceOption = False,
          reconfigure: ReconfigureOption = False, overrides: OverridesArgument = None,
          workers: WorkersOption = None) -> None:
    """The learned baseline: MaskablePPO policies trained on the held-out models' recorded
    evidence, one per λ (only when evaluate.methods lists 'learned': configs/learned.yaml)."""
    _run(config, workspace, "learn", ["learn"] if force else [], _context(workers=workers),
         overrides, reconfigure)

    def summary() -> dict:
        from rapomdp.experiment.learn_stage import load_learn_summary
        from rapomdp.workspace import Workspace

        return load_learn_summary(Workspace(workspace).require("learn"))

    data = _guard(summary)
    if not data.get("trained"):
        console.print(f"  nothing trained: {data.get('reason', '')}", highlight=False)
    for row in data.get("held_out", []):
        console.print(f"  held out, {row['method']} at {row['parameter']} {row['value']:g}: "
                      f"accuracy {row['accuracy']:.3f}, energy {row['mean_energy']:.3f} m",
                      highlight=False)


def _print_table1(workspace: Path) -> None:
    """Table 1 (``W/evaluate/table1.md``) on the console, as a table that fits its width, and
    the notes under it."""
    from rapomdp.experiment.episode_table import TABLE1_MD

    path = Path(workspace) / "evaluate" / TABLE1_MD
    if not path.exists():
        return
    lines = path.read_text(encoding="utf-8").splitlines()
    cells = [[escape(c.strip()) for c in line.strip().strip("|").split("|")]
             for line in lines if line.startswith("|") and not set(line) <= set("|-: ")]
    out = Console()
    if cells:
        table = Table(title="Table 1 (closed-loop episodes on the test models)",
                      title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False)
        for name in cells[0]:  # a header's interval or unit on a line of its own
            table.add_column(name.replace(" [", "\n[").replace(" (", "\n("))
        for row in cells[1:]:
            table.add_row(*row)
        wide = Measurement.get(out, out.options.update_width(10**6), table).maximum <= out.width
        for column in table.columns[:-1]:  # the cells whole where the table fits
            column.no_wrap = wide
        out.print(table)
    for line in lines:
        if line.strip() and not line.startswith("|"):
            out.print(escape(line), highlight=False)


def evaluate(workspace: WorkspaceOption, config: ConfigOption = None,
             force: ForceOption = False, reconfigure: ReconfigureOption = False,
             overrides: OverridesArgument = None, threads: ThreadsOption = None,
             workers: WorkersOption = None, scheduler: SchedulerOption = None) -> None:
    """Closed-loop episodes of every method on every test model (paper Sec. 5.2).

    Each test model starts from evaluate.starts_per_model seeded reachable viewpoints; every
    method (evaluate.methods) runs one episode from each. Prints Table 1 and writes
    W/evaluate/: table1.md|csv, per_class.md|csv, episodes.npz|csv, fig3.png, trajectories.png.
    """
    _run(config, workspace, "evaluate", ["evaluate"] if force else [],
         _context(threads, workers, scheduler), overrides, reconfigure)
    _print_table1(workspace)


