"""The run context: how many processes and threads a run uses, and whether bars show."""

from __future__ import annotations

import dataclasses

import pytest

from rapomdp.context import QUIET, RunContext, default_workers


def test_workers_default_to_the_machine_and_workers_run_single_threaded_and_quiet() -> None:
    assert RunContext().worker_count == default_workers()
    assert 1 <= default_workers() <= 2
    assert RunContext(workers=3).worker_count == 3
    inside = RunContext(workers=4, threads=8, progress=True).in_worker()
    assert (inside.workers, inside.threads, inside.progress) == (1, 1, False)
    assert (QUIET.worker_count, QUIET.threads, QUIET.progress) == (1, 1, False)


def test_the_context_is_frozen_and_checked() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        QUIET.workers = 2  # type: ignore[misc]
    with pytest.raises(ValueError, match="workers must be at least 1, got 0"):
        RunContext(workers=0)
    with pytest.raises(ValueError, match="threads must be at least 1, got -1"):
        RunContext(threads=-1)
