"""The README's results, generated from a finished workspace so that they cannot drift.

``rapomdp report -w runs/demo --readme README.md`` replaces the block between
:data:`BEGIN` and :data:`END` in the README with what the workspace's artefacts say: the
dataset's roles, the stages' times, single-view accuracy, Table 1 with its paired column, the
held-out comparison (its forecast), the accuracy–energy sweep, the final beliefs' calibration
and the self-awareness table; its figures are copied next to the README
(``--readme-figures``, default ``docs/figures`` beside it), and so is the report's Fig. 1, the
README's lead figure (:data:`LEAD_FIGURE`). Nothing in the block is typed by hand.
"""

from __future__ import annotations

import platform
import shutil
from pathlib import Path

from rapomdp.config import Config
from rapomdp.data.dataset import load_dataset, role_count_lines
from rapomdp.experiment.episode_table import EPISODES_FILE, SUMMARY_FILE, EpisodeTable
from rapomdp.experiment.held_out import load_held_out_comparison
from rapomdp.experiment.metrics import (
    CALIBRATED_ECE_NOTE,
    REPORTED_BELIEF_NOTE,
    belief_calibration_cells,
    table1_story,
)
from rapomdp.experiment.report import (
    evaluation_summaries,
    figure_class,
    held_out_comparison_cells,
    held_out_comparison_story,
)
from rapomdp.io import (
    atomic_path,
    check_output_path,
    markdown_table,
    read_json,
    write_text_atomic,
)
from rapomdp.recognition.artefacts import load_single_view_metrics
from rapomdp.workspace import StageError, Workspace

BEGIN = "<!-- BEGIN generated results: rapomdp report --readme (do not edit by hand) -->"
END = "<!-- END generated results -->"

#: Figures of the evaluate stage shown in the README: (file in W/evaluate, name beside it).
README_FIGURES = (("tradeoff.png", "demo_tradeoff.png"), ("fig3.png", "demo_fig3.png"),
                  ("trajectories.png", "demo_trajectories.png"))
#: The README's lead figure, beside it: the report's Fig. 1 of the figure class
#: (:func:`lead_figure`).
LEAD_FIGURE = "demo_fig1.png"


def _read(path: Path) -> str:
    if not path.exists():
        raise StageError(f"{path}: not found; run the stage that makes it "
                         f"(rapomdp run -w {path.parent.parent})")
    return path.read_text(encoding="utf-8").strip()


def _story(table: EpisodeTable | None, evaluate: Path, seed: int) -> list[str]:
    """What Table 1 and the curves show, from the episodes (as the report says it)."""
    if table is None:
        return []
    rows, paired, points, _ = evaluation_summaries(table, evaluate, seed)
    return [table1_story(rows, paired, points), ""]


def results_markdown(workspace: Workspace, figures_link: str, seed: int = 0) -> str:
    """The generated block (without its markers) for a workspace whose stages have all run;
    ``figures_link`` is the figures folder as the README links it."""
    manifest = workspace.manifest()["stages"]
    missing = [s for s in ("dataset", "classifier_eval", "observe", "evaluate")
               if s not in manifest]
    if missing:
        raise StageError(f"{workspace.root}: stage(s) {', '.join(missing)} have not run; "
                         f"run `rapomdp run -w {workspace.root}` first")
    finished = max(str(r.get("finished", "")) for r in manifest.values())
    seconds = {name: float(r.get("seconds", 0.0)) for name, r in manifest.items()}
    metrics = load_single_view_metrics(workspace.require("classifier_eval"))
    evaluate = workspace.require("evaluate")
    episodes = (EpisodeTable.load(evaluate / EPISODES_FILE)
                if (evaluate / EPISODES_FILE).exists() else None)
    lines = [
        f"*Generated from the workspace `{workspace.root.name}` (last stage finished "
        f"{finished}; Python {platform.python_version()}, {platform.machine()}).*",
        "",
        "**Dataset.** " + "; ".join(role_count_lines(workspace.require("dataset"))) + ".",
        "",
        f"**Single views.** The classifier is right on {metrics.xrho.accuracy:.1%} of the test "
        f"models' views from X_rho (chance {metrics.xrho.chance:.1%}).",
        "",
        "**Stage times** (seconds, as recorded in the manifest; "
        f"{sum(seconds.values()):.0f} s in all):",
        "",
        "| " + " | ".join(seconds) + " |",
        "|" + "---|" * len(seconds),
        "| " + " | ".join(f"{s:.0f}" for s in seconds.values()) + " |",
        "",
        "**Table 1** (closed-loop episodes on the test models):",
        "",
        *_story(episodes, evaluate, seed),
        _read(evaluate / "table1.md"),
        "",
    ]
    held_out = load_held_out_comparison(evaluate)
    if held_out is not None and held_out["methods"]:
        lines += ["**The held-out comparison** (every method on the volume models, run before "
                  "any test model was read: the forecast of Table 1; docs/experiment.md). "
                  + held_out_comparison_story(held_out), "",
                  markdown_table(*held_out_comparison_cells(held_out)).strip(), ""]
    if (evaluate / "tradeoff.md").exists():
        lines += ["**Accuracy against energy** (every method over its settings, the same "
                  "(test model, start) pairs):", "", _read(evaluate / "tradeoff.md"), "",
                  f"![Accuracy against energy]({figures_link}/demo_tradeoff.png)", ""]
    if episodes is not None:
        lines += ["**Calibration of the final belief** (confidence: the belief in the declared "
                  "class, which a calibrated belief's accuracy equals; ECE over 10 bins). "
                  + REPORTED_BELIEF_NOTE + " " + CALIBRATED_ECE_NOTE, "",
                  markdown_table(*belief_calibration_cells(episodes)).strip(), ""]
    lines += ["**Self-awareness** (observation models on the test models):", "",
              _read(workspace.require("observe") / "quality.md"), "",
              f"![Belief in the true class]({figures_link}/demo_fig3.png)", "",
              f"![Trajectories]({figures_link}/demo_trajectories.png)"]
    return "\n".join(lines)


def lead_figure(workspace: Workspace) -> Path | None:
    """The report's Fig. 1 (``W/report/fig1_<class>.png``, the class of Figs. 1 and 3:
    :func:`rapomdp.experiment.report.figure_class`), or None before the report has run."""
    if "report" not in workspace.manifest()["stages"]:
        return None
    summary = workspace.require("evaluate") / SUMMARY_FILE
    evaluation = read_json(summary) if summary.exists() else None
    classes = load_dataset(workspace.require("dataset")).classes
    name = figure_class(evaluation if isinstance(evaluation, dict) else None,
                        workspace.config(default=Config()), classes)
    png = workspace.require("report") / f"fig1_{name}.png"
    return png if png.is_file() else None


def update_readme(workspace: Workspace, readme: Path, figures: Path | None = None) -> Path:
    """Replace the README's generated block with ``workspace``'s results and copy its figures to
    ``figures`` (default: ``docs/figures`` beside the README): the evaluate stage's
    (:data:`README_FIGURES`) and, once the report has run, its Fig. 1 as the README's lead
    figure (:data:`LEAD_FIGURE`). The README must hold the markers."""
    readme = check_output_path(readme)  # a FIFO or device is neither read nor replaced
    figures = Path(figures) if figures is not None else readme.parent / "docs" / "figures"
    for name in (*(n for _, n in README_FIGURES), LEAD_FIGURE):  # all checked before any write
        check_output_path(figures / name)
    text = readme.read_text(encoding="utf-8")
    start, end = text.find(BEGIN), text.find(END)
    if start < 0 or end < start:
        raise StageError(f"{readme}: no generated-results block; add the two lines\n{BEGIN}\n"
                         f"{END}\nwhere the results should go")
    try:
        link = figures.resolve().relative_to(readme.parent.resolve()).as_posix()
    except ValueError:
        link = figures.resolve().as_posix()
    block = results_markdown(workspace, link, workspace.config(default=Config()).seed)
    figures.mkdir(parents=True, exist_ok=True)
    evaluate = workspace.require("evaluate")
    copies = [(evaluate / source, name) for source, name in README_FIGURES]
    lead = lead_figure(workspace)
    if lead is not None:
        copies.append((lead, LEAD_FIGURE))
    for source, name in copies:
        if source.exists():
            with atomic_path(figures / name) as tmp:
                shutil.copyfile(source, tmp)
    write_text_atomic(readme, text[:start] + BEGIN + "\n" + block + "\n" + text[end:])
    return readme
