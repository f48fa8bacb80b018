"""rapomdp.planning stands alone: its API from one import, and neither it nor any
`rapomdp pomdp` command loads torch, the robot toolbox or the pipeline's stages."""

from __future__ import annotations

import json
import re
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

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


# --- the rapomdp-planning distribution (packages/rapomdp-planning) ---------------------------

REPO = Path(__file__).resolve().parents[2]
PLANNING_PROJECT = REPO / "packages" / "rapomdp-planning"
#: Import names of the distributions whose name differs from their top-level module.
IMPORT_NAMES = {"pyyaml": "yaml", "pillow": "PIL", "scikit-learn": "sklearn",
                "roboticstoolbox-python": "roboticstoolbox"}
#: What the planning-only environment must never load (the issue's four, named whatever the
#: pyprojects say).
NEVER = {"torch", "roboticstoolbox", "trimesh", "embreex"}

BLOCKED_RUN = """
import importlib.abc, json, sys
BLOCKED = set({blocked!r})

class Blocked(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"{{name}} is blocked", name=name)
        return None

sys.meta_path.insert(0, Blocked())
sys.path[:0] = [{site!r}, {purelib!r}]
import rapomdp.planning
from rapomdp.planning.cli import main
try:
    import rapomdp.config
    pipeline = True
except ModuleNotFoundError:
    pipeline = False
codes = []
for argv in ({solve!r}, {export!r}):
    sys.argv = ["rapomdp-pomdp", *argv]
    try:
        main()
    except SystemExit as exc:
        codes.append(exc.code)
print(json.dumps({{"codes": codes, "pipeline": pipeline, "file": rapomdp.planning.__file__,
                  "modules": sorted(sys.modules)}}))
"""


def _requirement_name(requirement: str) -> str:
    return re.split(r"[\s<>=!~;\[(]", requirement.strip(), maxsplit=1)[0].lower()


def _import_name(distribution: str) -> str:
    return IMPORT_NAMES.get(distribution, distribution.replace("-", "_"))


def _with_requirements(names: set[str]) -> set[str]:
    """``names`` and every distribution they require in this environment, transitively."""
    from importlib import metadata

    seen, todo = set(), list(names)
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        try:
            requires = metadata.requires(name) or []
        except metadata.PackageNotFoundError:
            continue
        todo += [_requirement_name(r) for r in requires if "extra ==" not in r]
    return seen


def test_the_planning_distribution_is_the_solver_alone_and_solves_tiger(tmp_path: Path) -> None:
    """packages/rapomdp-planning builds (offline: no build isolation, no index) from src/ into
    a wheel of exactly rapomdp.planning, rapomdp.geometry, rapomdp.io and rapomdp.belief,
    requiring NumPy, SciPy, typer and rich only; from that wheel alone, with every other
    dependency of rapomdp blocked, `rapomdp-pomdp solve Tiger.pomdp` reaches the reference
    value and `export -w` names the distribution it needs. (benchmarks/planning_only_install.py
    installs it into a fresh venv with pip.)"""
    tomllib = pytest.importorskip("tomllib")  # Python 3.11
    pytest.importorskip("setuptools")
    # the project beside a link to src/, in tmp: its build writes there, not into the checkout
    project = tmp_path / "packages" / "rapomdp-planning"
    project.parent.mkdir()
    for name in ("pyproject.toml", "setup.cfg"):
        project.mkdir(exist_ok=True)
        (project / name).write_text((PLANNING_PROJECT / name).read_text())
    (tmp_path / "src").symlink_to(REPO / "src")
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-build-isolation",
                    "--no-deps", "--no-index", "--disable-pip-version-check", "-w", str(wheels),
                    str(project)], check=True, capture_output=True, cwd=tmp_path)
    (wheel,) = wheels.glob("rapomdp_planning-*.whl")
    src = REPO / "src"
    expected = {"rapomdp/__init__.py", "rapomdp/io.py", "rapomdp/belief.py"} | {
        p.relative_to(src).as_posix() for folder in ("geometry", "planning")
        for p in (src / "rapomdp" / folder).glob("*.py")}
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        info = next(n for n in names if n.endswith(".dist-info/METADATA"))
        metadata_text = archive.read(info).decode()
        scripts = archive.read(info.replace("METADATA", "entry_points.txt")).decode()
        archive.extractall(tmp_path / "site")
    assert {n for n in names if not n.split("/")[0].endswith(".dist-info")} == expected
    assert f"Version: {__import__('rapomdp').__version__}" in metadata_text
    planning_deps = {_requirement_name(line.split(":", 1)[1])
                     for line in metadata_text.splitlines() if line.startswith("Requires-Dist:")}
    assert planning_deps == {"numpy", "scipy", "typer", "rich"}
    assert "rapomdp-pomdp = rapomdp.planning.cli:main" in scripts
    # every dependency of the full rapomdp that the planning one does not bring is blocked
    full = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["dependencies"]
    blocked = {_import_name(_requirement_name(r)) for r in full} - {
        _import_name(d) for d in _with_requirements(planning_deps)}
    assert NEVER <= blocked
    tiger = tmp_path / "Tiger.pomdp"
    tiger.write_text(TIGER)
    probe = BLOCKED_RUN.format(
        blocked=sorted(blocked), site=str(tmp_path / "site"),
        purelib=sysconfig.get_paths()["purelib"],
        solve=["solve", str(tiger), "--timeout", "20"],
        export=["export", "-w", str(tmp_path), "--out", str(tmp_path / "w.pomdpx")])
    # -S: no site-packages processing, so the editable rapomdp of this environment is not seen
    done = subprocess.run([sys.executable, "-S", "-c", probe], capture_output=True, text=True,
                          cwd=tmp_path, check=True)
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["file"].startswith(str(tmp_path / "site"))
    assert result["pipeline"] is False
    assert not {m.split(".")[0] for m in result["modules"]} & blocked
    assert result["codes"] == [0, 2]
    lower, upper = (float(x) for x in re.search(r"lower (\S+), upper (\S+?),",
                                                 done.stdout).groups())
    assert 19.36 <= lower <= upper <= 19.38  # the reference SARSOP: 19.3711
    assert "needs the full rapomdp distribution" in " ".join(done.stderr.split())
    assert not (tmp_path / "w.pomdpx").exists()
