"""Independent tasks over worker processes, one PyTorch thread each, with a progress bar.

On the small shared machines this project targets, two single-threaded processes use two cores
far better than one process with two PyTorch threads (see docs/recognition.md). Workers are
started with ``spawn`` (safe whatever threads the parent has started); each task must be a
module-level function of picklable arguments, and results come back in task order.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing import get_context
from typing import Any, TypeVar

from rapomdp.progress import progress_bar

R = TypeVar("R")


#: Worker processes of the stages that spread work over processes (saliency, evaluate); the
#: CLI's --workers sets it (None: :func:`default_workers`). Not part of the configuration:
#: every task is seeded on its own, so results do not depend on it.
workers: int | None = None


def default_workers() -> int:
    """Two processes where there are two or more usable cores, else one."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return max(1, min(2, cores or 1))


def worker_count() -> int:
    """The processes a stage uses: ``workers`` when set, else :func:`default_workers`."""
    return workers or default_workers()


def _single_threaded_worker() -> None:
    import torch

    from rapomdp.progress import set_progress
    from rapomdp.recognition import stage

    set_progress(False)
    torch.set_num_threads(1)
    stage.threads = 1


def run_tasks(function: Callable[..., R], tasks: Sequence[tuple[Any, ...]], workers: int,
              description: str) -> list[R]:
    """``[function(*task) for task in tasks]``, over ``workers`` processes when more than one
    (in this process otherwise), with a progress bar."""
    workers = max(1, min(workers, len(tasks)))
    results: dict[int, R] = {}
    with progress_bar() as progress:
        bar = progress.add_task(description, total=len(tasks))
        if workers == 1:
            for i, task in enumerate(tasks):
                results[i] = function(*task)
                progress.advance(bar)
        else:
            with ProcessPoolExecutor(workers, mp_context=get_context("spawn"),
                                     initializer=_single_threaded_worker) as pool:
                futures = {pool.submit(function, *task): i for i, task in enumerate(tasks)}
                for future in as_completed(futures):
                    results[futures[future]] = future.result()
                    progress.advance(bar)
    return [results[i] for i in range(len(tasks))]
