"""Accuracy against energy in the closed loop as the wrong-declaration cost λ varies.

Needs a workspace where ``rapomdp run`` has reached the ``solve`` stage. For every λ
(``solve.wrong_declaration_cost_m``, metres of movement energy) and observation model, solves
the active-recognition MOMDP as the solve stage does (same discount, precision, start
viewpoint, energy with +inf replaced by the geodesic distance), but with ``--timeout`` CPU
seconds, then runs every test model x start episode of that policy in the closed loop and
prints Table 1 per λ plus one summary line per (λ, model). The Static method does not depend
on λ: it runs once and its rows are repeated in every table. Nothing is written into the
workspace.

Usage: OMP_NUM_THREADS=1 python benchmarks/lambda_sweep.py --workspace runs/demo
Writes benchmarks/results/lambda_sweep.txt.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path

import torch

from rapomdp.config import load_config
from rapomdp.experiment.config import METHOD_NAMES
from rapomdp.experiment.evaluation import ClosedLoop, EpisodeRecord, EpisodeTable
from rapomdp.experiment.methods import POMDPPolicy, StaticPolicy
from rapomdp.experiment.metrics import table1, table1_markdown
from rapomdp.planning.ar_solver import solve_active_recognition
from rapomdp.planning.momdp import build_active_recognition_problem
from rapomdp.planning.stage import start_viewpoint, workspace_arrays
from rapomdp.recognition import stage

RESULTS = Path(__file__).parent / "results" / "lambda_sweep.txt"
STAGES = ("dataset", "train", "observe", "vptree", "robot", "solve")


class Report:
    """Prints lines and keeps them for the results file."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def __call__(self, text: str = "") -> None:
        print(text, flush=True)
        self.lines.append(text)

    def write(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("\n".join(self.lines) + "\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", type=Path, default=Path("runs/demo"))
    parser.add_argument("--lambdas", type=float, nargs="+", default=[1.0, 2.0, 5.0, 10.0],
                        help="wrong-declaration costs λ (m of movement energy)")
    parser.add_argument("--models", nargs="+", default=["ra", "classifier"],
                        help="observation models of the workspace to solve")
    parser.add_argument("--iterations", type=int, default=None,
                        help="solver iterations per model (default: solve.iterations of the "
                        "workspace's config)")
    parser.add_argument("--starts", type=int, default=None,
                        help="start viewpoints per test model (default: evaluate.starts_per_"
                        "model of the workspace's config)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    stage.threads = 1
    out = Report()
    out("command: " + shlex.join([Path(sys.executable).name, *sys.argv]))
    out(f"workspace: {args.workspace.resolve()}")

    root = args.workspace
    config = load_config(root / "config.yaml")
    if args.starts is not None:
        config.evaluate.starts_per_model = args.starts
    # only Static is loaded from the workspace; the POMDP methods are solved here per λ
    config.evaluate.methods = ["static"]
    inputs = {name: root / name for name in STAGES}
    missing = [name for name, path in inputs.items() if not path.is_dir()]
    if missing:
        parser.error(f"{root} lacks the stage folder(s) {', '.join(missing)}")

    config.solve.models = list(args.models)
    # the solve stage's arrays: the named models, E_M made finite, reachability
    observe, energy, reachable, classes = workspace_arrays(config, root / "observe",
                                                           root / "robot", root / "vptree")
    v0 = start_viewpoint(reachable)

    began = time.perf_counter()
    loop = ClosedLoop.load(config, inputs)
    tests = loop.dataset.with_role("test")
    discount, precision = config.solve.discount, config.solve.precision
    iterations = args.iterations or config.solve.iterations
    out(f"test models: {len(tests)}, starts per model: {config.evaluate.starts_per_model}, "
        f"step budget: {config.evaluate.max_moves}, discount: {discount}, precision: "
        f"{precision}, solver iterations: {iterations}, revisits: {config.evaluate.revisit}, "
        f"start viewpoint: {v0}, "
        f"config λ: {config.solve.wrong_declaration_cost_m:g} m")
    out()

    static: list[EpisodeRecord] = []
    summaries: list[str] = []
    for lam in args.lambdas:
        methods: dict[str, POMDPPolicy | StaticPolicy] = {}
        bounds: dict[str, str] = {}
        for key in args.models:
            problem = build_active_recognition_problem(
                observe[key], energy, reachable, lam, discount, v0, allow_stay=False,
                class_names=classes)
            result = solve_active_recognition(problem, precision, config.solve.timeout_s,
                                              max_iterations=iterations)
            methods[key] = POMDPPolicy(result.policy, observe[key],
                                       METHOD_NAMES.get(key, key),
                                       revisit=config.evaluate.revisit)
            bounds[key] = (f"bounds [{result.lower:.4f}, {result.upper:.4f}] "
                           f"({result.elapsed:.1f} s, {result.iterations} it, "
                           f"{'converged' if result.converged else 'not converged'})")
        if not static:
            methods["static"] = StaticPolicy(METHOD_NAMES["static"])
        loop.methods = methods
        t0 = time.process_time()
        records = [r for model in tests for r in loop.run_model(model)]
        episodes_cpu = time.process_time() - t0
        if not static:
            static = [r for r in records if r.method == "static"]
            records = [r for r in records if r.method != "static"]
        keys = ["static", *args.models]
        table = EpisodeTable.from_records(static + records, loop.dataset, keys)
        rows = table1(table, keys)
        out(f"## λ = {lam:g} m ({len(records)} POMDP episodes, {episodes_cpu:.1f} CPU s)")
        out()
        out(table1_markdown(rows).rstrip("\n"))
        out()
        for row in rows[1:]:
            summaries.append(
                f"λ={lam:<5g} {row.method:<11} accuracy {row.accuracy:.3f} "
                f"[{row.accuracy_low:.3f}, {row.accuracy_high:.3f}]  moves "
                f"{row.means['moves']:.2f}  energy {row.means['energy']:.3f} m  "
                f"belief {row.means['belief']:.3f}  exhausted {row.exhausted}  "
                f"{bounds[row.method]}")
    out("## Summary (one line per λ and model)")
    out()
    static_row = table1(EpisodeTable.from_records(static, loop.dataset, ["static"]),
                        ["static"])[0]
    out(f"static (any λ) accuracy {static_row.accuracy:.3f} "
        f"[{static_row.accuracy_low:.3f}, {static_row.accuracy_high:.3f}]")
    for line in summaries:
        out(line)
    out()
    out(f"total wall time: {time.perf_counter() - began:.1f} s")
    out.write(RESULTS)


if __name__ == "__main__":
    main()
