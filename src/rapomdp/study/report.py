"""A study's report (``S/report/report.md|html``, CSVs, one accuracy–energy figure per
configuration), written from the seed workspaces' artefacts; the README's study block is
:mod:`rapomdp.study.readme` (its names stay importable here)."""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from rapomdp.config import METHOD_NAMES
from rapomdp.document import Block, Heading, Image, Paragraph, Table, to_html, to_markdown
from rapomdp.experiment.figures import tradeoff
from rapomdp.experiment.metrics import (
    CALIBRATED_ECE_NOTE,
    REPORTED_BELIEF_NOTE,
    standing_phrases,
)
from rapomdp.io import read_text, write_text_atomic
from rapomdp.study.pooled import (
    REFERENCE,
    HeldOutRow,
    PooledPoint,
    PooledRow,
    SeedResult,
    as_tradeoff_points,
    held_out_table,
    load_seed_results,
    pooled_points,
    pooled_table,
)
from rapomdp.study.readme import (  # noqa: F401
    BEGIN,
    END,
    VARY_WORDS,
    study_markdown,
    update_study_readme,
)
from rapomdp.study.spec import StudySpec
from rapomdp.workspace import Workspace

REPORT_DIR = "report"


def _interval(row: PooledRow) -> str:
    d = row.difference
    return "—" if d is None else f"{d.estimate:+.3f} [{d.low:+.3f}, {d.high:+.3f}]"


def pooled_cells(rows: Sequence[PooledRow]) -> tuple[list[str], list[list[str]]]:
    """The pooled Table 1: means over seeds, the paired difference to RA-POMDP and the
    per-seed spread."""
    ref = METHOD_NAMES.get(REFERENCE, REFERENCE)
    header = ["Method", "Accuracy (mean of seeds)", "Per seed", "SD over seeds",
              "Energy (m)", "# steps", "Confidence − accuracy", "ECE",
              "ECE if calibrated (95 %)",
              f"Δ accuracy vs {ref} [95 %, seeds × test models]", "Episodes"]
    cells = [[r.name, f"{r.accuracy:.3f}", " / ".join(f"{a:.3f}" for a in r.accuracy_by_seed),
              f"{r.accuracy_sd:.3f}", f"{r.energy_m:.3f}", f"{r.moves:.2f}",
              f"{r.overconfidence:+.3f}", f"{r.ece:.3f}", f"{r.ece_if_calibrated:.3f}",
              _interval(r), str(r.episodes)]
             for r in rows]
    return header, cells


def study_story(dataset: str, rows: Sequence[PooledRow], seeds: Sequence[int],
                vary: str) -> str:
    """Who wins on this configuration, pooled over seeds, from the numbers."""
    by = {r.method: r for r in rows}
    best = max(rows, key=lambda r: r.accuracy)
    per_seed = " / ".join(f"{a:.3f}" for a in best.accuracy_by_seed)
    parts = [f"On '{dataset}', over {len(seeds)} seeds ({', '.join(map(str, seeds))}; "
             f"{VARY_WORDS[vary]}), {best.name} is the most accurate method on average "
             f"({best.accuracy:.3f}; per seed {per_seed})."]
    ra = by.get(REFERENCE)
    if ra is not None:
        said = standing_phrases([(r.name, r.difference.estimate, r.difference.low,
                                  r.difference.high) for r in rows if r.difference is not None])
        parts.append(f"With 95 % intervals that resample seeds and, within them, test models, "
                     f"{ra.name} ({ra.accuracy:.3f} at {ra.energy_m:.2f} m) is "
                     f"{'; '.join(said)}.")
        movers = [r for r in rows if r.moves > 0]
        if movers:
            parts.append("Mean energy: " + ", ".join(f"{r.name} {r.energy_m:.2f} m"
                                                     for r in movers) + ".")
    return " ".join(parts)


def held_out_story(held: Sequence[HeldOutRow], seeds: int) -> str:
    """How RA-POMDP stood against the others on the held-out objects, pooled over seeds."""
    said = standing_phrases([(r.name, r.difference.estimate, r.difference.low,
                              r.difference.high) for r in held if r.difference is not None])
    if not said:
        return ""
    return (f"On the held-out objects (the volume models, run by the evaluate stages before "
            f"any test model was read; {seeds} seeds, intervals resampling seeds and, within "
            f"them, held-out objects) {METHOD_NAMES.get(REFERENCE, REFERENCE)} was "
            f"{'; '.join(said)}: the forecast that Table 1 above can be read against.")


def held_out_cells(held: Sequence[HeldOutRow], rows: Sequence[PooledRow]
                   ) -> tuple[list[str], list[list[str]]]:
    """Each method's held-out accuracy and energy (means of seeds), its held-out paired
    difference to RA-POMDP and, beside it, the test models' (the pooled Table 1's)."""
    ref = METHOD_NAMES.get(REFERENCE, REFERENCE)
    tested = {r.method: r for r in rows}
    header = ["Method", "Held-out accuracy (mean of seeds)", "Energy (m)",
              f"Held-out Δ vs {ref} [95 %, seeds × held-out objects]",
              f"Test Δ vs {ref} [95 %, seeds × test models]"]
    cells = []
    for r in held:
        d = r.difference
        test = tested.get(r.method)
        cells.append([r.name, f"{r.accuracy:.3f}", f"{r.energy_m:.3f}",
                      "—" if d is None else f"{d.estimate:+.3f} [{d.low:+.3f}, {d.high:+.3f}]",
                      "—" if test is None else _interval(test)])
    return header, cells


def rows_csv(dataset: str, rows: Sequence[PooledRow]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["dataset", "method", "accuracy", "accuracy_sd", "energy_m", "moves",
                     "confidence_minus_accuracy", "ece", "episodes", "difference_vs_ra",
                     "ci95_low", "ci95_high", "seeds", "ece_if_calibrated_95"])
    for r in rows:
        d = r.difference
        writer.writerow([dataset, r.method, f"{r.accuracy:.6g}", f"{r.accuracy_sd:.6g}",
                         f"{r.energy_m:.6g}", f"{r.moves:.6g}", f"{r.overconfidence:.6g}",
                         f"{r.ece:.6g}", r.episodes,
                         "" if d is None else f"{d.estimate:.6g}",
                         "" if d is None else f"{d.low:.6g}",
                         "" if d is None else f"{d.high:.6g}", len(r.accuracy_by_seed),
                         f"{r.ece_if_calibrated:.6g}"])
    return buffer.getvalue()


def seeds_csv(results: Sequence[SeedResult], rows: Sequence[PooledRow]) -> str:
    """Every seed's accuracy and energy per method (the per-seed spread)."""
    lines = ["dataset,seed,method,accuracy,energy_m"]
    for r in rows:
        for result, accuracy, energy in zip(results, r.accuracy_by_seed, r.energy_by_seed,
                                            strict=True):
            lines.append(f"{result.dataset},{result.seed},{r.method},{accuracy:.6g},"
                         f"{energy:.6g}")
    return "\n".join(lines) + "\n"


def points_csv(dataset: str, points: Sequence[PooledPoint]) -> str:
    lines = ["dataset,method,parameter,value,configured,accuracy,accuracy_min,accuracy_max,"
             "energy_m,seeds"]
    lines += [f"{dataset},{p.method},{p.parameter},{p.value:.6g},{int(p.configured)},"
              f"{p.accuracy:.6g},{p.accuracy_min:.6g},{p.accuracy_max:.6g},{p.energy_m:.6g},"
              f"{p.seeds}" for p in points]
    return "\n".join(lines) + "\n"


def study_seconds(results: Sequence[SeedResult]) -> tuple[float, float]:
    """(stage seconds the study's workspaces record, seconds the shared stages would have cost
    again). Each stage's seconds are its latest run's: a stage redone in place (a new version,
    a changed setting) counts that run, not the first."""
    spent = shared = 0.0
    for result in results:
        for name, record in Workspace(result.workspace).manifest()["stages"].items():
            spent += float(record.get("seconds", 0.0))
            if record.get("shared_from"):
                source = Workspace(record["shared_from"]).manifest()["stages"].get(name, {})
                shared += float(source.get("seconds", 0.0))
    return spent, shared


HEADROOM_FILE = Path("headroom") / "headroom.md"


def _headroom_blocks(results: Sequence[SeedResult]) -> list[Block]:
    """Each seed's headroom decomposition where it was measured (``W/headroom/``)."""
    blocks: list[Block] = []
    for result in results:
        path = result.workspace / HEADROOM_FILE
        if path.exists():
            blocks += [Heading(f"Headroom, seed {result.seed} (diagnostics: oracles counted on "
                               "the test models, never used for any choice)", 3),
                       Paragraph(read_text(path).strip())]
    return blocks


@dataclass(frozen=True)
class StudyReport:
    """Where the report was written, and each configuration's sentence of who wins."""

    html: Path
    markdown: Path
    stories: dict[str, str]


REPORTED_CONFIDENCE = ("Confidence − accuracy and ECE: " + REPORTED_BELIEF_NOTE + " "
                       + CALIBRATED_ECE_NOTE)
"""What the confidence columns of a configuration's pooled table are."""


def write_study_report(spec: StudySpec, root: str | Path,
                       resamples: int = 10_000) -> StudyReport:
    """``S/report/``: report.md and .html, table1_pooled.csv, table1_seeds.csv,
    tradeoff_pooled.csv and one ``tradeoff_<configuration>.png``.

    Table 1 pooled over the seeds of each configuration: accuracy is the mean over seeds,
    each paired difference's 95 % interval a two-stage bootstrap over seeds and test models
    (:func:`~rapomdp.study.bootstrap.hierarchical_bootstrap`).

    Args:
        spec: The study's specification (its seeds must have finished their evaluate stage).
        root: The study folder.
        resamples: Bootstrap resamples of each interval.

    Returns:
        The paths of report.html and report.md, and each configuration's sentence of who
        wins.

    Example:
        After :func:`~rapomdp.study.runner.run_study` (seconds)::

            report = write_study_report(StudySpec(seeds=(0, 1, 2)), "runs/study")
            report.html  # PosixPath('runs/study/report/report.html')
    """
    root = Path(root)
    out = root / REPORT_DIR
    out.mkdir(parents=True, exist_ok=True)
    results = load_seed_results(spec, root)
    blocks: list[Block] = [
        Heading("Study: Table 1 over seeds", 1),
        Paragraph(f"{len(spec.seeds)} seeds ({', '.join(map(str, spec.seeds))}), "
                  f"vary: {spec.vary} ({VARY_WORDS[spec.vary]}); configurations: "
                  f"{', '.join(d.name for d in spec.datasets)}. Accuracy is the mean over "
                  "seeds of each seed's accuracy; Δ is a method's paired accuracy minus "
                  "RA-POMDP's over the same (test model, start) pairs, its 95 % interval "
                  "a two-stage bootstrap that resamples seeds and, within them, test models "
                  "(crossed when every seed evaluated the same test models).")]
    pooled_csv, per_seed_csv, curves_csv = [], [], []
    stories = {}
    for name, seeds in results.items():
        rows = pooled_table(seeds, resamples)
        stories[name] = study_story(name, rows, spec.seeds, spec.vary)
        points = pooled_points(seeds)
        spent, shared = study_seconds(seeds)
        figure = f"tradeoff_{name}.png"
        if points:
            tradeoff(as_tradeoff_points(points), out / figure,
                     ylabel="accuracy (mean of seeds; bars: range over seeds)",
                     title=f"Accuracy against energy, {name}, {len(seeds)} seeds")
        header, cells = pooled_cells(rows)
        blocks += [Heading(f"Configuration '{name}'"),
                   Paragraph(stories[name]),
                   Table(header, cells),
                   Paragraph(REPORTED_CONFIDENCE)]
        held = held_out_table(seeds, resamples)
        if held:
            story = held_out_story(held, len(seeds))
            blocks += [*([Paragraph(story)] if story else []),
                       Table(*held_out_cells(held, rows))]
        blocks += [Paragraph(f"Stage time of the study's {len(seeds)} seeds: {spent:.0f} s "
                             "(each stage's latest run; shared stages counted once; sharing "
                             f"saved {shared:.0f} s).")]
        if points:
            blocks.append(Image(figure, f"Accuracy against energy on '{name}', the mean of "
                                        f"{len(seeds)} seeds (bars: the range over seeds)."))
        for result in seeds:
            blocks += [Heading(f"Seed {result.seed}", 3),
                       Paragraph(read_text(result.workspace / "evaluate" / "table1.md").strip())]
        blocks += _headroom_blocks(seeds)
        pooled_csv.append(rows_csv(name, rows))
        per_seed_csv.append(seeds_csv(seeds, rows))
        curves_csv.append(points_csv(name, points))
    write_text_atomic(out / "table1_pooled.csv", _concat(pooled_csv))
    write_text_atomic(out / "table1_seeds.csv", _concat(per_seed_csv))
    write_text_atomic(out / "tradeoff_pooled.csv", _concat(curves_csv))
    markdown = write_text_atomic(out / "report.md", to_markdown(blocks))
    html = write_text_atomic(out / "report.html", to_html(blocks, "rapomdp study"))
    return StudyReport(html, markdown, stories)


def _concat(tables: Sequence[str]) -> str:
    """CSV texts with one header."""
    head, *rest = tables
    return head + "".join(t.split("\n", 1)[1] for t in rest)
