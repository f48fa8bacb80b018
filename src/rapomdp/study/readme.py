r"""The README's headline claim: one table and one sentence, generated from a study.

The block between `BEGIN` and `END` in the README is written by code, from either
of two sources that give the same block for the same study:

- a study folder (``rapomdp study -s S --report-only --readme README.md``:
  `update_study_readme`), pooling its seed workspaces;
- the Markdown report such a study wrote (``S/report/report.md``, as committed under
  ``benchmarks/results/``), where the seed workspaces are not on the machine:
  ``python -m rapomdp.study.readme --readme README.md REPORT.md [REPORT.md ...]``
  (`update_study_readme_from_reports`).

Both go through the numbers as the report prints them (three decimals), so a study folder and
its report give the same block. The table has one row per method and, per configuration, the
accuracy (mean of seeds), the energy and the paired difference to RA-POMDP with its 95 %
interval; the sentence says how RA-POMDP stands on each configuration.

Examples:
    >>> report = '''5 seeds (0, 1, 2, 3, 4), vary: all (each seed its own split).
    ...
    ... ## Configuration 'default'
    ...
    ... | Method | Accuracy (mean of seeds) | Energy (m) | Δ accuracy vs RA-POMDP [95 %] |
    ... |---|---|---|---|
    ... | Random | 0.795 | 1.016 | -0.043 [-0.067, -0.020] |
    ... | RA-POMDP | 0.838 | 0.944 | — |
    ... '''
    >>> headline = headline_from_report(report, "report.md")
    >>> print(headline_sentence(headline))  # doctest: +NORMALIZE_WHITESPACE
    Over 5 seeds (0, 1, 2, 3, 4; each seed its own split, models, classifier and starts), with
    95 % intervals that resample seeds and, within them, test models, RA-POMDP is more
    accurate than Random (by 0.043) on 'default' (0.838 at 0.94 m).
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from rapomdp.config import METHOD_NAMES
from rapomdp.document import markdown_table
from rapomdp.experiment.metrics import standing_phrases
from rapomdp.experiment.readme import interval_cell, leading_number, markdown_tables
from rapomdp.io import read_text, write_text_atomic
from rapomdp.study.pooled import REFERENCE, PooledRow, load_seed_results, pooled_table
from rapomdp.study.spec import StudySpec
from rapomdp.workspace import StageError

BEGIN = "<!-- BEGIN generated study results: rapomdp study --readme (do not edit by hand) -->"
END = "<!-- END generated study results -->"
VARY_WORDS = {"all": "each seed its own split, models, classifier and starts",
              "train": "the same split, models and starts; each seed its own classifier"}
#: The pooled table's columns the headline reads (the study report's header, by prefix).
ACCURACY, ENERGY, DELTA = "Accuracy (mean of seeds)", "Energy (m)", "Δ accuracy vs "


@dataclass(frozen=True)
class Standing:
    """One method on one configuration, as the study's pooled table prints it.

    Attributes:
        method: the method's display name (``"RA-POMDP"``).
        accuracy: the mean over seeds of each seed's accuracy (0 to 1).
        energy_m: the mean movement energy per episode, metres.
        difference: the method's paired accuracy minus the reference's with its 95 %
            interval, (estimate, low, high); None for the reference itself.
    """

    method: str
    accuracy: float
    energy_m: float
    difference: tuple[float, float, float] | None


@dataclass(frozen=True)
class Headline:
    """A study's pooled results, as the README shows them.

    Attributes:
        seeds: the study's seeds.
        vary: what a seed varies (``"all"`` or ``"train"``).
        reference: the reference method's display name (RA-POMDP).
        configurations: per configuration (in the study's order), its methods' standings.
    """

    seeds: tuple[int, ...]
    vary: str
    reference: str
    configurations: dict[str, list[Standing]]


def standings(rows: Sequence[PooledRow]) -> list[Standing]:
    """A configuration's pooled rows rounded as the study report prints them (three
    decimals), so that the folder and its report give the same headline."""
    def printed(value: float) -> float:
        return float(f"{value:.3f}")

    return [Standing(r.name, printed(r.accuracy), printed(r.energy_m),
                     None if r.difference is None else
                     (printed(r.difference.estimate), printed(r.difference.low),
                      printed(r.difference.high)))
            for r in rows]


def headline_from_study(spec: StudySpec, root: str | Path,
                        resamples: int = 10_000) -> Headline:
    """The headline of a study folder whose seeds have run (pooled as its report pools them).

    Args:
        spec: the study's seeds, vary and configurations (``S/study.yaml``).
        root: the study folder ``S``.
        resamples: bootstrap resamples of each paired interval.

    Returns:
        Every configuration's standings.
    """
    results = load_seed_results(spec, root)
    return Headline(tuple(spec.seeds), spec.vary, METHOD_NAMES.get(REFERENCE, REFERENCE),
                    {name: standings(pooled_table(seeds, resamples))
                     for name, seeds in results.items()})


def headline_from_report(text: str, source: str | Path) -> Headline:
    """The headline of a study's Markdown report (``S/report/report.md``).

    Args:
        text: the report's Markdown, as ``rapomdp study --report-only`` writes it: a line
            ``N seeds (0, 1, ...), vary: V`` and, under each ``## Configuration 'name'``
            heading, the pooled table first.
        source: the report's path, for error messages.

    Returns:
        Every configuration's standings, in the report's order.

    Raises:
        StageError: the report has no seeds line, no configuration, or a configuration
            without its pooled table (the message names ``source``).
    """
    seeds_line = re.search(r"^(\d+) seeds \(([\d, ]+)\), vary: (\w+)", text, re.MULTILINE)
    if seeds_line is None:
        raise StageError(f"{source}: not a study report (no line 'N seeds (...), vary: ...')")
    seeds = tuple(int(s) for s in seeds_line.group(2).split(","))
    sections = re.split(r"^## Configuration '([^']+)'\s*$", text, flags=re.MULTILINE)
    configurations: dict[str, list[Standing]] = {}
    reference = ""
    for name, body in zip(sections[1::2], sections[2::2], strict=True):
        table = next(((h, rows) for h, rows in markdown_tables(body)
                      if "Method" in h and ACCURACY in h), None)
        if table is None:
            raise StageError(f"{source}: configuration '{name}' has no pooled table")
        header, rows = table
        delta = next(i for i, h in enumerate(header) if h.startswith(DELTA))
        reference = header[delta][len(DELTA):].split(" [")[0]
        method, accuracy, energy = (header.index(c) for c in ("Method", ACCURACY, ENERGY))
        configurations[name] = [Standing(r[method], leading_number(r[accuracy]),
                                         leading_number(r[energy]), interval_cell(r[delta]))
                                for r in rows]
    if not configurations:
        raise StageError(f"{source}: no '## Configuration' section")
    return Headline(seeds, seeds_line.group(3), reference, configurations)


def merge_headlines(headlines: Sequence[Headline], sources: Sequence[str | Path]) -> Headline:
    """Several reports' headlines as one table (the same seeds, vary and reference).

    Raises:
        StageError: the reports differ in seeds, vary or reference, or name one configuration
            twice.
    """
    first = headlines[0]
    configurations: dict[str, list[Standing]] = {}
    for headline, source in zip(headlines, sources, strict=True):
        if (headline.seeds, headline.vary, headline.reference) != (
                first.seeds, first.vary, first.reference):
            raise StageError(f"{source}: seeds {list(headline.seeds)}, vary {headline.vary}; "
                             f"the first report has seeds {list(first.seeds)}, vary "
                             f"{first.vary}: one table needs the same seeds")
        for name, rows in headline.configurations.items():
            if name in configurations:
                raise StageError(f"{source}: configuration '{name}' is in an earlier report")
            configurations[name] = rows
    return Headline(first.seeds, first.vary, first.reference, configurations)


def headline_sentence(headline: Headline) -> str:
    """One sentence: how the reference stands on each configuration (an interval that holds 0
    is "not distinguishable"), with its accuracy and energy."""
    said = []
    for name, rows in headline.configurations.items():
        phrases = standing_phrases([(r.method, *r.difference) for r in rows
                                    if r.difference is not None])
        own = next((r for r in rows if r.difference is None), None)
        where = f"on '{name}'" + ("" if own is None else
                                  f" ({own.accuracy:.3f} at {own.energy_m:.2f} m)")
        said.append(f"{' and '.join(phrases) or 'alone'} {where}")
    seeds = ", ".join(map(str, headline.seeds))
    return (f"Over {len(headline.seeds)} seeds ({seeds}; {VARY_WORDS[headline.vary]}), with "
            "95 % intervals that resample seeds and, within them, test models, "
            f"{headline.reference} is {'; '.join(said)}.")


def headline_table(headline: Headline) -> str:
    """One Markdown table: a row per method; per configuration its accuracy (mean of seeds),
    energy (m) and paired difference to the reference [95 %] (``—`` where a configuration
    did not run the method, or for the reference itself)."""
    methods: list[str] = []
    for rows in headline.configurations.values():
        methods += [r.method for r in rows if r.method not in methods]
    header = ["Method"]
    for name in headline.configurations:
        header += [f"'{name}' accuracy", "energy (m)", f"Δ vs {headline.reference} [95 %]"]
    body = []
    for method in methods:
        cells = [method]
        for rows in headline.configurations.values():
            row = next((r for r in rows if r.method == method), None)
            if row is None:
                cells += ["—", "—", "—"]
                continue
            d = row.difference
            cells += [f"{row.accuracy:.3f}", f"{row.energy_m:.2f}",
                      "—" if d is None else f"{d[0]:+.3f} [{d[1]:+.3f}, {d[2]:+.3f}]"]
        body.append(cells)
    return markdown_table(header, body).rstrip("\n")


def headline_markdown(headline: Headline, source: str) -> str:
    """The README's study block (without its markers): where it comes from, the sentence
    and the table."""
    return "\n".join([f"*Generated by `rapomdp study --readme` from {source}.*", "",
                      headline_sentence(headline), "", headline_table(headline)])


def study_markdown(spec: StudySpec, root: str | Path, resamples: int = 10_000) -> str:
    """The README's study block (without its markers) from a study folder."""
    return headline_markdown(headline_from_study(spec, root, resamples),
                             f"the study `{Path(root).name}`")


def replace_block(readme: str | Path, block: str) -> Path:
    """Write ``block`` between the README's study markers (the rest unchanged).

    Raises:
        StageError: the README lacks the markers (the message shows them).
    """
    readme = Path(readme)
    text = read_text(readme)
    start, end = text.find(BEGIN), text.find(END)
    if start < 0 or end < start:
        raise StageError(f"{readme}: no generated study block; add the two lines\n{BEGIN}\n"
                         f"{END}\nwhere the study's results should go")
    return write_text_atomic(readme, text[:start] + BEGIN + "\n" + block + "\n" + text[end:])


def update_study_readme(spec: StudySpec, root: str | Path, readme: str | Path) -> Path:
    """Replace the README's study block with what the study folder's seeds say."""
    return replace_block(readme, study_markdown(spec, root))


def update_study_readme_from_reports(reports: Sequence[str | Path],
                                     readme: str | Path) -> Path:
    """Replace the README's study block with what committed study reports say.

    Args:
        reports: study reports (``S/report/report.md``), their configurations side by side
            in one table, in this order.
        readme: the README holding the markers.

    Returns:
        The README's path.
    """
    if not reports:
        raise StageError("no study report given")
    headline = merge_headlines([headline_from_report(read_text(p), p) for p in reports],
                               reports)
    names = ", ".join(f"`{Path(p).as_posix()}`" for p in reports)
    return replace_block(readme, headline_markdown(headline, names))


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m rapomdp.study.readme --readme README.md REPORT.md...``; exit status 2 with
    one line ``error: ...`` on a bad report or README."""
    parser = argparse.ArgumentParser(
        prog="python -m rapomdp.study.readme",
        description="Write the README's study block from committed study reports "
                    "(S/report/report.md of `rapomdp study --report-only`).")
    parser.add_argument("reports", nargs="+", type=Path, help="study reports, in table order")
    parser.add_argument("--readme", type=Path, default=Path("README.md"),
                        help="the README holding the study block's markers")
    args = parser.parse_args(argv)
    try:
        sys.stdout.write(f"{update_study_readme_from_reports(args.reports, args.readme)}\n")
    except (StageError, OSError) as exc:
        sys.stderr.write(f"error: {exc}\n")
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
