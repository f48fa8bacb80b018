r"""The README's example run, generated from a finished workspace so that it cannot drift.

``rapomdp report -w runs/demo --readme README.md`` replaces the block between `BEGIN`
and `END` in the README with one sentence and one table, both from the evaluate stage's
Table 1 (``W/evaluate/table1.md``): which method was most accurate on this run and how
RA-POMDP stands against each other method (`table1_sentence`). The evaluate stage's
figures are copied next to the README (``--readme-figures``, default ``docs/figures`` beside
it; the documentation shows them), and so is the report's Fig. 1, the README's lead figure
(`LEAD_FIGURE`). Nothing in the block is typed by hand.

Examples:
    >>> table = ("| Method | Accuracy [95 % CI] | Δ accuracy vs RA-POMDP [95 % CI] |\n"
    ...          "|---|---|---|\n| Random | 0.700 [0.6, 0.8] | -0.100 [-0.150, -0.050] |\n"
    ...          "| RA-POMDP | 0.800 [0.7, 0.9] | — |\n")
    >>> print(table1_sentence(table))  # doctest: +NORMALIZE_WHITESPACE
    On this run RA-POMDP is the most accurate method (0.800); over the same (test model,
    start) pairs, with 95 % intervals that resample test models, RA-POMDP is more accurate
    than Random (by 0.100).
"""

from __future__ import annotations

import platform
import re
import shutil
from collections.abc import Sequence
from pathlib import Path

from rapomdp.config import Config
from rapomdp.data.dataset import load_dataset
from rapomdp.experiment.episode_table import SUMMARY_FILE
from rapomdp.experiment.metrics import standing_phrases
from rapomdp.experiment.report import figure_class
from rapomdp.io import atomic_path, check_output_path, read_json, write_text_atomic
from rapomdp.workspace import StageError, Workspace

BEGIN = "<!-- BEGIN generated results: rapomdp report --readme (do not edit by hand) -->"
END = "<!-- END generated results -->"

#: Figures of the evaluate stage shown in the README: (file in W/evaluate, name beside it).
README_FIGURES = (("tradeoff.png", "demo_tradeoff.png"), ("fig3.png", "demo_fig3.png"),
                  ("trajectories.png", "demo_trajectories.png"))
#: The README's lead figure, beside it: the report's Fig. 1 of the figure class
#: (`lead_figure`).
LEAD_FIGURE = "demo_fig1.png"


def _read(path: Path) -> str:
    if not path.exists():
        raise StageError(f"{path}: not found; run the stage that makes it "
                         f"(rapomdp run -w {path.parent.parent})")
    return path.read_text(encoding="utf-8").strip()


def markdown_tables(text: str) -> list[tuple[list[str], list[list[str]]]]:
    """Every pipe table of a Markdown text, as (header, rows of cells), in order.

    Args:
        text: Markdown, as `rapomdp.document.markdown_table` writes tables (one row a line,
            cells between ``|``, a ``|---|`` rule under the header).

    Returns:
        One ``(header, rows)`` per table; cells are stripped strings.
    """
    tables: list[tuple[list[str], list[list[str]]]] = []
    lines = text.splitlines()
    i = 0
    while i + 1 < len(lines):
        head, rule = lines[i].strip(), lines[i + 1].strip()
        if head.startswith("|") and re.fullmatch(r"\|(\s*:?-+:?\s*\|)+", rule):
            rows = []
            i += 2
            while i < len(lines) and lines[i].strip().startswith("|"):
                rows.append([c.strip() for c in lines[i].strip().strip("|").split("|")])
                i += 1
            tables.append(([c.strip() for c in head.strip("|").split("|")], rows))
        else:
            i += 1
    return tables


def interval_cell(cell: str) -> tuple[float, float, float] | None:
    """``"-0.195 [-0.254, -0.134]"`` as (estimate, low, high); None for ``"—"`` (the
    reference's own row) or an empty cell."""
    match = re.match(r"\s*([-+]?\d+(?:\.\d+)?)\s*\[\s*([-+]?\d+(?:\.\d+)?)\s*,"
                     r"\s*([-+]?\d+(?:\.\d+)?)\s*\]", cell)
    if match is None:
        return None
    estimate, low, high = (float(g) for g in match.groups())
    return estimate, low, high


def leading_number(cell: str) -> float:
    """The number a cell starts with (``"0.857 [0.826, 0.884]"`` -> 0.857)."""
    match = re.match(r"\s*([-+]?\d+(?:\.\d+)?)", cell)
    if match is None:
        raise ValueError(f"not a number: {cell!r}")
    return float(match.group(1))


def _column(header: Sequence[str], prefix: str) -> int | None:
    return next((i for i, h in enumerate(header) if h.startswith(prefix)), None)


def table1_sentence(table1: str) -> str:
    """One sentence saying what Table 1 shows, from its Markdown (``W/evaluate/table1.md``).

    Args:
        table1: Table 1 as the evaluate stage writes it: a ``Method`` column, an ``Accuracy``
            column and, where the methods were paired, a ``Δ accuracy vs <reference>`` column
            (the reference's own cell ``—``).

    Returns:
        Which method is the most accurate and, with the paired column, how the reference
        stands against each other method ("more accurate than A (by 0.1)", "not
        distinguishable from B": an interval holding 0).

    Raises:
        ValueError: the text holds no table with ``Method`` and ``Accuracy`` columns.
    """
    for header, rows in markdown_tables(table1):
        method, accuracy = _column(header, "Method"), _column(header, "Accuracy")
        if method is None or accuracy is None or not rows:
            continue
        best = max(rows, key=lambda r: leading_number(r[accuracy]))
        sentence = (f"On this run {best[method]} is the most accurate method "
                    f"({leading_number(best[accuracy]):.3f})")
        delta = _column(header, "Δ accuracy vs ")
        if delta is not None:
            reference = header[delta][len("Δ accuracy vs "):].split(" [")[0]
            said = standing_phrases([(r[method], *interval)
                                     for r in rows
                                     if (interval := interval_cell(r[delta])) is not None])
            if said:
                sentence += ("; over the same (test model, start) pairs, with 95 % intervals "
                             f"that resample test models, {reference} is {' and '.join(said)}")
        return sentence + "."
    raise ValueError("no table with Method and Accuracy columns")


def results_markdown(workspace: Workspace, figures_link: str = "docs/figures",
                     seed: int = 0) -> str:
    """The generated block (without its markers) for a workspace whose stages have all run.

    Args:
        workspace: a workspace whose evaluate stage has run.
        figures_link: unused; kept for callers that pass the README's figures folder.
        seed: the configuration's seed, named in the block's first line.

    Returns:
        Three paragraphs: where the numbers come from, `table1_sentence`, and Table 1.

    Raises:
        StageError: the evaluate stage has not run.
    """
    del figures_link
    if "evaluate" not in workspace.manifest()["stages"]:
        raise StageError(f"{workspace.root}: stage(s) evaluate have not run; "
                         f"run `rapomdp run -w {workspace.root}` first")
    table1 = _read(workspace.require("evaluate") / "table1.md")
    return "\n".join([
        f"*Generated by `rapomdp report --readme` from the workspace `{workspace.root.name}` "
        f"(seed {seed}; Python {platform.python_version()}, {platform.machine()}).*",
        "",
        table1_sentence(table1),
        "",
        table1,
    ])


def lead_figure(workspace: Workspace) -> Path | None:
    """The report's Fig. 1 (``W/report/fig1_<class>.png``, the class of Figs. 1 and 3:
    `rapomdp.experiment.report.figure_class`), or None before the report has run."""
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
    (`README_FIGURES`) and, once the report has run, its Fig. 1 as the README's lead
    figure (`LEAD_FIGURE`). The README must hold the markers."""
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
