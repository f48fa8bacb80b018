"""The ``report`` stage: one markdown and one HTML page gathering a workspace's results.

``W/report/`` holds ``report.md`` and ``report.html`` and a copy of every figure they show (PNG),
so the folder is self-contained. The report reads, from the stages it needs:

- ``evaluate``: ``episodes.npz`` (Table 1 and the per-class table are computed from the
  episodes, not parsed back from the markdown files), ``fig3.png``, ``trajectories.png`` and
  ``evaluate.json`` (episodes, images, images/s, methods, figure class, seconds);
- ``observe``: ``quality.csv`` (the self-awareness table's numbers) and ``calibration.png``;
- ``classifier_eval``: ``metrics.json``, ``confusion_xrho.png``, ``accuracy_hemisphere.png``;
- ``train``: ``training.png``; ``robot``: ``robot.json`` and ``robot.png``;
- ``solve``: ``solve_summary.json`` (the solver's bounds per observation model);
- Fig. 1, made here for the figure class from the render, saliency, volume and observe stages.

and, when present (they are not among its inputs): ``W/figures/fig2.png`` (``rapomdp figure
fig2``, expensive: it trains three classifiers) and ``W/vptree/vptree.json`` (the VP-tree
baseline). A missing file gives a line saying what is missing and which command makes it.
"""

from __future__ import annotations

import html
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from rapomdp.awareness.artefacts import (
    CALIBRATION_FIGURE,
    CALIBRATION_FILE,
    OBSERVATION_FILE,
    QUALITY_CSV,
    VALIDATION_CSV,
    RAChoice,
    load_quality,
    load_ra_choice,
)
from rapomdp.awareness.figures import RELIABILITY_MIN_COUNT, calibration_caption
from rapomdp.awareness.quality import quality_cells
from rapomdp.awareness.report import (
    FIGURES_DIR,
    declared_confidence_cells,
    floor_cell,
    write_fig1,
)
from rapomdp.config import METHOD_NAMES, Config
from rapomdp.context import RunContext
from rapomdp.data.dataset import load_dataset
from rapomdp.experiment.episode_table import (
    EPISODES_FILE,
    FIG3_FILE,
    SUMMARY_FILE,
    TRADEOFF_CSV,
    TRADEOFF_FIGURE,
    TRAJECTORIES_FILE,
    EpisodeTable,
)
from rapomdp.experiment.evaluation import PAIRED_REFERENCE
from rapomdp.experiment.evaluation import figure_class as evaluation_figure_class
from rapomdp.experiment.held_out import load_declared_fit, load_held_out_comparison
from rapomdp.experiment.learned import CURVES_FIGURE, LEARN_SUMMARY
from rapomdp.experiment.metrics import (
    CALIBRATED_ECE_NOTE,
    PER_CLASS_NOTE,
    REPORTED_BELIEF_NOTE,
    MethodSummary,
    PairedDifference,
    TradeoffPoint,
    belief_calibration_cells,
    paired_against,
    paired_note,
    per_class,
    per_class_cells,
    read_tradeoff_csv,
    standing_phrases,
    table1,
    table1_cells,
    table1_story,
)
from rapomdp.experiment.sections import LEARNED, REPORT_INPUTS
from rapomdp.io import (
    ArtefactError,
    atomic_path,
    load_npz,
    read_json,
    stable_hash,
    write_text_atomic,
)
from rapomdp.planning.artefacts import SOLVE_SUMMARY
from rapomdp.recognition.artefacts import (
    HEMISPHERE_FIGURE,
    METRICS_FILE,
    TRAINING_FIGURE,
    VPTREE_SUMMARY_FILE,
    confusion_file,
    load_single_view_metrics,
    load_vptree_summary,
)
from rapomdp.robot.artefacts import ROBOT_FIGURE, ROBOT_SUMMARY, describe
from rapomdp.workspace import StageError, StageInputs, Workspace, read_stage_record

REPORT_MD = "report.md"
REPORT_HTML = "report.html"
BELIEF_RELIABILITY_FIGURE = "belief_reliability.png"
T = TypeVar("T")


# --- the report's blocks, rendered both as markdown and as HTML -------------------------------


@dataclass(frozen=True)
class Heading:
    text: str
    level: int = 2


@dataclass(frozen=True)
class Paragraph:
    text: str


@dataclass(frozen=True)
class Table:
    header: list[str]
    rows: list[list[str]]


@dataclass(frozen=True)
class Image:
    file: str  # a PNG in the report folder
    caption: str


@dataclass(frozen=True)
class Link:
    """A line linking a file in the report folder (an interactive figure): ``text`` then the
    link, labelled ``label``."""

    text: str
    file: str
    label: str


@dataclass(frozen=True)
class Code:
    """Preformatted text (the configuration), folded under ``summary`` in the HTML page."""

    text: str
    summary: str


@dataclass(frozen=True)
class Missing:
    what: str
    how: str  # the command (or reason) that makes it


Block = Heading | Paragraph | Table | Image | Link | Code | Missing


def _md_cell(text: str) -> str:
    return text.replace("|", "\\|")


def to_markdown(blocks: Sequence[Block]) -> str:
    """The report as markdown (images as relative links)."""
    parts = []
    for block in blocks:
        if isinstance(block, Heading):
            parts.append(f"{'#' * block.level} {block.text}")
        elif isinstance(block, Paragraph):
            parts.append(block.text)
        elif isinstance(block, Table):
            lines = ["| " + " | ".join(_md_cell(c) for c in block.header) + " |",
                     "|" + "---|" * len(block.header)]
            lines += ["| " + " | ".join(_md_cell(c) for c in row) + " |" for row in block.rows]
            parts.append("\n".join(lines))
        elif isinstance(block, Image):
            parts.append(f"![{block.caption}]({block.file})\n\n*{block.caption}*")
        elif isinstance(block, Link):
            parts.append(f"{block.text} [{block.label}]({block.file})")
        elif isinstance(block, Code):
            parts.append(f"{block.summary}:\n\n```yaml\n{block.text.rstrip()}\n```")
        else:
            parts.append(f"> **Missing:** {block.what} — {block.how}")
    return "\n\n".join(parts) + "\n"


def table_html(table: Table) -> str:
    """One ``<table>`` with a header row; cells are escaped."""
    head = "".join(f"<th>{html.escape(c)}</th>" for c in table.header)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>"
        for row in table.rows
    )
    return f"<table>\n<thead><tr>{head}</tr></thead>\n<tbody>{body}</tbody>\n</table>"


_STYLE = (
    "body{font-family:sans-serif;max-width:60em;margin:2em auto;padding:0 1em;color:#222}"
    "table{border-collapse:collapse;margin:1em 0}th,td{border:1px solid #bbb;padding:.25em .6em;"
    "text-align:left}th{background:#eee}figure{margin:1.5em 0}img{max-width:100%}"
    "figcaption{font-style:italic;color:#444}.missing{background:#fff4e0;padding:.4em .8em;"
    "border-left:4px solid #e0a030}code{background:#f2f2f2;padding:0 .2em}"
)


def to_html(blocks: Sequence[Block], title: str) -> str:
    """The report as one HTML page (images as relative ``<img>`` links)."""
    parts = [
        "<!DOCTYPE html>", '<html lang="en">', "<head>", '<meta charset="utf-8">',
        f"<title>{html.escape(title)}</title>", f"<style>{_STYLE}</style>", "</head>", "<body>",
    ]
    for block in blocks:
        if isinstance(block, Heading):
            parts.append(f"<h{block.level}>{html.escape(block.text)}</h{block.level}>")
        elif isinstance(block, Paragraph):
            parts.append(f"<p>{html.escape(block.text)}</p>")
        elif isinstance(block, Table):
            parts.append(table_html(block))
        elif isinstance(block, Link):
            parts.append(f'<p>{html.escape(block.text)} <a href="{html.escape(block.file)}">'
                         f"{html.escape(block.label)}</a></p>")
        elif isinstance(block, Code):
            parts.append(f"<details><summary>{html.escape(block.summary)}</summary>"
                         f"<pre>{html.escape(block.text)}</pre></details>")
        elif isinstance(block, Image):
            parts.append(f'<figure><img src="{html.escape(block.file)}" '
                         f'alt="{html.escape(block.caption)}"><figcaption>'
                         f"{html.escape(block.caption)}</figcaption></figure>")
        else:
            parts.append(f'<p class="missing"><strong>Missing:</strong> '
                         f"{html.escape(block.what)} — {html.escape(block.how)}</p>")
    parts += ["</body>", "</html>"]
    return "\n".join(parts) + "\n"


# --- gathering the workspace's results --------------------------------------------------------


class _Builder:
    """Collects blocks and copies the figures they show into the report folder."""

    def __init__(self, root: Path, out: Path) -> None:
        self.root = root
        self.out = out
        self.blocks: list[Block] = []

    def add(self, *blocks: Block) -> None:
        self.blocks.extend(blocks)

    def missing(self, what: str, how: str) -> None:
        self.blocks.append(Missing(what, how))

    def copy(self, source: Path, name: str | None = None) -> str:
        """Copy ``source`` into the report folder (as ``name``); returns the name there."""
        name = name or source.name
        target = self.out / name
        if source.resolve() != target.resolve():
            with atomic_path(target) as tmp:
                shutil.copyfile(source, tmp)
        return name

    def figure(self, source: Path, caption: str, how: str, name: str | None = None) -> None:
        """Copy ``source`` into the report (as ``name``) with its caption, or say it is
        missing and how to make it."""
        if not source.is_file():
            self.missing(f"{self.shown(source)} (not found)", how)
            return
        self.blocks.append(Image(self.copy(source, name), caption))

    def interactive(self, source: Path, what: str) -> None:
        """Link a self-contained interactive HTML figure (copied into the report folder)."""
        if source.is_file():
            self.add(Link(f"Interactive 3D version of {what} (self-contained, works offline):",
                          self.copy(source), source.name))

    def load(self, source: Path, reader: Callable[[Path], T], how: str) -> T | None:
        """``reader(source)`` (an artefact's typed loader), or a missing line saying why not."""
        if not source.is_file():
            self.missing(f"{self.shown(source)} (not found)", how)
            return None
        try:
            return reader(source)
        except (ArtefactError, KeyError, ValueError) as exc:
            self.missing(f"{self.shown(source)}: {exc}", how)
            return None

    def json(self, source: Path, how: str) -> dict[str, Any] | None:
        if not source.is_file():
            self.missing(f"{self.shown(source)} (not found)", how)
            return None
        try:
            data = read_json(source)
        except ArtefactError as exc:
            self.missing(str(exc), how)
            return None
        if not isinstance(data, dict):
            self.missing(f"{self.shown(source)} is not a JSON object", how)
            return None
        return data

    def shown(self, path: Path) -> str:
        try:
            return str(path.relative_to(self.root))
        except ValueError:
            return str(path)


def _fmt(value: Any, digits: int = 3) -> str:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return str(value)
    return str(value) if isinstance(value, int) else f"{value:.{digits}f}"


def figure_class(evaluation: dict[str, Any] | None, config: Config,
                 classes: Sequence[str]) -> str:
    """The class of Figs. 1 and 3: the one the evaluate stage drew, else the configuration's
    (:func:`rapomdp.experiment.evaluation.figure_class`)."""
    drawn = (evaluation or {}).get("figure_class")
    return drawn if drawn in classes else evaluation_figure_class(config, classes)


def _provenance(builder: _Builder, config: Config, given: dict[str, Path]) -> None:
    """The configuration hash and every stage's key: the workspace's, then those of the
    report's input folders (``given``: ``{stage: folder}``) not recorded there."""
    builder.add(Paragraph(
        f"Configuration hash {stable_hash(config.model_dump(mode='json'))[:12]}, "
        f"seed {config.seed}, workspace {builder.root}. Every stage the workspace holds, by "
        f"when it last finished (key: the hash of its configuration sections and inputs):"))
    ran = Workspace(builder.root).manifest().get("stages", {})
    order = sorted((str(record.get("finished", "")), name) for name, record in ran.items()
                   if name != "report" and isinstance(record, dict))
    folders = {name: builder.root / name for _, name in order}
    folders.update({name: folder for name, folder in given.items() if name not in folders})
    rows = []
    for name, folder in folders.items():
        try:
            record = read_stage_record(folder)
        except StageError:
            rows.append([name, "-", "-", "-"])
            continue
        rows.append([name, str(record.get("key", "-"))[:12], str(record.get("finished", "-")),
                     _fmt(record.get("seconds", "-"), 1)])
    builder.add(Table(["stage", "key", "finished", "seconds"], rows))
    builder.add(Code(config.to_commented_yaml(),
                     "The configuration of this run (as `rapomdp config` prints it)"))


#: What Table 1's columns mean (metrics.table1_markdown writes them).
TABLE1_COLUMNS = (
    "Columns: Accuracy — the fraction of episodes whose declared class is the test model's "
    "true class, with Wilson's 95 % score interval; Belief — the method's final belief in the "
    "true class; # steps — the moves made (images after the first); Distance — the camera's "
    "path along the sphere of radius ρ, in metres; Energy — the summed movement energy E_M of "
    "Eq. 3, in metres; each as mean ± the half-width of Student's 95 % interval; — where a "
    "method never moves. Episodes — test models × start viewpoints (those that hit the step "
    "budget had to declare there). The intervals treat episodes as independent draws: they "
    "describe the spread over this protocol's starts and classes, not over unseen objects.")


def _timing(seconds: Any, workers: Any) -> str:
    """The evaluate stage's times in words."""
    if not isinstance(seconds, dict):
        return f"Time: {_fmt(seconds, 1)} s." if seconds is not None else ""
    parts = []
    if "episodes_cpu" in seconds:
        parts.append(f"the episodes took {_fmt(seconds['episodes_cpu'], 1)} s of CPU time")
    if "episodes_wall" in seconds:
        over = f" over {workers} worker(s)" if isinstance(workers, int) else ""
        parts.append(f"{_fmt(seconds['episodes_wall'], 1)} s of wall time{over}")
    if "total" in seconds:
        parts.append(f"the stage {_fmt(seconds['total'], 1)} s in all")
    return ("Time: " + ", ".join(parts) + ".") if parts else ""


def evaluation_summaries(table: EpisodeTable, folder: Path, seed: int
                         ) -> tuple[list[MethodSummary], dict[str, PairedDifference],
                                    list[TradeoffPoint], str]:
    """Table 1's rows, the paired differences to RA-POMDP (empty, with the reason as the last
    item, when the episodes share no (test model, start) pairs) and the accuracy-energy points
    of an evaluate folder: what the report and the README's generated block say."""
    rows = table1(table, table.methods)
    try:
        paired, unpaired = paired_against(table, table.methods, PAIRED_REFERENCE, seed=seed), ""
    except ValueError as exc:
        paired, unpaired = {}, str(exc)
    points = (read_tradeoff_csv((folder / TRADEOFF_CSV).read_text(encoding="utf-8"))
              if (folder / TRADEOFF_CSV).is_file() else [])
    return rows, paired, points, unpaired


def _evaluation(b: _Builder, folder: Path, cmd: str, seed: int) -> dict[str, Any] | None:
    how = f"made by `{cmd} evaluate -w {b.root}`"
    b.add(Heading("Closed-loop recognition (Table 1)"))
    data = b.json(folder / SUMMARY_FILE, how)
    if data is not None:
        methods = data.get("methods", [])
        b.add(Paragraph(
            f"{data.get('episodes', '?')} episodes of the methods "
            f"{', '.join(map(str, methods)) if isinstance(methods, list) else methods}; "
            f"{data.get('images', '?')} depth images rendered and classified "
            f"({_fmt(data.get('images_per_s', '?'), 1)} images per CPU second). "
            f"{_timing(data.get('seconds'), data.get('workers'))}"))
    table = b.load(folder / EPISODES_FILE, EpisodeTable.load, how)
    if table is not None:
        rows, paired, points, unpaired = evaluation_summaries(table, folder, seed)
        if unpaired:
            b.add(Paragraph(f"No paired comparison: {unpaired}."))
        b.add(Paragraph(table1_story(rows, paired, points)))
        b.add(Table(*table1_cells(rows, paired)))
        if paired:
            b.add(Paragraph(paired_note(paired)))
        b.add(Paragraph(TABLE1_COLUMNS))
        _held_out_comparison(b, folder)
        b.add(Paragraph("Per class:"), Paragraph(PER_CLASS_NOTE),
              Table(*per_class_cells(per_class(table, table.methods), table.methods)))
    figure = (data or {}).get("figure_class", "the figure class")
    classes = f"the {len(table.classes)} classes" if table is not None else "every class"
    b.figure(folder / FIG3_FILE,
             f"Fig. 3: the mean belief in the true class after each image, per method: left, "
             f"the test models of class {figure}; right, the mean over {classes} (step 0 is "
             f"the start viewpoint; an episode that has declared keeps its final belief).",
             how)
    b.figure(folder / TRAJECTORIES_FILE,
             "The camera's trajectories on the test viewsphere X_rho, per method.", how)
    if (folder / TRADEOFF_FIGURE).exists():
        b.add(Heading("Accuracy against energy"))
        b.figure(folder / TRADEOFF_FIGURE,
                 "Accuracy against mean movement energy: each POMDP method solved at every "
                 "λ of evaluate.lambdas, Random at every stop belief, from the same (test "
                 "model, start) pairs as Table 1 (the points: evaluate/tradeoff.md and .csv).",
                 how)
    return data


HELD_OUT_COMPARISON_NOTE = (
    "What held-out objects say, before any test model is read: every method run on the volume "
    "models, which the classifier never trained on, from the same seeded starts; each group's "
    "views are the labels the classifier gave them, its beliefs (and a POMDP's lookahead) use "
    "the observation models fitted without the group, and a POMDP's plan is the solve "
    "stage's. A forecast "
    "of Table 1's direction, with intervals as wide as the held-out objects are few (how "
    "often it has forecast it on the development sets: docs/experiment.md, \"The held-out "
    "comparison\"). Each fold's models are fitted on one group of volume models fewer than "
    "Table 1's; on the real-CAD development sets it understated the VP-tree against RA-POMDP "
    "(its held-out loop reads its own labels of the volume models), and Random and the "
    "Classifier POMDP by less than their seeds resolve.")


def held_out_comparison_story(record: dict[str, Any]) -> str:
    """One sentence of how the reference method stands against the others held out."""
    reference = record["reference"]
    name = METHOD_NAMES.get(reference, reference)
    paired = record["paired"]
    said = standing_phrases([(METHOD_NAMES.get(m, m), p["difference"], p["low"], p["high"])
                             for m, p in paired.items()])
    if not said:
        why = record.get("skipped", {}).get(reference, "it is not among evaluate.methods")
        return f"{name} has no held-out closed loop to pair the others with: {why}."
    objects = max(p["objects"] for p in paired.values())
    left_out = "".join(f" {METHOD_NAMES.get(m, m)} is not compared: {why}."
                       for m, why in record.get("not_held_out", {}).items())
    return (f"On the {objects} held-out objects, with 95 % intervals that resample them, "
            f"{name} is {'; '.join(said)}.{left_out}")


def held_out_comparison_cells(record: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """The held-out comparison (``held_out/comparison.json``) as a table: per method accuracy,
    mean energy, episodes and the paired difference to the reference."""
    reference = record["reference"]
    header = ["Method", "Held-out accuracy", "Energy (m)",
              f"Δ accuracy vs {METHOD_NAMES.get(reference, reference)} [95 %, held-out objects]",
              "Episodes"]
    rows = []
    for name in record.get("order", record["methods"]):
        row, p = record["methods"][name], record["paired"].get(name)
        delta = ("—" if name == reference else "not paired" if p is None else
                 f"{p['difference']:+.3f} [{p['low']:+.3f}, {p['high']:+.3f}]")
        rows.append([METHOD_NAMES.get(name, name), f"{row['accuracy']:.3f}",
                     f"{row['energy_m']:.2f}", delta, str(row["episodes"])])
    return header, rows


def _held_out_comparison(b: _Builder, folder: Path) -> None:
    """Table 1's methods on the held-out objects (the evaluate stage's comparison)."""
    record = load_held_out_comparison(folder)
    if record is None or not record["methods"]:
        return
    b.add(Paragraph(held_out_comparison_story(record) + " " + HELD_OUT_COMPARISON_NOTE))
    b.add(Table(*held_out_comparison_cells(record)))


def _awareness(b: _Builder, config: Config, inputs: StageInputs, class_name: str,
               fig1: Callable[..., tuple[Path, Path]], cmd: str) -> None:
    b.add(Heading("Recognition self-awareness"))
    ws = Workspace(b.root)
    fig1_how = f"made by `{cmd} figure fig1 -w {b.root} --class {class_name}`"
    try:
        png, page = fig1(ws, class_name, out_dir=b.out)
    except (StageError, ArtefactError) as exc:
        b.missing(f"Fig. 1 for class {class_name} could not be made ({exc})", fig1_how)
    else:
        b.figure(png, f"Fig. 1, class {class_name}: (a) a depth view of its volume model, "
                      f"(b) the 2D saliency of that view, (c) the 3D dense saliency volume, "
                      f"(d) the normalised viewpoint scores on X_rho.", fig1_how, png.name)
        b.interactive(page, "Fig. 1")
    fig2 = b.root / FIGURES_DIR / "fig2.png"
    fig2_how = (f"`{cmd} figure fig2 -w {b.root}` or `{cmd} report --fig2 -w {b.root}` makes "
                f"it (it trains three two-class classifiers, so the report does not by default)")
    if fig2.is_file():
        b.figure(fig2, "Fig. 2: one class's saliency volume in two-class problems and in the "
                       "all-class problem, all seen from one camera.", fig2_how)
        b.interactive(fig2.with_suffix(".html"), "Fig. 2")
    else:  # optional: not asked for, so not a missing figure
        b.add(Paragraph(f"Fig. 2 (one class's saliency volume in two-class problems) is "
                        f"optional: {fig2_how}."))
    observe_how = f"made by `{cmd} observe -w {b.root}`"
    choice = _ra_choice(b, inputs.observe, observe_how)
    b.add(Paragraph("How well each observation model predicts the classifier's correctness on "
                    "the test models over X_rho (single view, before the belief's "
                    "temperature):"))
    quality = b.load(inputs.observe / QUALITY_CSV, lambda p: load_quality(p.parent),
                     observe_how)
    if quality is not None:
        b.add(Table(*quality_cells(quality)))
        note = _identical_rows(inputs.observe, choice)
        if note:
            b.add(Paragraph(note))
    b.figure(inputs.observe / CALIBRATION_FIGURE,
             calibration_caption(choice.variant, choice.method) if choice is not None else
             "Calibration: the classifier's accuracy per viewpoint-score bin on the held-out "
             "evidence (which RA variant is RA-POMDP's model could not be read).",
             observe_how)
    _self_awareness(b, inputs, class_name, observe_how)


def _ra_choice(b: _Builder, observe: Path, how: str) -> RAChoice | None:
    """Which RA variant RA-POMDP's model is and what chose it: the held-out validation table
    (the chosen row marked), or why there is none."""
    choice = b.load(observe / CALIBRATION_FILE, lambda p: load_ra_choice(p.parent), how)
    if choice is None:
        return None
    validation = (b.load(observe / VALIDATION_CSV,
                         lambda p: load_quality(p.parent, VALIDATION_CSV), how)
                  if (observe / VALIDATION_CSV).exists() else None)
    if choice.configured == "mixture" and choice.weights:
        weights = ", ".join(f"`{name}` {w:.2f}" for name, w in
                            sorted(choice.weights.items(), key=lambda kv: -kv[1]) if w >= 0.005)
        why = ("the RA variants averaged with weights fitted on the held-out labels "
               f"(`observe.ra_model: mixture`, the default; each held-out object scored by the "
               f"variants fitted without its group, the test models play no part): {weights}")
    elif choice.configured == "mixture":
        why = (f"the fallback of `observe.ra_model: mixture` ({choice.rule}): {choice.reason}")
    else:
        why = (f"as configured (`observe.ra_model: {choice.configured}`)"
               + ("; the held-out validation below shows how the variants compare"
                  if validation else ""))
    b.add(Paragraph(f"RA-POMDP's observation model (`ra`) is `{choice.model}`, {why}. The row "
                    f"`ra` in the tables is that variant itself."))
    if validation:
        header, rows = quality_cells(validation)
        header = [*header[:-1], "held-out accuracy"]  # the accuracy of these groups' outcomes
        rows = [[f"{row[0]} (chosen)" if row[0] == choice.model else row[0], *row[1:]]
                for row in rows]
        b.add(Paragraph("Held-out validation (the groups of held-out evidence, each scored by "
                        "the models fitted without it):"), Table(header, rows))
    return choice


def _identical_rows(observe: Path, choice: RAChoice | None) -> str:
    """Which rows of the quality tables are equal because their models are, and why."""
    from rapomdp.awareness.report import identical_models

    try:
        groups = identical_models(load_npz(observe / OBSERVATION_FILE))
    except (ArtefactError, KeyError, ValueError):
        return ""
    parts = []
    for group in groups:
        if choice is not None and {"ra", choice.model} <= set(group):
            others = [f"`{n}`" for n in group if n not in ("ra", choice.model)]
            parts.append(f"`ra` and `{choice.model}` are one model (`ra` is the chosen "
                         f"variant), so their rows are equal by construction"
                         + (f"; {', '.join(others)} coincide with it on this evidence"
                            if others else ""))
        else:
            names = " and ".join(f"`{n}`" for n in group)
            parts.append(f"{names} give the same P(o | c, x) at every viewpoint on this "
                         f"evidence (their fits coincide), so their rows are equal")
    return ("Equal rows: " + "; ".join(parts) + ".") if parts else ""


def _self_awareness(b: _Builder, inputs: StageInputs, class_name: str, how: str) -> None:
    """Predicted vs observed P(correct), one class's hemispheres and the calibration of every
    method's final belief."""
    from rapomdp.awareness.report import AWARENESS_RELIABILITY, write_awareness_figures

    observe = inputs.observe
    try:
        rel, hemi = write_awareness_figures(observe, class_name, b.out)
    except (StageError, ArtefactError, KeyError) as exc:
        b.missing(f"the self-awareness figures could not be made ({exc})", how)
    else:
        b.figure(rel, "Predicted against observed P(correct) on the test models, per "
                      "observation model (single view, before the belief's temperature; "
                      "marker area and the bars below: (test model, viewpoint) pairs per "
                      "bin).", how, rel.name)
        b.add(Link("Its bins and counts:", f"{AWARENESS_RELIABILITY}.csv",
                   f"{AWARENESS_RELIABILITY}.csv"))
        b.figure(hemi, f"Class {class_name}: predicted P(correct) per viewpoint (RA, "
                       f"Classifier) beside the test models' actual accuracy.", how, hemi.name)
    episodes = inputs.evaluate / EPISODES_FILE
    if episodes.exists():
        _belief_calibration(b, EpisodeTable.load(episodes), inputs.evaluate)
    vptree = b.root / "vptree"  # not an input of the report stage (as the VP-tree summary)
    header, rows = declared_confidence_cells(observe, vptree if vptree.is_dir() else None)
    if rows:
        b.add(Paragraph("The declared confidence, fitted on held-out random walks stopped at "
                        "belief thresholds 0.5 to 0.99: per model, a and, at those stops, the "
                        "belief's and the declared belief's confidence and ECE, each held-out "
                        "group scored by the a the other groups give (docs/awareness.md)."))
        b.add(Table(header, rows))
    record = load_declared_fit(inputs.evaluate)
    if record is not None and record["methods"]:
        whose = ("The POMDP methods' and the learned baseline's" if LEARNED in record["methods"]
                 else "The POMDP methods'")
        b.add(Paragraph(
            f"{whose} declared confidence, fitted at "
            f"their own held-out closed-loop stops: "
            f"each volume group's models run from {record['starts_per_model']} starts, the "
            "belief (and a POMDP's lookahead) by the model fitted without the group, a POMDP "
            f"by the solve stage's plan, λ = {record['lambda_m']:g} m; per "
            "method a, the loop's accuracy and energy, and at its stops the belief's and the "
            "declared belief's confidence and ECE (each group by the a the other groups "
            "give). These a are the ones the methods above reported with."))
        b.add(Table(*closed_loop_cells(record)))


def closed_loop_cells(record: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """The held-out closed loop's record (``held_out/declared_fit.json``) as a table: per
    POMDP method a, the loop's accuracy and mean energy, the belief's and the declared
    belief's (held out) confidence and ECE at its stops, and the stops."""
    header = ["Method", "a", "Accuracy", "Energy (m)",
              "Belief: confidence", "ECE", "Declared (held out): confidence", "ECE",
              "ECE if calibrated (95 %)", "Stops"]
    rows = []
    for name, fit in record["methods"].items():
        d = fit["declared_confidence"]
        rows.append([METHOD_NAMES.get(name, name), f"{d['temperature']:.3f}",
                     f"{fit['accuracy']:.3f}", f"{fit['energy']:.2f}",
                     f"{d['confidence']:.3f}", f"{d['ece']:.3f}",
                     f"{d['declared_confidence']:.3f}", f"{d['declared_ece']:.3f}",
                     floor_cell(d),
                     str(fit["episodes"])])
    return header, rows


def _belief_calibration(b: _Builder, table: EpisodeTable, evaluate: Path) -> None:
    """Every method's final belief against its accuracy (:func:`belief_calibration_cells`) and
    the reliability of its confidence."""
    from rapomdp.awareness.figures import reliability_figure
    from rapomdp.awareness.report import write_reliability_csv
    from rapomdp.experiment.figures import method_style

    curves = belief_reliability(table)
    styles = {METHOD_NAMES.get(m, m): method_style(m, i)[::2]
              for i, m in enumerate(table.methods)}
    b.add(Paragraph("Calibration of every method's final belief in the closed loop on the test "
                    "models: the mean belief in the true class; the confidence (the belief in "
                    "the declared class), which a calibrated belief's accuracy equals; ECE of "
                    "the confidence over 10 equal-width bins. "
                    + REPORTED_BELIEF_NOTE + " " + CALIBRATED_ECE_NOTE))
    b.add(Table(*belief_calibration_cells(table)))
    figure = reliability_figure(curves, b.out / BELIEF_RELIABILITY_FIGURE,
                                xlabel="final belief in the declared class",
                                title="Final beliefs on the test models (10 bins)",
                                styles=styles)
    data = write_reliability_csv(curves, figure.with_suffix(".csv"))
    b.add(Image(figure.name, "Reliability of every method's final belief: accuracy against "
                             "confidence (belief in the declared class), from "
                             f"{b.shown(evaluate / EPISODES_FILE)}; marker area and the bars "
                             "below: episodes per bin (legend: episodes in all), bins of "
                             f"fewer than {RELIABILITY_MIN_COUNT} episodes hollow and off the "
                             "line."),
          Link("Its bins and counts:", data.name, data.name))


def belief_reliability(table: EpisodeTable, bins: int = 10
                       ) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Every method's final confidence (the belief in the declared class) against its
    accuracy, per equal-width bin: (mean confidence, accuracy, episodes), by display name (the
    reliability figure's and ``belief_reliability.csv``'s data)."""
    from rapomdp.recognition.belief import reliability

    confidence = table.final_confidence()
    return {METHOD_NAMES.get(m, m): reliability(confidence[table.method == m],
                                                table.correct[table.method == m], bins)
            for m in table.methods}


def _learned(b: _Builder, folder: Path | None, cmd: str) -> None:
    """The learned baseline's training (time, curves) and its held-out scores beside Random's,
    when the learn stage trained it (``evaluate.methods`` lists ``learned``; it changes only
    with the evaluate stage, an input, so the folder is read beside it like the VP-tree's)."""
    if folder is None or not (folder / LEARN_SUMMARY).is_file():
        return
    how = f"made by `{cmd} learn -w {b.root}` (with learned in evaluate.methods)"
    data = b.json(folder / LEARN_SUMMARY, how)
    if not data or not data.get("trained"):
        return
    b.add(Heading("Learned baseline (MaskablePPO)"))
    try:
        seconds, evidence = data["seconds"], data["evidence"]
        b.add(Paragraph(
            f"One policy per λ ({', '.join(f'{v:g}' for v in data['lambdas'])} m), each "
            f"trained for {data['timesteps']:,} environment steps on the recorded evidence of "
            f"{evidence['models']} held-out volume models (no test model), its belief Eq. 5 "
            f"with the "
            f"'{data['observation_model']}' observation model. Training took "
            f"{seconds['train_wall']:.0f} s of wall time ({seconds['train_cpu']:.0f} s of CPU "
            f"over {data['workers']} process(es)); recording the evidence "
            f"{seconds['record']:.0f} s."))
        rows = [[METHOD_NAMES.get(r["method"], r["method"]),
                 f"{r['parameter']} = {r['value']:g}", _fmt(r["accuracy"]),
                 _fmt(r["mean_energy"]), _fmt(r["mean_moves"], 2), _fmt(r["episodes"])]
                for r in data["held_out"]]
    except (KeyError, TypeError, ValueError) as exc:
        b.missing(f"learn/{LEARN_SUMMARY} lacks {exc}", how)
        return
    b.add(Paragraph("On the held-out models themselves (every reachable start; in-sample for "
                    "the learned policy, which trained on them):"),
          Table(["method", "setting", "accuracy", "energy (m)", "moves", "episodes"], rows))
    b.figure(folder / CURVES_FIGURE,
             "Training curves of the learned baseline: mean return, accuracy and energy of "
             "the training episodes that ended in each PPO update, one line per λ.", how)


def _classifier(b: _Builder, inputs: StageInputs, cmd: str) -> None:
    b.add(Heading("Single-view classifier"))
    how = f"made by `{cmd} classifier_eval -w {b.root}`"
    metrics = b.load(inputs.classifier_eval / METRICS_FILE,
                     lambda p: load_single_view_metrics(p.parent), how)
    if metrics is not None:
        rows = [[label, _fmt(part.images), _fmt(part.accuracy), _fmt(part.chance)]
                for part, label in ((metrics.xrho, "test viewpoints X_rho"),
                                    (metrics.sphere, "whole sphere"))]
        b.add(Table(["test views", "images", "accuracy", "chance"], rows))
    b.figure(inputs.classifier_eval / confusion_file("xrho", "png"),
             "Single-view confusion of the classifier on the test models over X_rho.", how)
    b.figure(inputs.classifier_eval / HEMISPHERE_FIGURE,
             "Single-view accuracy and mean probability of the true class per test viewpoint.",
             how)
    b.figure(inputs.train / TRAINING_FIGURE,
             "Training curves: loss and accuracy per epoch.",
             f"made by `{cmd} train -w {b.root}`")
    vptree = b.root / "vptree" / VPTREE_SUMMARY_FILE
    how = f"made by `{cmd} vptree -w {b.root}` (the VP-tree baseline)"
    if vptree.is_file():
        data = b.load(vptree, lambda p: load_vptree_summary(p.parent), how)
        if data is not None:
            accuracy = "?" if data.accuracy_test_xrho is None else data.accuracy_test_xrho
            b.add(Paragraph(f"VP-tree baseline (vocabulary tree), single-view accuracy on the "
                            f"test models over X_rho: {_fmt(accuracy)}."))
    else:
        b.missing(f"VP-tree baseline accuracy (vptree/{VPTREE_SUMMARY_FILE} not found)", how)


def _robot_and_solver(b: _Builder, config: Config, inputs: StageInputs, cmd: str
                      ) -> None:
    b.add(Heading("Robot and planner"))
    how = f"made by `{cmd} robot -w {b.root}`"
    summary = b.json(inputs.robot / ROBOT_SUMMARY, how)
    if summary is not None:
        try:
            b.add(Paragraph(f"Panda arm: {describe(summary)}."))
        except (KeyError, TypeError) as exc:
            b.missing(f"robot/{ROBOT_SUMMARY} lacks {exc}", how)
    b.figure(inputs.robot / ROBOT_FIGURE,
             "The Panda's reachability of the test viewpoints, coloured by manipulability, with "
             "the arm drawn at a few of its solutions.", how)
    how = f"made by `{cmd} solve -w {b.root}`"
    bounds = b.json(inputs.solve / SOLVE_SUMMARY, how)
    if bounds is not None:
        solved = {str(name): v for name, v in bounds.items() if isinstance(v, dict)}
        rows = [[name, _fmt(v.get("lower", "-"), 4), _fmt(v.get("upper", "-"), 4),
                 _gap(v), _fmt(v.get("seconds", "-"), 1), _fmt(v.get("vectors", "-"))]
                for name, v in solved.items()]
        b.add(Paragraph("The solver's bounds on the value of the start belief, per observation "
                        "model (values are negative costs, metres of energy):"),
              Table(["observation model", "lower", "upper", "gap", "seconds", "alpha vectors"],
                    rows),
              Paragraph(solver_gap_note(solved, config.solve, _mean_energies(inputs))))


def _gap(row: dict[str, Any]) -> str:
    lower, upper = row.get("lower"), row.get("upper")
    if isinstance(lower, int | float) and isinstance(upper, int | float):
        return f"{max(upper - lower, 0.0):.4f}"  # bounds equal up to rounding: 0, not -0
    return "-"


def _mean_energies(inputs: StageInputs) -> dict[str, float]:
    """Each method's mean movement energy per episode in Table 1's episodes (none without
    them)."""
    episodes = inputs.evaluate / EPISODES_FILE
    if not episodes.is_file():
        return {}
    try:
        table = EpisodeTable.load(episodes)
    except (ArtefactError, KeyError, ValueError):
        return {}
    return {m: float(table.energy[table.method == m].mean()) for m in table.methods}


def solver_gap_note(solved: dict[str, dict[str, Any]], solve: Any,
                    energies: dict[str, float]) -> str:
    """What the solver's gap (upper − lower bound at the start belief) means for each policy:
    the lower bound is the expected discounted value of the policy the solver returned, the
    upper bound one no policy exceeds, so the policy is at most the gap worse than optimal —
    for the observation model it was solved on — in metres, set against a wrong declaration's
    cost λ and the method's mean episode energy in Table 1 (``energies``, by method: the
    observation model's name). ``solve`` is the configuration's solve section."""
    lam, discount = float(solve.wrong_declaration_cost_m), float(solve.discount)
    parts, converged = [], []
    for name, row in solved.items():
        lower, upper = row.get("lower"), row.get("upper")
        if not (isinstance(lower, int | float) and isinstance(upper, int | float)):
            continue
        gap = max(upper - lower, 0.0)
        if row.get("converged") or gap <= solve.precision:
            converged.append(f"`{name}`")
            continue
        stop = ("stopped at the CPU-time limit (solve.timeout_s)" if row.get("timed_out")
                else f"stopped at the iteration budget (solve.iterations: "
                     f"{row.get('iterations', solve.iterations)})")
        energy = energies.get(name)
        against = (f"; its mean episode energy in Table 1 is {energy:.2f} m, so the gap is "
                   f"{gap / energy:.2g} times what an episode spends moving"
                   if energy is not None and energy > 0 else "")
        parts.append(f"`{name}`: {stop} with a gap of {gap:.2f} m: its policy may cost up to "
                     f"{gap:.2f} m more per episode than an optimal one, as much as "
                     f"{gap / lam:.2g} wrong declaration(s) at λ = {lam:g} m{against}")
    if converged:
        parts.insert(0, f"{', '.join(converged)}: converged (gap within the precision "
                        f"{solve.precision:g} m), so each policy is optimal to that amount")
    if not parts:
        return ""
    return ("What the gap means: the lower bound is the expected discounted (γ = "
            f"{discount:g}) value, from the start belief, of the policy the solver returned; "
            "no policy is worth more than the upper bound. A policy is therefore at most its "
            "gap worse than optimal — optimal for the observation model it was solved on; how "
            "it does on the test models is Table 1's — and the bound does not say how much of "
            "the gap is the policy's and how much the upper bound's looseness. "
            + "; ".join(parts) + ".")


def write_report(config: Config, inputs: StageInputs, out: Path,
                 fig1: Callable[..., tuple[Path, Path]] | None = None,
                 command: str = "rapomdp") -> tuple[Path, Path]:
    """Write ``report.md`` and ``report.html`` (and the figures) into ``out``.

    ``inputs`` holds the folder of each of :data:`REPORT_INPUTS` in one workspace; a missing
    one raises :class:`StageError` naming it. ``fig1`` makes Fig. 1 (default
    :func:`~rapomdp.awareness.report.write_fig1`). Returns (html, markdown) paths.
    """
    given = inputs.given()
    missing = [name for name in REPORT_INPUTS if name not in given or not given[name].is_dir()]
    if missing:
        raise StageError(f"report: needs the stage(s) {', '.join(missing)}, which have not "
                         f"run; run `{command} {missing[0]} -w WORKSPACE` first")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    root = inputs.dataset.parent
    classes = load_dataset(inputs.dataset).classes
    b = _Builder(root, out)
    title = f"rapomdp report: {root.name}"
    b.add(Heading(title, 1))
    _provenance(b, config, {name: given[name] for name in REPORT_INPUTS})
    b.add(Paragraph(f"Classes ({len(classes)}): {', '.join(classes)}."))
    evaluation = _evaluation(b, inputs.evaluate, command, config.seed)
    _learned(b, inputs.learn_dir or root / "learn", command)
    _awareness(b, config, inputs, figure_class(evaluation, config, classes),
               fig1 or write_fig1, command)
    _classifier(b, inputs, command)
    _robot_and_solver(b, config, inputs, command)
    md = write_text_atomic(out / REPORT_MD, to_markdown(b.blocks))
    page = write_text_atomic(out / REPORT_HTML, to_html(b.blocks, title))
    return page, md


def run_report_stage(config: Config, inputs: StageInputs, out: Path,
                     context: RunContext) -> None:
    """The pipeline stage: the report of the workspace the inputs belong to."""
    del context  # one process, no long loops
    write_report(config, inputs, out)
