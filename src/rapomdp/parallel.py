"""Independent tasks over worker processes, one PyTorch thread each, with a progress bar.

On the small shared machines this project targets, two single-threaded processes use two cores
far better than one process with two PyTorch threads (see docs/recognition.md). Workers are
started with ``spawn`` (safe whatever threads the parent has started); each task must be a
module-level function of picklable arguments, and results come back in task order. How many
workers, and whether a bar shows, come from the caller's :class:`~rapomdp.context.RunContext`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from typing import Any, TypeVar

from rapomdp.progress import progress_bar

R = TypeVar("R")


def _single_threaded_worker() -> None:
    import torch

    torch.set_num_threads(1)


def run_tasks(function: Callable[..., R], tasks: Sequence[tuple[Any, ...]], workers: int,
              description: str, progress: bool = True) -> list[R]:
    """``[function(*task) for task in tasks]``, over ``workers`` processes when more than one
    (in this process otherwise), with a progress bar when ``progress``."""
    workers = max(1, min(workers, len(tasks)))
    results: dict[int, R] = {}
    with progress_bar(progress) as bar:
        task_bar = bar.add_task(description, total=len(tasks))
        if workers == 1:
            for i, task in enumerate(tasks):
                results[i] = function(*task)
                bar.advance(task_bar)
        else:
            with ProcessPoolExecutor(workers, mp_context=get_context("spawn"),
                                     initializer=_single_threaded_worker) as pool:
                futures = {pool.submit(function, *task): i for i, task in enumerate(tasks)}
                for future in as_completed(futures):
                    results[futures[future]] = future.result()
                    bar.advance(task_bar)
    return [results[i] for i in range(len(tasks))]
