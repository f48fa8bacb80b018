"""The worker pool one run's stages share: the same processes serve every task run that passes
it, a failure stops them and the next run starts new ones, and it never leaves its process."""

from __future__ import annotations

import os
import pickle

import pytest

from rapomdp import processes
from rapomdp.context import RunContext
from rapomdp.parallel import pooled, run_tasks
from rapomdp.processes import WorkerPool


def worker_pid(_: int) -> int:
    """The process a task ran in (a task of the tests below)."""
    return os.getpid()


def refuse_two(value: int) -> int:
    if value == 2:
        raise ValueError("task 2 refuses")
    return value


def test_task_runs_that_pass_the_pool_share_its_processes() -> None:
    tasks = [(i,) for i in range(6)]
    with WorkerPool(2) as pool:
        first = set(run_tasks(worker_pid, tasks, 2, "a", False, pool=pool))
        processes = set(pool.executor()._processes)  # the pool's worker pids
        assert len(processes) == 2 and first <= processes and os.getpid() not in first
        assert set(run_tasks(worker_pid, tasks, 2, "b", False, pool=pool)) <= processes
        assert set(pool.executor()._processes) == processes  # the same processes still
        # without the pool a run starts (and ends) processes of its own
        assert set(run_tasks(worker_pid, tasks, 2, "c", False)).isdisjoint(processes)
        # a run that would use other than the pool's number of processes starts its own
        assert set(run_tasks(worker_pid, tasks, 3, "d", False, pool=pool)).isdisjoint(processes)
        # one task runs here, pool or not; fewer tasks than workers still use the pool's
        assert run_tasks(worker_pid, [(0,)], 2, "e", False, pool=pool) == [os.getpid()]
        assert set(run_tasks(worker_pid, [(0,), (1,)], 2, "f", False, pool=pool)) <= processes
    assert pool._executor is None  # closed with the block


def test_a_failed_run_stops_the_pool_and_the_next_run_starts_new_processes() -> None:
    tasks = [(i,) for i in range(4)]
    with WorkerPool(2) as pool:
        run_tasks(worker_pid, tasks, 2, "a", False, pool=pool)
        before = set(pool.executor()._processes)
        with pytest.raises(ValueError, match="task 2 refuses"):
            run_tasks(refuse_two, [(1,), (2,), (3,)], 2, "refusing", False, pool=pool)
        assert pool._executor is None
        after = set(run_tasks(worker_pid, tasks, 2, "again", False, pool=pool))
        assert after <= set(pool.executor()._processes) and after.isdisjoint(before)


def test_progress_reports_reach_the_parent_through_the_pool() -> None:
    from tests.test_parallel import counted_steps

    with WorkerPool(2) as pool:
        for _ in range(2):  # the pool's one manager serves every run's queue
            assert run_tasks(counted_steps, [(3,), (4,), (1,)], 2, "steps", False,
                             sizes=[3, 4, 1], reports=True, pool=pool) == [3, 4, 1]
        assert pool._manager is not None
    assert pool._manager is None


def test_pooled_gives_a_context_its_pool_once() -> None:
    with pooled(RunContext(workers=2, progress=False)) as context:
        assert isinstance(context.pool, WorkerPool) and context.pool.workers == 2
        assert context == RunContext(workers=2, progress=False)  # the pool is not compared
        with pooled(context) as inner:
            assert inner.pool is context.pool
        assert context.in_worker().pool is None
        pool = context.pool
    assert pool._executor is None
    for alone in (RunContext(workers=1), RunContext(workers=2, scheduler="tcp://127.0.0.1:1")):
        with pooled(alone) as same:
            assert same is alone and same.pool is None


def test_a_pool_never_leaves_its_process() -> None:
    with pooled(RunContext(workers=2, progress=False)) as context:
        sent = pickle.loads(pickle.dumps(context))
        assert sent.pool is None and sent.workers == 2
        assert pickle.loads(pickle.dumps(context.pool)) is None
    with pytest.raises(ValueError, match="at least 2 workers, got 1"):
        WorkerPool(1)


def test_one_pipeline_run_starts_its_workers_once(tmp_path, monkeypatch) -> None:
    """Render, xrho and classifier_eval each run tasks over two processes: one pool serves
    them all."""
    from concurrent.futures import ProcessPoolExecutor

    from rapomdp.pipeline import run_pipeline
    from rapomdp.workspace import Workspace
    from tests.conftest import TINY_PIPELINE, tiny_config

    started: list[int] = []

    class Counted(ProcessPoolExecutor):
        def __init__(self, *args, **kwargs) -> None:  # noqa: ANN002, ANN003
            started.append(args[0])
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(processes, "ProcessPoolExecutor", Counted)
    results = run_pipeline(tiny_config(**TINY_PIPELINE), Workspace(tmp_path / "ws"),
                           until="classifier_eval",
                           context=RunContext(workers=2, threads=1, progress=False))
    assert [r.name for r in results] == ["dataset", "render", "train", "xrho",
                                         "classifier_eval"]
    assert started == [2]


def native_threads(_: int) -> tuple[list[int], str | None]:
    """The BLAS / OpenMP pools' thread counts in a worker, and its OMP_NUM_THREADS."""
    import torch
    from threadpoolctl import threadpool_info

    return ([p["num_threads"] for p in threadpool_info()] + [torch.get_num_threads()],
            os.environ.get("OMP_NUM_THREADS"))


def test_workers_run_one_native_thread_whatever_the_shell_says(monkeypatch) -> None:
    """Two workers with a BLAS thread per core each were 2x slower on 2 cores."""
    monkeypatch.setenv("OMP_NUM_THREADS", "2")
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "2")
    for counts, omp in run_tasks(native_threads, [(0,), (1,)], 2, "threads", False):
        assert counts and set(counts) == {1} and omp == "1"
