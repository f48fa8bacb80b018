"""rapomdp.planning stands alone: its API from one import, and neither it nor any
`rapomdp pomdp` command loads torch, the robot toolbox or the pipeline's stages."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import rapomdp.planning as planning
from tests.planning.planning_fixtures import TIGER

HEAVY = ("torch", "roboticstoolbox", "trimesh", "matplotlib", "rapomdp.pipeline",
         "rapomdp.robot", "rapomdp.recognition")

PROBE = """
import json, sys
{body}
print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in {{'torch',
      'roboticstoolbox', 'trimesh', 'matplotlib'}} or m.startswith(('rapomdp.pipeline',
      'rapomdp.robot', 'rapomdp.recognition')))))
"""


def loaded_after(body: str, cwd: Path) -> list[str]:
    out = subprocess.run([sys.executable, "-c", PROBE.format(body=body)], capture_output=True,
                         text=True, cwd=cwd, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_the_api_is_exported_with_all() -> None:
    for name in planning.__all__:
        assert getattr(planning, name) is not None, name
    for name in ("ActiveRecognitionProblem", "build_active_recognition_problem",
                 "solve_active_recognition", "solve_pomdp", "ActiveRecognitionPolicy",
                 "AlphaVectorPolicy", "read_pomdp", "write_pomdp", "write_pomdpx",
                 "MemoryCapError"):
        assert name in planning.__all__


def test_import_and_pomdp_commands_load_no_torch_nor_robot(tmp_path: Path) -> None:
    assert loaded_after("import rapomdp.planning", tmp_path) == []
    tiger = tmp_path / "Tiger.pomdp"
    tiger.write_text(TIGER)
    solve = (f"from rapomdp.cli import app\n"
             f"try:\n    app(['pomdp', 'solve', {str(tiger)!r}, '--timeout', '2'])\n"
             f"except SystemExit as e:\n    assert e.code in (0, None), e.code\n")
    assert loaded_after(solve, tmp_path) == []
    export = (f"from rapomdp.cli import app\n"
              f"try:\n    app(['pomdp', 'export', '--benchmark', '4x3', '--solve', '0.2',"
              f" '--out', {str(tmp_path / 'x.pomdpx')!r}])\n"
              f"except SystemExit as e:\n    assert e.code in (0, None), e.code\n")
    assert loaded_after(export, tmp_path) == []
    assert (tmp_path / "x.pomdpx").read_text().startswith("<?xml")
    assert not any(m.startswith(HEAVY) for m in loaded_after("import rapomdp.cli", tmp_path))
