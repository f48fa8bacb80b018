"""How one run uses the machine: worker processes, PyTorch threads, progress bars.

None of it is configuration: every task is seeded on its own, so the artefacts do not depend on
it (and no stage's cache key hashes it). The CLI builds one :class:`RunContext` from its options
and passes it to every stage; a library caller passes its own, or gets ``RunContext()``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rapomdp.processes import WorkerPool


def default_workers() -> int:
    """Two processes where there are two or more usable cores, else one."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return max(1, min(2, cores or 1))


@dataclass(frozen=True)
class RunContext:
    """``workers``: processes of the stages that spread tasks (saliency, solve, evaluate; None:
    :func:`default_workers`); ``threads``: PyTorch threads (None: the classifier's default,
    ``$RAPOMDP_THREADS`` or half the cores); ``progress``: rich progress bars on or off;
    ``scheduler``: a ``dask.distributed`` scheduler address the independent tasks go to (None:
    the local process pool); ``pool``: worker processes the run's stages share
    (:func:`rapomdp.parallel.pooled`; None: each stage starts its own)."""

    workers: int | None = None
    threads: int | None = None
    progress: bool = True
    scheduler: str | None = None
    pool: WorkerPool | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        for name in ("workers", "threads"):
            value = getattr(self, name)
            if value is not None and value < 1:
                raise ValueError(f"{name} must be at least 1, got {value}")

    @property
    def worker_count(self) -> int:
        """The processes a stage uses: ``workers`` when set, else :func:`default_workers`."""
        return self.workers or default_workers()

    @property
    def uses_cluster(self) -> bool:
        """Whether tasks go to a Dask scheduler (so even one task leaves this process)."""
        return self.scheduler is not None

    def in_worker(self) -> RunContext:
        """The context of a task inside a worker process: one thread, no bars of its own."""
        return replace(self, workers=1, threads=1, progress=False, scheduler=None, pool=None)


#: One process, one thread, no progress bars: tests and quiet library use.
QUIET = RunContext(workers=1, threads=1, progress=False)
