"""Our exports in the reference SARSOP toolkit (AdaCompNUS/sarsop), and both solvers' bounds.

Builds ``pomdpsol`` from a local git mirror of the toolkit (nothing is downloaded: pass the
mirror's git directory), exports one active-recognition problem as ``.pomdpx`` (viewpoint fully
observed: SARSOP's MOMDP mode) and as flat ``.pomdp``, runs ``pomdpsol`` on both for the same
CPU budget as our structured solver, and prints the bounds [lower, upper] at the start belief.

    OMP_NUM_THREADS=1 PYTHONPATH=src nice -n 5 python benchmarks/sarsop_reference.py \\
        --sarsop-git /work/.mirror/AdaCompNUS+sarsop/repo [--workspace W --model ra | \\
        --benchmark 16x4] [--seconds 30]

The build copies the mirror's ``src/`` out (``git archive HEAD src | tar -x``) and runs, in
``src/``, ``make -j2 CFLAGS='-g -w -O3 $(INCDIR) -msse2 -mfpmath=sse -fcommon'``; ``pomdpsol``
is run without ``--memory`` (its option overflows past 2 GB). Export the binary's path as
``RAPOMDP_POMDPSOL`` for the test that loads our exports in it.
"""

from __future__ import annotations

import argparse
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

MAKE_CFLAGS = "CFLAGS=-g -w -O3 $(INCDIR) -msse2 -mfpmath=sse -fcommon"
ROW = re.compile(r"^\s*([\d.]+)\s+\d+\s+\d+\s+(-?[\d.e+-]+)\s+(-?[\d.e+-]+)\s+", re.M)


def build_pomdpsol(git_dir: Path, build_dir: Path) -> Path:
    """``pomdpsol`` built from the mirror at ``git_dir`` into ``build_dir`` (kept if built)."""
    binary = build_dir / "src" / "pomdpsol"
    if binary.exists():
        return binary
    build_dir.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(["git", "--git-dir", str(git_dir), "archive", "HEAD", "src"],
                             check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(build_dir)], input=archive, check=True)
    subprocess.run(["make", "-j2", MAKE_CFLAGS], cwd=build_dir / "src", check=True,
                   capture_output=True)
    return binary


def run_pomdpsol(binary: Path, problem: Path, seconds: float) -> dict[str, object]:
    """Bounds of ``pomdpsol problem --timeout seconds``: the last row of its table, the time
    it reports, its CPU time, and the max RSS of all children so far (the first run's own)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        out = subprocess.run([str(binary), str(problem), "--timeout", str(seconds),
                              "-o", str(Path(tmp) / "out.policy")],
                             capture_output=True, text=True, cwd=tmp)
        wall = time.perf_counter() - start
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    rows = ROW.findall(out.stdout)
    if out.returncode != 0 or not rows:
        tail = (out.stdout + out.stderr).strip().splitlines()[-4:]
        return {"error": " | ".join(tail)}
    t, lower, upper = rows[-1]
    return {"lower": float(lower), "upper": float(upper), "solver_s": float(t),
            "wall_s": round(wall, 1),
            "cpu_s": round(usage.ru_utime + usage.ru_stime - before.ru_utime - before.ru_stime, 1),
            "max_rss_gb": round(usage.ru_maxrss / 1e6, 2)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sarsop-git", type=Path, default=Path(
        "/work/.mirror/AdaCompNUS+sarsop/repo"), help="git directory of a sarsop mirror")
    ap.add_argument("--build-dir", type=Path, default=Path("/tmp/sarsop-reference"))
    ap.add_argument("--pomdpsol", type=Path, default=None, help="an already built binary")
    ap.add_argument("--workspace", type=Path, default=None)
    ap.add_argument("--model", default="ra")
    ap.add_argument("--benchmark", default="16x4")
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--flat", action="store_true", help="also run pomdpsol on the flat .pomdp")
    ap.add_argument("--ours-only", action="store_true",
                    help="only our solver (run in a fresh process so its peak memory is its own)")
    args = ap.parse_args()

    from rapomdp.planning import (
        benchmark_problem,
        solve_active_recognition,
        to_flat_pomdp,
        write_pomdp,
        write_pomdpx,
    )

    if args.workspace is not None:
        from rapomdp.planning.cli import _workspace_problem

        problem = _workspace_problem(args.workspace, args.model)
        name = f"workspace {args.workspace} model {args.model}"
    else:
        n_v, n_c = (int(x) for x in args.benchmark.split("x"))
        problem = benchmark_problem(n_v, n_c, 0)
        name = f"benchmark {args.benchmark} (seed 0)"
    if args.ours_only:
        result = solve_active_recognition(problem, precision=1e-3, timeout=args.seconds,
                                          report_every=1e9)
        print(f"ours (structured, rapomdp.planning): [{result.lower:.4f}, {result.upper:.4f}] "
              f"at {result.elapsed:.1f} s CPU, max RSS "
              f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6:.2f} GB; {result.note}")
        return
    binary = args.pomdpsol or build_pomdpsol(args.sarsop_git, args.build_dir)
    print(f"{name}: {problem.n_viewpoints} viewpoints x {problem.n_classes} classes, "
          f"{problem.targets.size} move targets, lambda {problem.lambda_:g}; "
          f"{args.seconds:g} s each; pomdpsol {binary}")
    with tempfile.TemporaryDirectory() as tmp:
        files = {"pomdpx": write_pomdpx(problem, Path(tmp) / "problem.pomdpx")}
        if args.flat:
            files["pomdp"] = write_pomdp(to_flat_pomdp(problem), Path(tmp) / "problem.pomdp")
        for kind, path in files.items():
            r = run_pomdpsol(binary, path, args.seconds)
            size = path.stat().st_size / 1e6
            if "error" in r:
                print(f"reference pomdpsol on .{kind} ({size:.1f} MB): refused: {r['error']}")
            else:
                print(f"reference pomdpsol on .{kind} ({size:.1f} MB): [{r['lower']:.4f}, "
                      f"{r['upper']:.4f}] at its {r['solver_s']:.1f} s (CPU {r['cpu_s']} s, "
                      f"wall {r['wall_s']} s incl. loading), max RSS {r['max_rss_gb']} GB",
                      flush=True)
    ours = subprocess.run([sys.executable, __file__, *sys.argv[1:], "--ours-only"],
                          capture_output=True, text=True, check=True)
    print(ours.stdout.strip().splitlines()[-1])


if __name__ == "__main__":
    main()
