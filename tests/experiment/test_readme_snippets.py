"""The README's Python snippets run as written (issue 15: a library that works as documented).

Each ```python block of README.md is executed in a folder where ``runs/exp1`` is the tiny
pipeline workspace of the closed-loop tests and ``Tiger.pomdp`` is the classic problem; the
planning block's free names (the arrays of your own problem, a viewpoint, a belief, a label) are
given a small problem first, as a reader's own code would."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest

from tests.planning.planning_fixtures import TIGER

README = Path(__file__).resolve().parents[2] / "README.md"


def python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


@pytest.fixture
def reader_folder(pipeline_workspace, tmp_path: Path):
    ws, _ = pipeline_workspace
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "exp1").symlink_to(ws.root)
    (tmp_path / "Tiger.pomdp").write_text(TIGER)
    before = Path.cwd()
    os.chdir(tmp_path)
    yield tmp_path
    os.chdir(before)


def test_the_readme_has_its_three_python_snippets() -> None:
    blocks = python_blocks(README.read_text())
    assert len(blocks) == 3
    assert "DepthRenderer" in blocks[0] and "solve_pomdp" in blocks[1] and "gym.make" in blocks[2]


def test_rendering_and_classifying_as_written(reader_folder) -> None:
    namespace: dict = {}
    exec(python_blocks(README.read_text())[0], namespace)
    assert namespace["depth"].shape == (128, 120, 160)
    assert namespace["points"].shape[1] == 3 and len(namespace["points"]) > 1000
    probabilities = namespace["probabilities"]
    assert probabilities.shape == (128, 3)  # the tiny workspace's three classes
    np.testing.assert_allclose(probabilities.sum(axis=1), 1.0, atol=1e-5)


def test_planning_as_written(reader_folder) -> None:
    from rapomdp.planning import benchmark_problem

    given = benchmark_problem(12, 3, seed=1)
    namespace: dict = {"P": given.observation_model, "E": given.move_energy,
                       "reachable": given.reachable, "viewpoint": 0,
                       "belief": np.full(3, 1 / 3), "label": 1}
    block = python_blocks(README.read_text())[1]
    exec(block.replace("timeout=10", "timeout=2").replace("timeout=30", "timeout=2"), namespace)
    tiger = namespace["tiger"]
    assert tiger.lower <= tiger.upper + 1e-9
    assert namespace["action"].kind in ("move", "declare")
    assert namespace["belief"].shape == (3,) and abs(namespace["belief"].sum() - 1) < 1e-9
    assert (reader_folder / "ar.pomdpx").read_text().startswith("<?xml")


def test_the_environment_as_written(reader_folder) -> None:
    namespace: dict = {}
    exec(python_blocks(README.read_text())[2], namespace)
    obs, info = namespace["obs"], namespace["info"]
    assert set(obs) == {"depth", "viewpoint"} and obs["depth"].ndim == 2
    assert "action_mask" in info and "invalid" in info
