"""benchmarks/ holds what a user reruns: every script answers ``--help`` and is run by
``make bench`` or listed, with its command, in benchmarks/README.md."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCHMARKS = ROOT / "benchmarks"
#: Seconds every script's ``--help`` may take together (most import torch).
HELP_LIMIT_S = 300


def scripts() -> list[Path]:
    return sorted(BENCHMARKS.glob("*.py"))


def bench_target(makefile: str) -> str:
    """The recipe lines of the Makefile's ``bench`` target."""
    match = re.search(r"^bench:.*\n((?:\t.*\n)+)", makefile, flags=re.MULTILINE)
    assert match, "the Makefile has no bench target"
    return match.group(1)


#: Run in one fresh interpreter: each script as ``__main__`` with ``--help``, its exit status and
#: whether it printed a usage line, one JSON line a script. One interpreter, so torch and the
#: package are imported once, not once a script.
DRIVER = """
import contextlib, io, json, os, runpy, sys
base = list(sys.path)
for path in sys.argv[1:]:
    out = io.StringIO()
    sys.argv = [path, "--help"]
    sys.path[:] = [os.path.dirname(os.path.abspath(path)), *base]  # as `python path` has it
    code = 0
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        try:
            runpy.run_path(path, run_name="__main__")
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        except BaseException as exc:
            code, _ = 1, out.write(repr(exc))
    text = out.getvalue()
    print(json.dumps({"script": path, "code": code, "usage": "usage:" in text,
                      "tail": text[-300:]}), flush=True)
"""


def run_help(paths: list[Path]) -> list[dict[str, object]]:
    """Each script's answer to ``--help`` (a subprocess bounded by ``HELP_LIMIT_S``)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "OMP_NUM_THREADS": "1"}
    done = subprocess.run([sys.executable, "-c", DRIVER, *map(str, paths)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=HELP_LIMIT_S)
    assert done.returncode == 0, done.stderr[-2000:]
    return [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]


def test_there_are_few_scripts_and_results() -> None:
    assert 10 <= len(scripts()) <= 41
    results = [p for p in (BENCHMARKS / "results").iterdir() if p.is_file()]
    assert len(results) <= 80


def test_every_script_answers_help_with_its_usage() -> None:
    answers = run_help(scripts())
    assert [Path(str(a["script"])).name for a in answers] == [p.name for p in scripts()]
    failed = {Path(str(a["script"])).name: f"exit {a['code']}: {a['tail']}" for a in answers
              if a["code"] != 0 or not a["usage"]}
    assert failed == {}


def test_a_script_without_help_is_caught(tmp_path: Path) -> None:
    quiet = tmp_path / "quiet.py"
    quiet.write_text("print('ran the whole benchmark')\n")
    failing = tmp_path / "failing.py"
    failing.write_text("import sys\nsys.exit(3)\n")
    answers = {Path(str(a["script"])).name: a for a in run_help([quiet, failing])}
    assert answers["quiet.py"]["code"] == 0 and answers["quiet.py"]["usage"] is False
    assert answers["failing.py"]["code"] == 3


def test_every_script_is_run_by_make_bench_or_listed_in_the_readme() -> None:
    bench = bench_target((ROOT / "Makefile").read_text())
    readme = (BENCHMARKS / "README.md").read_text()
    unlisted = [p.name for p in scripts()
                if f"benchmarks/{p.name}" not in bench and f"`{p.name}" not in readme]
    assert unlisted == []


def test_make_bench_runs_only_scripts_that_exist() -> None:
    named = set(re.findall(r"benchmarks/(\w+\.py)", bench_target((ROOT / "Makefile").read_text())))
    assert named
    assert sorted(n for n in named if not (BENCHMARKS / n).is_file()) == []


def test_the_bench_target_is_found_and_a_missing_one_is_said() -> None:
    assert "render_speed.py" in bench_target("x:\n\ttrue\nbench: a\n\tpython render_speed.py\n\n")
    with pytest.raises(AssertionError, match="no bench target"):
        bench_target("test:\n\tpytest\n")
