"""The solver installs alone: ``packages/rapomdp-planning`` into a fresh venv, then Tiger solved.

Creates a new virtual environment (``python3 -m venv``, no system site-packages), installs the
planning distribution into it with pip as a user would (``pip install
./packages/rapomdp-planning``: pip builds it from this repository's ``src/``, its build
dependency and NumPy, SciPy, typer and rich coming from the configured index or local wheels),
then checks that

- none of torch, roboticstoolbox-python, trimesh and embreex is installed, nor imported by
  ``import rapomdp.planning``, and the pipeline (``rapomdp.config``) is absent;
- ``rapomdp-pomdp solve Tiger.pomdp`` converges to the reference SARSOP's value (19.3711,
  tests/planning/data/README.md) within 0.01;
- ``rapomdp-pomdp export --benchmark`` writes a .pomdpx and ``export --workspace`` says it needs
  the full distribution;

and prints the install's size (MB added to the fresh venv's site-packages) and times (s). Exit
status 1 when a check fails. For CI (the venv is removed afterwards unless ``--keep``):

    python benchmarks/planning_only_install.py [--python python3] [--problem Tiger.pomdp]
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "packages" / "rapomdp-planning"
TIGER = REPO / "tests" / "planning" / "data" / "Tiger.pomdp"
#: The reference SARSOP's lower bound on Tiger (tests/planning/data/README.md).
TIGER_VALUE = 19.3711
#: Distributions (pip names) and modules the planning-only environment must not hold.
FORBIDDEN_DISTRIBUTIONS = ("torch", "roboticstoolbox-python", "trimesh", "embreex")
FORBIDDEN_MODULES = ("torch", "roboticstoolbox", "trimesh", "embreex")


def run(command: list[str], cwd: Path | None = None) -> tuple[subprocess.CompletedProcess[str],
                                                             float]:
    """``command``'s completed process (output captured) and its wall time in seconds."""
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, cwd=cwd, check=False)
    return done, time.perf_counter() - start


def folder_mb(folder: Path) -> float:
    """The summed size of the files under ``folder`` in MB (10^6 bytes)."""
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file()
               and not p.is_symlink()) / 1e6


def staged_project(work: Path) -> Path:
    """The distribution's project files beside a link to this checkout's ``src/``, in
    ``work``: pip builds there (its ``build/`` folder too), not in the checkout."""
    project = work / "packages" / PACKAGE.name
    project.mkdir(parents=True)
    for name in ("pyproject.toml", "setup.cfg"):
        shutil.copyfile(PACKAGE / name, project / name)
    (work / "src").symlink_to(REPO / "src")
    return project


def distribution_mb(names: tuple[str, ...]) -> dict[str, float]:
    """The installed size in MB of each of ``names`` in *this* interpreter's environment (the
    full rapomdp's), from its RECORD; absent ones are left out."""
    from importlib import metadata

    sizes = {}
    for name in names:
        try:
            files = metadata.distribution(name).files or []
        except metadata.PackageNotFoundError:
            continue
        sizes[name] = sum(f.size or 0 for f in files) / 1e6
    return sizes


def site_packages(venv: Path) -> Path:
    found = sorted(venv.glob("lib/python*/site-packages")) + sorted(
        venv.glob("Lib/site-packages"))
    if not found:
        raise SystemExit(f"{venv}: no site-packages folder")
    return found[0]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--python", default="python3", help="the interpreter of the new venv")
    ap.add_argument("--problem", type=Path, default=TIGER, help="Tiger.pomdp")
    ap.add_argument("--keep", type=Path, default=None,
                    help="create the venv here and keep it (default: a temporary folder)")
    args = ap.parse_args()
    if not args.problem.is_file():
        raise SystemExit(f"{args.problem}: not found (--problem Tiger.pomdp)")
    work = Path(tempfile.mkdtemp(prefix="rapomdp-planning-"))
    venv = args.keep if args.keep is not None else work / "venv"
    failures: list[str] = []

    def check(ok: bool, what: str) -> None:
        print(f"  [{'ok' if ok else 'FAILED'}] {what}")
        if not ok:
            failures.append(what)

    try:
        done, venv_s = run([args.python, "-m", "venv", str(venv)])
        if done.returncode:
            raise SystemExit(f"python -m venv failed:\n{done.stderr}")
        python, bin_dir = venv / "bin" / "python", venv / "bin"
        site = site_packages(venv)
        bare_mb = folder_mb(site)
        done, install_s = run([str(python), "-m", "pip", "install", "--quiet",
                               "--disable-pip-version-check", str(staged_project(work))])
        if done.returncode:
            raise SystemExit(f"pip install {PACKAGE} failed:\n{done.stdout}\n{done.stderr}")
        installed_mb = folder_mb(site)
        done, _ = run([str(python), "-m", "pip", "list", "--format=json",
                       "--disable-pip-version-check"])
        names = sorted(d["name"].lower() for d in json.loads(done.stdout))
        probe = ("import json, sys, rapomdp.planning, importlib.util as u; "
                 "print(json.dumps([sorted(sys.modules), u.find_spec('rapomdp.config') is None]))")
        done, import_s = run([str(python), "-c", probe], cwd=work)
        modules, no_pipeline = json.loads(done.stdout) if done.returncode == 0 else ([], False)
        done, solve_s = run([str(bin_dir / "rapomdp-pomdp"), "solve", str(args.problem),
                             "--timeout", "30"], cwd=work)
        bounds = re.search(r"lower (-?[0-9.e+-]+), upper (-?[0-9.e+-]+)", done.stdout)
        solve_out = done
        done, export_s = run([str(bin_dir / "rapomdp-pomdp"), "export", "--benchmark", "16x4",
                              "--out", str(work / "problem.pomdpx")], cwd=work)
        exported = done.returncode == 0 and (work / "problem.pomdpx").read_text(
            encoding="utf-8").startswith("<?xml")
        refused, _ = run([str(bin_dir / "rapomdp-pomdp"), "export", "-w", str(work),
                          "--out", str(work / "w.pomdpx")], cwd=work)

        print(f"fresh venv ({args.python}, {sys.platform}): {venv_s:.1f} s to create, "
              f"site-packages {bare_mb:.1f} MB")
        print(f"pip install ./packages/rapomdp-planning: {install_s:.1f} s wall, "
              f"{installed_mb - bare_mb:.1f} MB added to site-packages "
              f"({installed_mb:.1f} MB in all)")
        print(f"distributions installed: {', '.join(names)}")
        avoided = distribution_mb(FORBIDDEN_DISTRIBUTIONS)
        if avoided:
            print(f"not installed, as the full rapomdp's environment ({sys.executable}) holds "
                  f"them: " + ", ".join(f"{n} {mb:.0f} MB" for n, mb in avoided.items())
                  + f" ({sum(avoided.values()):.0f} MB)")
        print(f"import rapomdp.planning: {import_s:.2f} s wall (a new interpreter)")
        print(f"rapomdp-pomdp solve {args.problem.name}: {solve_s:.2f} s wall")
        for line in solve_out.stdout.splitlines()[-3:]:
            print(f"    {line}")
        print(f"rapomdp-pomdp export --benchmark 16x4: {export_s:.2f} s wall")
        print("checks:")
        check(not set(FORBIDDEN_DISTRIBUTIONS) & set(names),
              f"none of {', '.join(FORBIDDEN_DISTRIBUTIONS)} installed")
        loaded = [m for m in modules if m.split(".")[0] in FORBIDDEN_MODULES]
        check(bool(modules) and not loaded,
              f"import rapomdp.planning loads none of {', '.join(FORBIDDEN_MODULES)}"
              + (f" (loaded: {', '.join(loaded)})" if loaded else ""))
        check(no_pipeline, "the pipeline (rapomdp.config) is not installed")
        check(solve_out.returncode == 0 and bounds is not None
              and abs(float(bounds.group(1)) - TIGER_VALUE) <= 0.01,
              f"Tiger solved to the reference value {TIGER_VALUE} within 0.01"
              + (f" (lower {bounds.group(1)}, upper {bounds.group(2)})" if bounds else
                 f" (exit {solve_out.returncode}: {solve_out.stderr.strip()[-300:]})"))
        check(exported, "export --benchmark wrote a .pomdpx")
        check(refused.returncode == 2 and "needs the full rapomdp distribution"
              in " ".join(refused.stderr.split()),
              "export --workspace names the full distribution it needs")
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)
    print("all checks passed" if not failures else f"{len(failures)} check(s) FAILED")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
