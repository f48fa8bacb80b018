"""Progress bars for long work (rich), quiet when asked."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import TypeVar

from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

T = TypeVar("T")

_enabled = True


def set_progress(enabled: bool) -> None:
    """Turn progress bars on or off for this process (tests and libraries turn them off)."""
    global _enabled
    _enabled = enabled


def progress_bar(status: bool = False) -> Progress:
    """The project's rich bar: description, bar, count, elapsed, remaining.

    With ``status`` it also shows a ``status`` field (e.g. loss and accuracy) that the caller
    updates with ``progress.update(task, status=...)``. Disabled when bars are off.
    """
    columns = [
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        *([TextColumn("{task.fields[status]}")] if status else []),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
    ]
    return Progress(*columns, disable=not _enabled)


def track(items: Iterable[T], description: str, total: int | None = None) -> Iterator[T]:
    """Iterate over ``items`` with a progress bar showing count, elapsed and remaining time."""
    if not _enabled:
        yield from items
        return
    if total is None and hasattr(items, "__len__"):
        total = len(items)  # type: ignore[arg-type]
    with progress_bar() as progress:
        task = progress.add_task(description, total=total)
        for item in items:
            yield item
            progress.advance(task)
