"""The ``report`` stage: one markdown and one HTML page gathering a workspace's results.

``W/report/`` holds ``report.md`` and ``report.html`` and a copy of every figure they show (PNG),
so the folder is self-contained. The report reads, from the stages it needs:

- ``evaluate``: ``table1.md``, ``per_class.md``, ``fig3.png``, ``trajectories.png`` and
  ``evaluate.json`` (episodes, images, images/s, methods, figure class, seconds);
- ``observe``: ``quality.md`` (self-awareness table) and ``calibration.png``;
- ``classifier_eval``: ``metrics.json``, ``confusion_xrho.png``, ``accuracy_hemisphere.png``;
- ``train``: ``training.png``; ``robot``: ``robot.json`` and ``robot.png``;
- ``solve``: ``solve_summary.json`` (the solver's bounds per observation model);
- Fig. 1, made here for the figure class from the render, saliency, volume and observe stages.

and, when present (they are not among its inputs): ``W/figures/fig2.png`` (``rapomdp figure
fig2``, expensive: it trains three classifiers) and ``W/vptree/vptree.json`` (the VP-tree
baseline). A missing file gives a line saying what is missing and which command makes it.
"""

from __future__ import annotations

import csv
import html
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rapomdp.awareness.report import FIGURES_DIR, write_fig1
from rapomdp.config import Config
from rapomdp.data.dataset import load_dataset
from rapomdp.experiment.evaluation import figure_class as evaluation_figure_class
from rapomdp.io import ArtefactError, atomic_path, read_json, write_text_atomic
from rapomdp.robot.stage import describe
from rapomdp.workspace import StageError, Workspace, read_stage_record, stable_hash

REPORT_SECTIONS = ("seed",)
REPORT_INPUTS = ("dataset", "train", "classifier_eval", "observe", "robot", "solve", "evaluate")
REPORT_MD = "report.md"
REPORT_HTML = "report.html"


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
class Missing:
    what: str
    how: str  # the command (or reason) that makes it


Block = Heading | Paragraph | Table | Image | Missing


def _split_row(line: str) -> list[str]:
    line = line.strip()
    if line.startswith("|"):
        line = line[1:]
    if line.endswith("|") and not line.endswith("\\|"):
        line = line[:-1]
    cells, current, escaped = [], "", False
    for char in line:
        if char == "|" and not escaped:
            cells.append(current.strip())
            current = ""
        else:
            current += char
        escaped = char == "\\" and not escaped
    cells.append(current.strip())
    return [cell.replace("\\|", "|") for cell in cells]


def _is_delimiter(cells: Sequence[str]) -> bool:
    return bool(cells) and all(c and set(c) <= set(":-") and "-" in c for c in cells)


def parse_markdown(text: str) -> list[Block]:
    """Blocks of a simple markdown text: pipe tables (a header, a ``|---|`` row, body rows),
    ``#`` headings and paragraphs (consecutive other lines). Enough for the stages' tables."""
    blocks: list[Block] = []
    lines = text.splitlines()
    i, paragraph = 0, []

    def flush() -> None:
        if paragraph:
            blocks.append(Paragraph(" ".join(paragraph)))
            paragraph.clear()

    while i < len(lines):
        line = lines[i].strip()
        if (line.startswith("|") and i + 1 < len(lines)
                and _is_delimiter(_split_row(lines[i + 1]))):
            flush()
            header = _split_row(line)
            rows = []
            i += 2
            while i < len(lines) and lines[i].strip().startswith("|"):
                cells = _split_row(lines[i])
                rows.append((cells + [""] * len(header))[: len(header)])
                i += 1
            blocks.append(Table(header, rows))
            continue
        if line.startswith("#"):
            flush()
            level = len(line) - len(line.lstrip("#"))
            blocks.append(Heading(line[level:].strip(), min(level, 6)))
        elif line:
            paragraph.append(line)
        else:
            flush()
        i += 1
    flush()
    return blocks


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

    def figure(self, source: Path, caption: str, how: str, name: str | None = None) -> None:
        """Copy ``source`` into the report (as ``name``) with its caption, or say it is
        missing and how to make it."""
        if not source.is_file():
            self.missing(f"{self._shown(source)} (not found)", how)
            return
        name = name or source.name
        target = self.out / name
        if source.resolve() != target.resolve():
            with atomic_path(target) as tmp:
                shutil.copyfile(source, tmp)
        self.blocks.append(Image(name, caption))

    def markdown(self, source: Path, how: str) -> None:
        """The tables (and text) of a markdown file, or a missing line."""
        if not source.is_file():
            self.missing(f"{self._shown(source)} (not found)", how)
            return
        blocks = parse_markdown(source.read_text())
        if not any(isinstance(b, Table) for b in blocks):
            self.missing(f"{self._shown(source)} holds no markdown table", how)
        self.blocks.extend(blocks)

    def json(self, source: Path, how: str) -> dict[str, Any] | None:
        if not source.is_file():
            self.missing(f"{self._shown(source)} (not found)", how)
            return None
        try:
            data = read_json(source)
        except ArtefactError as exc:
            self.missing(str(exc), how)
            return None
        if not isinstance(data, dict):
            self.missing(f"{self._shown(source)} is not a JSON object", how)
            return None
        return data

    def _shown(self, path: Path) -> str:
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


def _provenance(builder: _Builder, config: Config, inputs: dict[str, Path]) -> None:
    builder.add(Paragraph(
        f"Configuration hash {stable_hash(config.model_dump(mode='json'))[:12]}, "
        f"seed {config.seed}, workspace {builder.root}."))
    rows = []
    for name, folder in inputs.items():
        try:
            record = read_stage_record(folder)
        except StageError:
            rows.append([name, "-", "-", "-"])
            continue
        rows.append([name, str(record.get("key", "-"))[:12], str(record.get("finished", "-")),
                     _fmt(record.get("seconds", "-"), 1)])
    builder.add(Table(["stage", "key", "finished", "seconds"], rows))


def _evaluation(b: _Builder, folder: Path, cmd: str) -> dict[str, Any] | None:
    how = f"made by `{cmd} evaluate -w {b.root}`"
    b.add(Heading("Closed-loop recognition (Table 1)"))
    data = b.json(folder / "evaluate.json", how)
    if data is not None:
        seconds = data.get("seconds", {})
        timing = ", ".join(f"{k} {_fmt(v, 1)} s" for k, v in seconds.items()) \
            if isinstance(seconds, dict) else _fmt(seconds)
        methods = data.get("methods", [])
        b.add(Paragraph(
            f"{data.get('episodes', '?')} episodes of the methods "
            f"{', '.join(map(str, methods)) if isinstance(methods, list) else methods}; "
            f"{data.get('images', '?')} depth images rendered and classified "
            f"({_fmt(data.get('images_per_s', '?'), 1)} images/s). Time: {timing or '-'}."))
    b.markdown(folder / "table1.md", how)
    b.add(Paragraph("Per class:"))
    b.markdown(folder / "per_class.md", how)
    figure = (data or {}).get("figure_class", "the figure class")
    b.figure(folder / "fig3.png",
             f"Fig. 3: belief in the true class along the episodes of class {figure}, per "
             f"method (step 0 is the start viewpoint).", how)
    b.figure(folder / "trajectories.png",
             "The camera's trajectories on the test viewsphere X_rho, per method.", how)
    if (folder / "tradeoff.png").exists():
        b.add(Heading("Accuracy against energy"))
        b.figure(folder / "tradeoff.png",
                 "Accuracy against mean movement energy: each POMDP method solved at every "
                 "λ of evaluate.lambdas, Random at every stop belief, from the same (test "
                 "model, start) pairs as Table 1.", how)
        b.markdown(folder / "tradeoff.md", how)
    return data


def _awareness(b: _Builder, config: Config, inputs: dict[str, Path], class_name: str,
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
        b.add(Paragraph(f"Interactive 3D version: {page.name} (in this folder)."))
    fig2 = b.root / FIGURES_DIR / "fig2.png"
    b.figure(fig2, "Fig. 2: one class's saliency volume in two-class problems and in the "
                   "all-class problem.",
             f"made by `{cmd} figure fig2 -w {b.root}` (trains three two-class classifiers, "
             f"so the report does not make it)")
    observe_how = f"made by `{cmd} observe -w {b.root}`"
    b.add(Paragraph("How well each observation model predicts the classifier's correctness on "
                    "the test models over X_rho:"))
    b.markdown(inputs["observe"] / "quality.md", observe_how)
    b.figure(inputs["observe"] / "calibration.png",
             "Calibration: the classifier's accuracy per viewpoint-score bin on the held-out "
             "evidence, and the fitted score-to-correctness map of RA-POMDP's model.",
             observe_how)
    _self_awareness(b, inputs, class_name, observe_how)


def _self_awareness(b: _Builder, inputs: dict[str, Path], class_name: str, how: str) -> None:
    """Held-out validation, predicted vs observed P(correct), one class's hemispheres and the
    calibration of every method's final belief."""
    from rapomdp.awareness.quality import expected_calibration_error
    from rapomdp.awareness.report import write_awareness_figures

    observe = inputs["observe"]
    if (observe / "validation.md").exists():
        b.add(Paragraph("Held-out validation (what chose RA-POMDP's model): each group of the "
                        "held-out evidence scored by the models fitted without it:"))
        b.markdown(observe / "validation.md", how)
    try:
        rel, hemi = write_awareness_figures(observe, class_name, b.out)
    except (StageError, ArtefactError, KeyError) as exc:
        b.missing(f"the self-awareness figures could not be made ({exc})", how)
    else:
        b.figure(rel, "Predicted against observed P(correct) on the test models, per "
                      "observation model (single view, before the belief's temperature).",
                 how, rel.name)
        b.figure(hemi, f"Class {class_name}: predicted P(correct) per viewpoint (RA, "
                       f"Classifier) beside the test models' actual accuracy.", how, hemi.name)
    episodes = inputs["evaluate"] / "episodes.csv"
    if episodes.exists():
        with open(episodes) as handle:
            records = list(csv.DictReader(handle))
        rows = []
        for method in dict.fromkeys(r["method"] for r in records):
            belief = np.array([float(r["belief"]) for r in records if r["method"] == method])
            right = np.array([int(r["correct"]) for r in records if r["method"] == method])
            rows.append([method, _fmt(float(right.mean())), _fmt(float(belief.mean())),
                         _fmt(float(belief.mean() - right.mean())),
                         _fmt(expected_calibration_error(belief, right))])
        b.add(Paragraph("Calibration of every method's final belief in the closed loop "
                        "(ECE: 10 equal-width bins):"))
        b.add(Table(["method", "accuracy", "mean final belief", "belief − accuracy", "ECE"],
                    rows))


def _classifier(b: _Builder, inputs: dict[str, Path], cmd: str) -> None:
    b.add(Heading("Single-view classifier"))
    how = f"made by `{cmd} evaluate-classifier -w {b.root}`"
    metrics = b.json(inputs["classifier_eval"] / "metrics.json", how)
    if metrics is not None:
        rows = []
        for key, label in (("xrho", "test viewpoints X_rho"), ("sphere", "whole sphere")):
            part = metrics.get(key)
            if isinstance(part, dict):
                rows.append([label, _fmt(part.get("images", "-")),
                             _fmt(part.get("accuracy", "-")), _fmt(part.get("chance", "-"))])
        b.add(Table(["test views", "images", "accuracy", "chance"], rows))
    b.figure(inputs["classifier_eval"] / "confusion_xrho.png",
             "Single-view confusion of the classifier on the test models over X_rho.", how)
    b.figure(inputs["classifier_eval"] / "accuracy_hemisphere.png",
             "Single-view accuracy and mean probability of the true class per test viewpoint.",
             how)
    b.figure(inputs["train"] / "training.png",
             "Training curves: loss and accuracy per epoch.",
             f"made by `{cmd} train -w {b.root}`")
    vptree = b.root / "vptree" / "vptree.json"
    how = f"made by `{cmd} vptree -w {b.root}` (the VP-tree baseline)"
    if vptree.is_file():
        data = b.json(vptree, how)
        if data is not None:
            b.add(Paragraph(f"VP-tree baseline (vocabulary tree), single-view accuracy on the "
                            f"test models over X_rho: {_fmt(data.get('accuracy_test_xrho', '?'))}"
                            f"."))
    else:
        b.missing("VP-tree baseline accuracy (vptree/vptree.json not found)", how)


def _robot_and_solver(b: _Builder, inputs: dict[str, Path], cmd: str) -> None:
    b.add(Heading("Robot and planner"))
    how = f"made by `{cmd} robot -w {b.root}`"
    summary = b.json(inputs["robot"] / "robot.json", how)
    if summary is not None:
        try:
            b.add(Paragraph(f"Panda arm: {describe(summary)}."))
        except (KeyError, TypeError) as exc:
            b.missing(f"robot/robot.json lacks {exc}", how)
    b.figure(inputs["robot"] / "robot.png",
             "The Panda's reachability of the test viewpoints, coloured by manipulability, with "
             "the arm drawn at a few of its solutions.", how)
    how = f"made by `{cmd} solve -w {b.root}`"
    bounds = b.json(inputs["solve"] / "solve_summary.json", how)
    if bounds is not None:
        rows = [[str(name), _fmt(v.get("lower", "-"), 4), _fmt(v.get("upper", "-"), 4),
                 _fmt(v.get("seconds", "-"), 1), _fmt(v.get("vectors", "-"))]
                for name, v in bounds.items() if isinstance(v, dict)]
        b.add(Paragraph("The solver's bounds on the value of the start belief, per observation "
                        "model (values are negative costs, metres of energy):"),
              Table(["observation model", "lower", "upper", "seconds", "alpha vectors"], rows))


def write_report(config: Config, inputs: dict[str, Path], out: Path,
                 fig1: Callable[..., tuple[Path, Path]] | None = None,
                 command: str = "rapomdp") -> tuple[Path, Path]:
    """Write ``report.md`` and ``report.html`` (and the figures) into ``out``.

    ``inputs`` maps each of :data:`REPORT_INPUTS` to its stage folder in one workspace;
    a missing one raises :class:`StageError` naming it. ``fig1`` makes Fig. 1 (default
    :func:`~rapomdp.awareness.report.write_fig1`). Returns (html, markdown) paths.
    """
    missing = [name for name in REPORT_INPUTS if name not in inputs
               or not Path(inputs[name]).is_dir()]
    if missing:
        raise StageError(f"report: needs the stage(s) {', '.join(missing)}, which have not "
                         f"run; run `{command} {missing[0]} -w WORKSPACE` first")
    inputs = {name: Path(inputs[name]) for name in REPORT_INPUTS}
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    root = inputs["dataset"].parent
    classes = load_dataset(inputs["dataset"]).classes
    b = _Builder(root, out)
    title = f"rapomdp report: {root.name}"
    b.add(Heading(title, 1))
    _provenance(b, config, inputs)
    b.add(Paragraph(f"Classes ({len(classes)}): {', '.join(classes)}."))
    evaluation = _evaluation(b, inputs["evaluate"], command)
    _awareness(b, config, inputs, figure_class(evaluation, config, classes),
               fig1 or write_fig1, command)
    _classifier(b, inputs, command)
    _robot_and_solver(b, inputs, command)
    md = write_text_atomic(out / REPORT_MD, to_markdown(b.blocks))
    page = write_text_atomic(out / REPORT_HTML, to_html(b.blocks, title))
    return page, md


def run_report_stage(config: Config, inputs: dict[str, Path], out: Path) -> None:
    """The pipeline stage: the report of the workspace the inputs belong to."""
    write_report(config, inputs, out)
