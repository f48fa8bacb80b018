"""The runnable examples in the library's docstrings run and print what they say.

Every module whose docstrings hold a ``>>>`` example is found and its examples run (the fast
ones are doctests; slower examples are plain code blocks), each module's in a fresh namespace
of its globals. The entry points named in :data:`ENTRY_POINTS` must hold one.
"""

from __future__ import annotations

import doctest
import importlib
import re
from pathlib import Path

import pytest

SOURCE = Path(__file__).resolve().parents[1] / "src" / "rapomdp"

#: Modules of public entry points whose docstrings must hold a runnable example.
ENTRY_POINTS = {
    "rapomdp.workspace.running",  # Workspace
    "rapomdp.workspace.lock",  # Workspace.check, Workspace.locked
    "rapomdp.workspace.stages",  # StageInputs
    "rapomdp.planning.ar_solver",  # solve_active_recognition
    "rapomdp.belief",  # update_beliefs, temper, declared_belief, BayesBelief
    "rapomdp.planning.momdp",  # build_active_recognition_problem
    "rapomdp.planning.pomdp",  # POMDP, belief_update
    "rapomdp.planning.policy",  # the policies
    "rapomdp.planning.io_pomdp",  # parse_pomdp, format_pomdp
    "rapomdp.study.spec",  # StudySpec
    "rapomdp.study.bootstrap",  # hierarchical_bootstrap
    "rapomdp.geometry.camera",
    "rapomdp.geometry.viewsphere",
    "rapomdp.geometry.voxels",
    "rapomdp.robot.energy",
    "rapomdp.robot.arm",
    "rapomdp.robot.ik",
    "rapomdp.robot.scene",
    "rapomdp.robot.stage",  # ik_settings
}


def modules_with_examples() -> list[str]:
    """The modules of ``src/rapomdp`` whose text holds a ``>>>`` line."""
    found = []
    for path in sorted(SOURCE.rglob("*.py")):
        if re.search(r"^\s*>>> ", path.read_text(encoding="utf-8"), flags=re.M):
            parts = path.relative_to(SOURCE.parent).with_suffix("").parts
            found.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return found


@pytest.mark.parametrize("name", modules_with_examples())
def test_the_docstring_examples_run(name: str) -> None:
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS, report=True, verbose=False)
    assert result.attempted > 0, f"{name}: its >>> lines are in no docstring doctest finds"
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples of {name} failed"


def test_the_entry_points_hold_runnable_examples() -> None:
    assert ENTRY_POINTS <= set(modules_with_examples())
