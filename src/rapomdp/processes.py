"""The local worker processes: started with ``spawn``, one PyTorch thread each, watching their
parent (they end with it, also when it is killed), stopped at once on an interrupt; and a
:class:`WorkerPool` that keeps them for the several task runs of one pipeline run.

:mod:`rapomdp.parallel` runs tasks over them (or over a Dask cluster).
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from multiprocessing import get_context
from typing import Any

#: How often a worker process checks that its parent is alive, in seconds.
PARENT_POLL_S = 0.5


def _watch_parent(parent_pid: int) -> None:
    """End this process as soon as ``parent_pid`` is no longer its parent (it died)."""
    while os.getppid() == parent_pid:
        time.sleep(PARENT_POLL_S)
    os._exit(70)


#: The variables that size the native thread pools (OpenMP, OpenBLAS, MKL) a library reads
#: when it loads.
NATIVE_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def single_threaded_worker(parent_pid: int | None = None) -> None:
    """A worker's set-up: watch the parent (when given), one PyTorch thread and one BLAS /
    OpenMP thread. Two workers that each let OpenBLAS start a thread per core measured the
    solve stage 2x slower on 2 cores (benchmarks/results/worker_threads.txt)."""
    if parent_pid is not None:
        threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True,
                         name="rapomdp-parent-watch").start()
    for name in NATIVE_THREAD_VARIABLES:  # libraries loaded from now on
        os.environ[name] = "1"
    import numpy  # noqa: F401 - its BLAS loaded, to be limited below
    import torch
    from threadpoolctl import threadpool_limits

    torch.set_num_threads(1)
    threadpool_limits(1)  # the pools of libraries loaded already


@contextmanager
def sigint_held() -> Iterator[None]:
    """SIGINT held back (blocked, not lost) in this thread while it starts worker processes:
    they inherit the block, so a Ctrl-C (sent to the whole process group) reaches only this
    process, which stops them (no traceback of theirs); the held signal arrives at the end."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def stop_executor(pool: ProcessPoolExecutor) -> None:
    """Cancel what is queued and end the workers now (an interrupt must not wait for them)."""
    # taken before the shutdown, which drops the pool's table of processes
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        if process.is_alive():
            process.terminate()


def _report_queue(parent_pid: int) -> Any:
    """A queue the workers' reports reach the parent through: a manager process's, started
    with SIGINT held (a Ctrl-C is the parent's to handle) and ending with its parent."""
    from multiprocessing.managers import SyncManager

    manager = SyncManager(ctx=get_context("spawn"))
    with sigint_held():
        manager.start(_watched_helper, (parent_pid,))
    return manager


def _watched_helper(parent_pid: int) -> None:
    """A helper process's set-up: watch the parent (no PyTorch)."""
    threading.Thread(target=_watch_parent, args=(parent_pid,), daemon=True,
                     name="rapomdp-parent-watch").start()


def _no_pool() -> None:
    """What a :class:`WorkerPool` becomes when pickled: none (it belongs to its process)."""
    return None


class WorkerPool:
    """``workers`` single-threaded worker processes kept for every task run of one pipeline
    run (its stages) instead of new ones per :func:`rapomdp.parallel.run_tasks` call: starting
    them (spawn, importing PyTorch) costs a call about 3 s of wall time on 2 cores.

    Started on first use. A call that fails or is interrupted stops them, and the next call
    starts new ones. Pickled (a :class:`~rapomdp.context.RunContext` sent to a worker) it
    becomes ``None``: a worker process has no pool of its own."""

    def __init__(self, workers: int) -> None:
        if workers < 2:
            raise ValueError(f"a worker pool needs at least 2 workers, got {workers}")
        self.workers = workers
        self._executor: ProcessPoolExecutor | None = None
        self._manager: Any = None

    def executor(self) -> ProcessPoolExecutor:
        """The pool's processes (started with the first submission)."""
        if self._executor is None:
            self._executor = ProcessPoolExecutor(self.workers, mp_context=get_context("spawn"),
                                                 initializer=single_threaded_worker,
                                                 initargs=(os.getpid(),))
        return self._executor

    def report_queue(self) -> Any:
        """A new queue for one call's progress reports, through the pool's manager process."""
        if self._manager is None:
            self._manager = _report_queue(os.getpid())
        return self._manager.Queue()

    def stop(self) -> None:
        """End the workers now, dropping queued tasks (after a failure or an interrupt)."""
        executor, self._executor = self._executor, None
        if executor is not None:
            stop_executor(executor)
        self._shut_manager()

    def close(self) -> None:
        """End the workers once their tasks are done."""
        executor, self._executor = self._executor, None
        if executor is not None:
            executor.shutdown(wait=True)
        self._shut_manager()

    def _shut_manager(self) -> None:
        manager, self._manager = self._manager, None
        if manager is not None:
            manager.shutdown()

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, kind: object, *_: object) -> None:
        if kind is None:
            self.close()
        else:
            self.stop()

    def __reduce__(self) -> tuple[Callable[[], None], tuple[()]]:
        return _no_pool, ()


