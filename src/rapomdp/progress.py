"""Progress bars for long work (rich); each call says whether bars are on (the run context's
``progress``), so nothing here is process-wide state. A bar counts units a user knows
(``12/385 models``, ``140/560 episodes``): its task's ``unit`` field."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import TypeVar

from rich.progress import (
    BarColumn,
    Progress,
    ProgressColumn,
    Task,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.text import Text

T = TypeVar("T")


class CountColumn(ProgressColumn):
    """``12/385 models``: units done, the total (``?`` when unknown) and the task's ``unit``
    field when it has one."""

    def render(self, task: Task) -> Text:
        total = "?" if task.total is None else f"{int(task.total)}"
        unit = task.fields.get("unit", "")
        return Text(f"{int(task.completed)}/{total}" + (f" {unit}" if unit else ""),
                    style="progress.download")


def progress_bar(enabled: bool = True, status: bool = False) -> Progress:
    """The project's rich bar: description, bar, count (and unit), elapsed, remaining.

    With ``status`` it also shows a ``status`` field (e.g. loss and accuracy) that the caller
    updates with ``progress.update(task, status=...)``. Invisible unless ``enabled``.
    """
    columns = [
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        CountColumn(),
        *([TextColumn("{task.fields[status]}")] if status else []),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
    ]
    return Progress(*columns, disable=not enabled)


def track(items: Iterable[T], description: str, enabled: bool = True,
          total: int | None = None, unit: str = "") -> Iterator[T]:
    """Iterate over ``items`` with a progress bar showing count (of ``unit``: ``models``),
    elapsed and remaining time (just the items unless ``enabled``)."""
    if not enabled:
        yield from items
        return
    if total is None and hasattr(items, "__len__"):
        total = len(items)  # type: ignore[arg-type]
    with progress_bar(enabled) as progress:
        task = progress.add_task(description, total=total, unit=unit)
        for item in items:
            yield item
            progress.advance(task)
