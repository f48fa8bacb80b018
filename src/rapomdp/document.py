"""The document layer: blocks of a report, written as Markdown and as one HTML page.

A report is a list of blocks (:data:`Block`: headings, paragraphs, tables, images, links,
preformatted text and missing-artefact lines); :func:`to_markdown` and :func:`to_html` write
the same list as the two pages. Every Markdown table of the package — a report's, and those the
stages write on their own (``table1.md``, ``quality.md``, ``headroom.md``) — is laid out by
:func:`markdown_table`, every HTML table by :func:`table_html`. :class:`Builder` collects a
report's blocks and copies the figures they show into its folder.

It sits with the foundations (it imports :mod:`rapomdp.io` only), so every stage may write
tables through it.
"""

from __future__ import annotations

import html
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from rapomdp.io import ArtefactError, atomic_path, read_json

T = TypeVar("T")


# --- the blocks -------------------------------------------------------------------------------


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


# --- tables -----------------------------------------------------------------------------------


def _md_cell(text: str) -> str:
    return text.replace("|", "\\|")


def _table_lines(header: Sequence[str], rows: Sequence[Sequence[str]],
                 cell: Callable[[str], str]) -> list[str]:
    lines = ["| " + " | ".join(cell(c) for c in header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(c) for c in row) + " |" for row in rows]
    return lines


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A Markdown table of string cells, written as they are (a stage's ``.md`` file).

    Args:
        header: The header row's cells.
        rows: The body's rows, each as many cells as ``header``.

    Returns:
        The table, one row a line, a ``|---|`` rule under the header, newline-terminated.
    """
    return "\n".join(_table_lines(header, rows, str)) + "\n"


def table_html(table: Table) -> str:
    """One ``<table>`` with a header row; cells are escaped.

    Args:
        table: The table block.

    Returns:
        The ``<table>`` element (no trailing newline).
    """
    head = "".join(f"<th>{html.escape(c)}</th>" for c in table.header)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>"
        for row in table.rows
    )
    return f"<table>\n<thead><tr>{head}</tr></thead>\n<tbody>{body}</tbody>\n</table>"


# --- the two pages ----------------------------------------------------------------------------


def to_markdown(blocks: Sequence[Block]) -> str:
    """The blocks as one Markdown page.

    Args:
        blocks: The page's blocks, in order.

    Returns:
        The page: blocks separated by a blank line, images as relative links, a table's ``|``
        inside a cell escaped; newline-terminated.
    """
    parts = []
    for block in blocks:
        if isinstance(block, Heading):
            parts.append(f"{'#' * block.level} {block.text}")
        elif isinstance(block, Paragraph):
            parts.append(block.text)
        elif isinstance(block, Table):
            parts.append("\n".join(_table_lines(block.header, block.rows, _md_cell)))
        elif isinstance(block, Image):
            parts.append(f"![{block.caption}]({block.file})\n\n*{block.caption}*")
        elif isinstance(block, Link):
            parts.append(f"{block.text} [{block.label}]({block.file})")
        elif isinstance(block, Code):
            parts.append(f"{block.summary}:\n\n```yaml\n{block.text.rstrip()}\n```")
        else:
            parts.append(f"> **Missing:** {block.what} — {block.how}")
    return "\n\n".join(parts) + "\n"


_STYLE = (
    "body{font-family:sans-serif;max-width:60em;margin:2em auto;padding:0 1em;color:#222}"
    "table{border-collapse:collapse;margin:1em 0}th,td{border:1px solid #bbb;padding:.25em .6em;"
    "text-align:left}th{background:#eee}figure{margin:1.5em 0}img{max-width:100%}"
    "figcaption{font-style:italic;color:#444}.missing{background:#fff4e0;padding:.4em .8em;"
    "border-left:4px solid #e0a030}code{background:#f2f2f2;padding:0 .2em}"
)


def to_html(blocks: Sequence[Block], title: str) -> str:
    """The blocks as one self-styled HTML page.

    Args:
        blocks: The page's blocks, in order.
        title: The page's ``<title>``.

    Returns:
        The page, every text escaped, images as relative ``<img>`` links; newline-terminated.
    """
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


# --- gathering a report -----------------------------------------------------------------------


class Builder:
    """Collects blocks and copies the figures they show into the report folder.

    Args:
        root: The folder paths are shown relative to (a workspace).
        out: The report folder.
    """

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
        """The JSON object in ``source``, or a missing line saying why not."""
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
        """``path`` relative to the root when it is inside it, else as it is."""
        try:
            return str(path.relative_to(self.root))
        except ValueError:
            return str(path)
