"""Independent tasks: the local pool and a Dask cluster give the same results, in task order;
a worker that dies, a scheduler that cannot be reached and a task's own error are named."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rapomdp.parallel import WorkerError, run_tasks
from tests.faults.harness import foreign_service

distributed = pytest.importorskip("distributed")


def seeded_draws(seed: int, size: int) -> np.ndarray:
    """A task whose result depends only on its arguments (as every stage's task does)."""
    return np.random.default_rng(seed).normal(size=size)


def _power(base: int, exponent: int) -> int:
    return base**exponent


def test_results_come_back_in_task_order_whatever_the_workers() -> None:
    tasks = [(b, e) for b in range(4) for e in range(3)]
    expected = [b**e for b, e in tasks]
    assert run_tasks(_power, tasks, 1, "serial", progress=False) == expected
    assert run_tasks(_power, tasks, 2, "two processes", progress=False) == expected
    assert run_tasks(_power, [], 2, "nothing", progress=False) == []


def refuse(value: int) -> int:
    if value == 2:
        raise ValueError(f"task {value} refuses")
    return value


@pytest.fixture(scope="module")
def cluster():
    """One in-process Dask worker (seconds to start; the tasks are this module's)."""
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as local:
        yield local


@pytest.fixture
def on_dask(cluster) -> str:
    return cluster.scheduler_address


def test_dask_gives_the_local_results_in_task_order(on_dask) -> None:
    tasks = [(seed, 5 + seed) for seed in range(6)]
    remote = run_tasks(seeded_draws, tasks, 1, "draws", scheduler=on_dask)
    local = run_tasks(seeded_draws, tasks, 1, "draws")
    assert [len(r) for r in remote] == [5 + s for s in range(6)]
    for a, b in zip(remote, local, strict=True):
        assert a.tobytes() == b.tobytes()


def test_a_tasks_own_error_in_a_worker_process_comes_back_as_it_is() -> None:
    with pytest.raises(ValueError, match="task 2 refuses"):
        run_tasks(refuse, [(1,), (2,), (3,)], 2, "refusing", progress=False)


def test_a_tasks_own_error_comes_back_as_it_is(on_dask) -> None:
    with pytest.raises(ValueError, match="task 2 refuses"):
        run_tasks(refuse, [(1,), (2,), (3,)], 1, "refusing", scheduler=on_dask)


def test_solve_on_dask_writes_the_local_policies(on_dask, tmp_path: Path) -> None:
    from rapomdp.planning.momdp import benchmark_problem
    from rapomdp.planning.workspace import solve_workspace_problems

    problem = benchmark_problem(12, 3, seed=2)
    models = {"a": problem.observation_model, "b": problem.observation_model[::-1].copy()}
    arrays = (problem.move_energy, None)
    solve_workspace_problems(models, *arrays, tmp_path / "dask", max_iterations=4, workers=1,
                             scheduler=on_dask)
    solve_workspace_problems(models, *arrays, tmp_path / "local", max_iterations=4, workers=1)
    for name in ("a", "b"):
        remote = np.load(tmp_path / "dask" / f"policy_{name}.npz")
        local = np.load(tmp_path / "local" / f"policy_{name}.npz")
        assert remote.files == local.files
        for key in local.files:
            assert remote[key].tobytes() == local[key].tobytes(), (name, key)


def test_an_unreachable_scheduler_is_named() -> None:
    with pytest.raises(WorkerError, match="cannot reach the Dask scheduler at tcp://127"):
        run_tasks(seeded_draws, [(0, 1)], 1, "draws", scheduler="tcp://127.0.0.1:9")


def test_the_scheduler_is_validated_and_in_no_stage_key() -> None:
    from rapomdp.config import ConfigError, config_from_dict
    from rapomdp.pipeline import STAGES

    assert config_from_dict({"parallel": {"scheduler": "tcp://10.0.0.5:8786"}}).parallel \
        .scheduler == "tcp://10.0.0.5:8786"
    with pytest.raises(ConfigError, match="parallel.scheduler"):
        config_from_dict({"parallel": {"scheduler": "10.0.0.5 8786"}})
    assert not any("parallel" in stage.sections for stage in STAGES)


@pytest.mark.parametrize(("address", "expect"), [
    ("garbage", "not a dask.distributed scheduler address"),
    ("", "not a dask.distributed scheduler address"),
    ("inproc://x", "no scheduler of this process has that address")])
def test_a_scheduler_address_is_checked_before_any_task(address: str, expect: str) -> None:
    from rapomdp.parallel import check_scheduler

    with pytest.raises(WorkerError, match=expect):
        check_scheduler(address)
    with pytest.raises(WorkerError, match=expect):
        run_tasks(seeded_draws, [(0, 1)], 1, "draws", scheduler=address)


def test_an_inproc_scheduler_of_this_process_is_accepted(on_dask) -> None:
    from rapomdp.parallel import check_scheduler

    assert check_scheduler(on_dask) == on_dask


@pytest.mark.parametrize(("reply", "expect"), [
    (None, "no Dask handshake within 2 s"),
    (b"SSH-2.0-OpenSSH_9.6\r\n" + b"\xff" * 64, "the service there is not a Dask scheduler")])
def test_a_service_that_is_not_a_scheduler_is_named_within_the_handshake_bound(
        reply: bytes | None, expect: str) -> None:
    import time

    from rapomdp.parallel import check_scheduler

    with foreign_service(reply) as address:
        start = time.monotonic()
        with pytest.raises(WorkerError, match=expect):
            check_scheduler(address, timeout_s=2.0)
    assert time.monotonic() - start < 6


def blocked_signals(_: int) -> set[int]:
    """The signals a worker holds blocked (a task of the test below)."""
    import signal

    return {int(s) for s in signal.pthread_sigmask(signal.SIG_BLOCK, [])}


def test_workers_leave_ctrl_c_to_the_parent() -> None:
    """A Ctrl-C reaches the whole process group: the workers hold SIGINT blocked, so only
    the parent is interrupted (it stops them) and no worker prints a traceback."""
    import signal

    masks = run_tasks(blocked_signals, [(0,), (1,)], 2, "masks", progress=False)
    assert all(int(signal.SIGINT) in mask for mask in masks)
    assert int(signal.SIGINT) not in blocked_signals(0)  # the parent's block is lifted


def counted_steps(steps: int, report) -> int:  # noqa: ANN001 - a TaskReport
    """A task that reports one unit per step (as evaluate reports episodes)."""
    for _ in range(steps):
        report(1)
    return steps


@pytest.mark.parametrize("workers", [1, 2])
def test_the_bar_counts_units_the_tasks_report_as_they_go(monkeypatch, workers: int) -> None:
    from rich.progress import Progress

    from rapomdp import parallel

    made: list[Progress] = []
    advances: list[float] = []

    class Recording(Progress):
        def advance(self, task_id, advance=1):  # noqa: ANN001, ANN201
            advances.append(advance)
            super().advance(task_id, advance)

    def bar(enabled: bool = True, status: bool = False) -> Progress:
        made.append(Recording(disable=True))
        return made[-1]

    monkeypatch.setattr(parallel, "progress_bar", bar)
    sizes = [3, 5, 2]
    done = run_tasks(counted_steps, [(n,) for n in sizes], workers, "episodes", unit="episodes",
                     sizes=sizes, reports=True)
    assert done == sizes
    task = made[-1].tasks[0]
    assert (task.total, task.completed, task.fields["unit"]) == (10, 10, "episodes")
    assert sum(advances) == 10 and max(advances) <= 1  # step by step, nothing counted twice
    # without reports a task's units count when it ends
    advances.clear()
    assert run_tasks(_power, [(2, 1), (2, 2)], workers, "models", unit="models",
                     sizes=[4, 6]) == [2, 4]
    assert sorted(advances) == [4, 6] and made[-1].tasks[0].completed == 10
    with pytest.raises(ValueError, match="2 sizes for 3 tasks"):
        run_tasks(_power, [(1, 1)] * 3, 1, "x", progress=False, sizes=[1, 2])
