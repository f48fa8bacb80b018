"""Independent tasks over worker processes, one PyTorch thread each, with a progress bar; or
over a Dask cluster when a scheduler is named.

On the small shared machines this project targets, two single-threaded processes use two cores
far better than one process with two PyTorch threads (see docs/recognition.md). Workers are
started with ``spawn`` (safe whatever threads the parent has started); each task must be a
module-level function of picklable arguments, and results come back in task order. A worker
watches its parent and ends with it, also when the parent is killed (SIGKILL); the stages of
one run share their workers (:func:`pooled`, :mod:`rapomdp.processes`).

How many workers, whether a bar shows and which scheduler come from the caller's
:class:`~rapomdp.context.RunContext`. With a scheduler (``--scheduler tcp://host:port`` or
``parallel.scheduler`` in the configuration) the same tasks are submitted to that
``dask.distributed`` scheduler instead:
every task is seeded on its own, so the results are bit-identical to the local pool's. Tasks
read and write the workspace, which the Dask workers must see at the same path (a shared
file system). See docs/scale-out.md.
"""

from __future__ import annotations

import asyncio
import functools
import os
import re
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import ExitStack, contextmanager
from dataclasses import replace
from typing import TYPE_CHECKING, Any, TypeVar

from rapomdp.config import SCHEDULER_PATTERN
from rapomdp.processes import WorkerPool, sigint_held, single_threaded_worker
from rapomdp.progress import progress_bar

if TYPE_CHECKING:
    from rapomdp.context import RunContext

R = TypeVar("R")


#: How long the scheduler's handshake may take before the address is refused, in seconds.
HANDSHAKE_TIMEOUT_S = 10.0
#: How often the parent reads the workers' progress reports, in seconds.
REPORT_POLL_S = 0.25


class WorkerError(RuntimeError):
    """A worker process died, or the Dask cluster cannot be used (named)."""


@functools.cache
def _set_up_dask_worker(pid: int) -> None:
    """Set up a Dask worker process once (cached per process id)."""
    single_threaded_worker(None)


def _dask_task(function: Callable[..., R], client_pid: int, task: tuple[Any, ...]) -> R:
    """One task on a Dask worker; a worker process is set up as the local pool's are (one
    PyTorch thread), a worker thread of the client's own process is left alone."""
    if os.getpid() != client_pid:
        _set_up_dask_worker(os.getpid())
    return function(*task)


async def _identity(address: str, timeout_s: float) -> object:
    """What the service at ``address`` says it is (Dask's handshake, then ``identity``)."""
    from distributed.comm import connect

    comm = await connect(address, timeout=timeout_s)
    try:
        await comm.write({"op": "identity", "reply": True})
        return await comm.read()
    finally:
        comm.abort()


def check_scheduler(address: str, timeout_s: float | None = None) -> str:
    """``address`` if a Dask scheduler answers there, else :class:`WorkerError` naming it: the
    configuration's pattern first, then (``inproc://``) a scheduler of this process, else a
    handshake bounded by ``timeout_s`` (default :data:`HANDSHAKE_TIMEOUT_S`)."""
    if not isinstance(address, str) or not re.fullmatch(SCHEDULER_PATTERN, address):
        raise WorkerError(f"scheduler {str(address)[:80]!r}: not a dask.distributed scheduler "
                          "address (e.g. tcp://10.0.0.5:8786)")
    try:
        from distributed.comm.inproc import global_manager
    except ImportError:
        raise WorkerError(f"scheduler {address}: dask.distributed is not installed "
                          "(pip install 'rapomdp[dask]')") from None
    if address.startswith("inproc://"):
        if address.removeprefix("inproc://") not in global_manager.listeners:
            raise WorkerError(f"scheduler {address}: no scheduler of this process has that "
                              "address (inproc:// is a LocalCluster in the same Python "
                              "process; a separate one is tcp://host:port)")
        return address
    timeout_s = HANDSHAKE_TIMEOUT_S if timeout_s is None else timeout_s
    try:
        reply = asyncio.run(asyncio.wait_for(_identity(address, timeout_s), timeout_s + 1.0))
    except (TimeoutError, asyncio.TimeoutError):
        raise WorkerError(f"scheduler {address}: no Dask handshake within {timeout_s:g} s "
                          "(another service on that port, or none?)") from None
    except OSError as exc:
        raise WorkerError(f"cannot reach the Dask scheduler at {address} "
                          f"({' '.join(str(exc).split())[:200]})") from None
    except Exception as exc:  # noqa: BLE001 - whatever a foreign service makes Dask read
        raise WorkerError(f"scheduler {address}: the service there is not a Dask scheduler "
                          f"(Dask cannot read what it sent: {type(exc).__name__})") from None
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        raise WorkerError(f"scheduler {address}: the service there is not a Dask scheduler "
                          f"(it says it is {str(reply)[:60]!r})")
    return address


def _run_on_dask(function: Callable[..., R], tasks: Sequence[tuple[Any, ...]],
                 description: str, scheduler: str, progress: bool, unit: str = "tasks",
                 sizes: Sequence[int] | None = None) -> list[R]:
    try:
        from distributed import Client
        from distributed import as_completed as dask_completed
        from distributed.scheduler import KilledWorker
    except ImportError:
        raise WorkerError(f"scheduler {scheduler}: dask.distributed is not installed "
                          "(pip install 'rapomdp[dask]')") from None
    check_scheduler(scheduler)
    try:
        client = Client(scheduler, timeout="20s", set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise WorkerError(f"cannot reach the Dask scheduler at {scheduler} ({exc})") from None
    results: dict[int, R] = {}
    with client, progress_bar(progress) as bars:
        sizes = [1] * len(tasks) if sizes is None else sizes
        bar = bars.add_task(f"{description} (dask)", total=sum(sizes), unit=unit)
        futures = [client.submit(_dask_task, function, os.getpid(), task, pure=False)
                   for task in tasks]
        index = {future.key: i for i, future in enumerate(futures)}
        try:
            for future in dask_completed(futures, loop=client.loop):
                results[index[future.key]] = future.result()
                bars.advance(bar, sizes[index[future.key]])
        except KilledWorker as exc:
            raise WorkerError(f"{description}: Dask workers died running a task ({exc}); "
                              "out of memory?") from None
        finally:
            client.cancel([f for f in futures if not f.done()])
    return [results[i] for i in range(len(tasks))]


class TaskReport:
    """What a task of :func:`run_tasks` (with ``reports``) is given as its last argument:
    ``report(units)`` advances the bar by ``units`` as the task goes (from a worker process,
    through a queue the parent reads); picklable."""

    def __init__(self, index: int, queue: Any = None,
                 advance: Callable[[int, int], None] | None = None) -> None:
        self.index, self._queue, self._advance = index, queue, advance

    def __call__(self, units: int = 1) -> None:
        if self._queue is not None:
            self._queue.put((self.index, int(units)))
        elif self._advance is not None:
            self._advance(self.index, int(units))

    def __getstate__(self) -> dict[str, Any]:  # the bar's callback stays in the parent
        return {"index": self.index, "_queue": self._queue, "_advance": None}


@contextmanager
def pooled(context: RunContext) -> Iterator[RunContext]:
    """``context`` with a :class:`WorkerPool` of its ``worker_count`` processes, shared by
    every call that passes it on until the block ends; ``context`` itself when it has a pool
    already, sends tasks to a Dask scheduler, or uses one process."""
    if context.pool is not None or context.uses_cluster or context.worker_count < 2:
        yield context
        return
    with WorkerPool(context.worker_count) as pool:
        yield replace(context, pool=pool)


def run_tasks(function: Callable[..., R], tasks: Sequence[tuple[Any, ...]], workers: int,
              description: str, progress: bool = True,
              scheduler: str | None = None, unit: str = "tasks",
              sizes: Sequence[int] | None = None, reports: bool = False,
              pool: WorkerPool | None = None) -> list[R]:
    """``[function(*task) for task in tasks]``, on the Dask ``scheduler`` when one is named,
    else over ``workers`` processes when more than one (in this process otherwise), with a
    progress bar when ``progress``. A worker that dies raises :class:`WorkerError`. The
    processes are ``pool``'s when it has exactly as many as the call would use (else new
    ones, ended when the call is).

    The bar counts ``unit`` (``models``, ``solves``, ``episodes``): each task is ``sizes[i]``
    of them (default 1). With ``reports`` each task is called with a :class:`TaskReport` as
    its last argument and reports its units as it goes (on a Dask cluster the bar moves when
    a task ends); whatever a task did not report is counted when it ends.
    """
    sizes = [1] * len(tasks) if sizes is None else [int(n) for n in sizes]
    if len(sizes) != len(tasks):
        raise ValueError(f"{description}: {len(sizes)} sizes for {len(tasks)} tasks")
    if scheduler is not None and tasks:
        if reports:
            tasks = [(*task, TaskReport(i)) for i, task in enumerate(tasks)]
        return _run_on_dask(function, tasks, description, scheduler, progress, unit, sizes)
    workers = max(1, min(workers, len(tasks)))
    results: dict[int, R] = {}
    reported = [0] * len(tasks)
    with progress_bar(progress) as bars:
        bar = bars.add_task(description, total=sum(sizes), unit=unit)

        def advance(index: int, units: int) -> None:
            units = max(0, min(units, sizes[index] - reported[index]))
            reported[index] += units
            bars.advance(bar, units)

        if workers == 1:
            for i, task in enumerate(tasks):
                extra = (TaskReport(i, advance=advance),) if reports else ()
                results[i] = function(*task, *extra)
                advance(i, sizes[i])
            return [results[i] for i in range(len(tasks))]
        with ExitStack() as owned:
            if pool is None or min(pool.workers, len(tasks)) != workers:
                pool = owned.enter_context(WorkerPool(workers))
            queue = pool.report_queue() if reports else None

            def drain() -> None:
                while queue is not None and not queue.empty():
                    advance(*queue.get())

            try:
                executor = pool.executor()
                with sigint_held():  # the workers start on the first submissions
                    futures = {executor.submit(function, *task,
                                               *((TaskReport(i, queue),) if reports else ())): i
                               for i, task in enumerate(tasks)}
                pending = set(futures)
                while pending:
                    done, pending = wait(pending, timeout=REPORT_POLL_S,
                                         return_when=FIRST_COMPLETED)
                    drain()
                    for future in done:
                        results[futures[future]] = future.result()
                        advance(futures[future], sizes[futures[future]])
            except BrokenProcessPool:
                pool.stop()
                raise WorkerError(f"{description}: a worker process died (killed, or out of "
                                  "memory); nothing of this stage was kept") from None
            except BaseException:
                pool.stop()
                raise
    return [results[i] for i in range(len(tasks))]
