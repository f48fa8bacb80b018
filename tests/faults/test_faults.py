"""The fault-injection suite: each bad input or fault gives a named error (or the right
result), no traceback, no file outside the workspace and no data lost."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.faults.cases import CASES
from tests.faults.harness import Case, files_outside


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_fault(case: Case, tmp_path: Path) -> None:
    outcome = case.run(tmp_path)
    assert not outcome.traceback, outcome.detail
    if case.succeeds:
        assert outcome.exit_code == 0, outcome.detail or outcome.message
    else:
        assert outcome.exit_code == 2, outcome.detail or outcome.message
        assert outcome.message.startswith("error:") or "\n" not in outcome.message
    assert case.expect in outcome.message, (outcome.message, outcome.detail)
    assert outcome.lost == []
    assert files_outside(tmp_path, ("ws", "input", "tiny.yaml", "pids")) == []


def test_every_case_of_the_issue_is_covered() -> None:
    names = {c.name for c in CASES}
    for required in ("no -c", "failed run", "status: stale", "taxonomy.json ../",
                     "billion laughs", "zero-area class", "radius .inf", "views: true",
                     "truncated .npz", "empty .npz", "manifest not UTF-8", "manifest a list",
                     "manifest {} (status)", "seed: -1", "seed: 1e23", "read-only, cached",
                     "disk full", "failed folder swap", "Latin-1 OBJ", "kill -9 mid-stage",
                     "kill -9: workers", "two runs at once", "checkpoint class list"):
        assert required in names


def test_every_case_of_issue_28_is_covered() -> None:
    names = {c.name for c in CASES}
    for required in ("Wilson at 0 % and 100 %", "--scheduler garbage", "--scheduler ''",
                     "--scheduler inproc://x", "--scheduler at an HTTP server",
                     "--scheduler at another service", "pomdp export --out DIR",
                     "pomdp export: disk full", "--benchmark 100000x3", "pomdp solve /dev/zero",
                     "run --workers 0", "preview --width 0", "preview --elevation-deg nan",
                     "reward 1e308", ".pomdp 1_000", "YAML: a second train:", "YAML: seed twice",
                     "YAML: !!set of classes", "2 GB PLY", "env.step(np.array(3))",
                     "env reset start=True", "env reset model=True", "env max_moves=inf",
                     "env max_moves=nan", "env max_moves=2.7", "pomdp errors on stderr", "Ctrl-C",
                     "disk full: npz write", "250-byte mesh name", "config -w FILE",
                     "test model = train file"):
        assert required in names
