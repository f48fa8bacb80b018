"""Independent tasks in this process or over worker processes, results in task order."""

from __future__ import annotations

from rapomdp.parallel import run_tasks


def _power(base: int, exponent: int) -> int:
    return base**exponent


def test_results_come_back_in_task_order_whatever_the_workers() -> None:
    tasks = [(b, e) for b in range(4) for e in range(3)]
    expected = [b**e for b, e in tasks]
    assert run_tasks(_power, tasks, 1, "serial", progress=False) == expected
    assert run_tasks(_power, tasks, 2, "two processes", progress=False) == expected
    assert run_tasks(_power, [], 2, "nothing", progress=False) == []
