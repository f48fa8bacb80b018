"""Progress bars for long work (rich); each call says whether bars are on (the run context's
``progress``), so nothing here is process-wide state."""

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


def progress_bar(enabled: bool = True, status: bool = False) -> Progress:
    """The project's rich bar: description, bar, count, elapsed, remaining.

    With ``status`` it also shows a ``status`` field (e.g. loss and accuracy) that the caller
    updates with ``progress.update(task, status=...)``. Invisible unless ``enabled``.
    """
    columns = [
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        *([TextColumn("{task.fields[status]}")] if status else []),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
    ]
    return Progress(*columns, disable=not enabled)


def track(items: Iterable[T], description: str, enabled: bool = True,
          total: int | None = None) -> Iterator[T]:
    """Iterate over ``items`` with a progress bar showing count, elapsed and remaining time
    (just the items unless ``enabled``)."""
    if not enabled:
        yield from items
        return
    if total is None and hasattr(items, "__len__"):
        total = len(items)  # type: ignore[arg-type]
    with progress_bar(enabled) as progress:
        task = progress.add_task(description, total=total)
        for item in items:
            yield item
            progress.advance(task)
