"""``rapomdp pomdp ...``: solve ``.pomdp`` files and export active-recognition problems.

Registered by the top-level CLI as ``app.add_typer(pomdp_app, name="pomdp")``. Planning
stands alone: these commands import no torch, robot or pipeline code (the workspace's
configuration is read only by ``export --workspace``), so they start in a fraction of a second.
"""

from __future__ import annotations

import dataclasses
import math
import re
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import typer
from rich.console import Console
from rich.live import Live
from rich.markup import escape
from rich.table import Table

from rapomdp.io import ArtefactError, check_output_path, describe_os_error
from rapomdp.planning.bounds import flat_solver_bytes
from rapomdp.planning.io_pomdp import PomdpParseError, read_pomdp, write_pomdp
from rapomdp.planning.io_pomdpx import write_pomdpx
from rapomdp.planning.memory import DEFAULT_MEMORY_GB, MemoryCapError
from rapomdp.planning.momdp import (
    BENCHMARK_LAMBDA,
    DEFAULT_LAMBDA,
    ActiveRecognitionProblem,
    benchmark_problem,
    build_active_recognition_problem,
    load_problem_arrays,
    to_flat_pomdp,
)
from rapomdp.planning.sarsop import Progress, SolveResult, solve_pomdp

pomdp_app = typer.Typer(
    help="Solve POMDPs (Cassandra .pomdp) with the SARSOP-style solver; export problems.",
    no_args_is_help=True,
    rich_markup_mode="markdown",  # docstrings are markdown: wrapped lines join
)


class BoundsDisplay:
    """Live table of the bounds on a terminal; one plain line per update otherwise."""

    def __init__(self, console: Console, title: str) -> None:
        self.console = console
        self.title = title
        self.live: Live | None = None
        self.last: Progress | None = None

    def _table(self, p: Progress) -> Table:
        t = Table(title=self.title)
        for col in ("time s", "lower", "upper", "gap", "vectors", "points", "iterations"):
            t.add_column(col, justify="right")
        t.add_row(
            f"{p.elapsed:.1f}", f"{p.lower:.6g}", f"{p.upper:.6g}", f"{p.gap:.4g}",
            str(p.n_alpha), str(p.n_points), str(p.iterations),
        )
        return t

    def __enter__(self) -> BoundsDisplay:
        if self.console.is_terminal:
            self.live = Live(console=self.console, refresh_per_second=4, transient=False)
            self.live.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        if self.live is not None:
            self.live.__exit__(None, None, None)

    def __call__(self, p: Progress) -> None:
        self.last = p
        if self.live is not None:
            self.live.update(self._table(p))
        else:
            self.console.print(
                f"t={p.elapsed:7.2f}s  lower={p.lower:.6g}  upper={p.upper:.6g}  "
                f"gap={p.gap:.4g}  vectors={p.n_alpha}  points={p.n_points}",
                soft_wrap=True,
            )


def _report(console: Console, result: SolveResult[Any], size: int) -> None:
    state = "converged" if result.converged else "stopped at the time limit"
    if result.note.startswith("stopped"):
        state = "stopped at the memory cap"
    console.print(
        f"{state} after {result.elapsed:.2f} s of CPU time, {result.iterations} iterations: "
        f"lower {result.lower:.6g}, upper {result.upper:.6g}, gap {result.upper - result.lower:.4g}"
    )
    if result.note:
        console.print(f"note: {result.note}")
    console.print(f"policy: {size} alpha vectors")


#: Where the errors go (the bounds and the summary go to the command's console, stdout).
_ERRORS = Console(stderr=True, soft_wrap=True, highlight=False)


def _error(console: Console, message: object) -> typer.Exit:
    """Print one ``error:`` line on stderr (the message shown as is); the exit to raise."""
    text = " ".join(str(message).split())
    _ERRORS.print(f"[red]error:[/red] {escape(text)}", soft_wrap=True, highlight=False)
    return typer.Exit(2)


def _check_out(console: Console, out: Path) -> None:
    """Refuse an ``--out`` that is not a regular file or a new path (a folder, a device)."""
    try:
        check_output_path(out)
    except ArtefactError as exc:
        raise _error(console, exc) from None


def _write(console: Console, what: str, write: Callable[[], Path]) -> Path:
    """``write()``; a file that cannot be written (a folder, a full disk) is one error line."""
    try:
        return write()
    except OSError as exc:
        raise _error(console, f"writing {what}: {describe_os_error(exc)}") from None
    except (ArtefactError, ValueError) as exc:
        raise _error(console, f"writing {what}: {exc}") from None


def _check_positive(console: Console, **options: float) -> None:
    """Refuse NaN, infinite, zero or negative values of the named options."""
    for name, value in options.items():
        if not (math.isfinite(value) and value > 0):
            raise _error(console, f"--{name.replace('_', '-')} must be a positive finite "
                                  f"number, got {value}")


TIMEOUT_HELP = ("Stop after S seconds of process CPU time (reading the file included; time "
                "asleep or waiting for the machine does not count).")
MEMORY_HELP = ("Memory cap in GB: the solver's arrays are estimated before they are "
               "allocated and a problem that cannot fit is refused.")


@pomdp_app.command("solve")
def solve_cmd(
    file: Path = typer.Argument(..., help="A .pomdp file (Cassandra's format)."),
    precision: float = typer.Option(1e-3, "--precision", help="Stop when upper - lower <= P."),
    timeout: float = typer.Option(60.0, "--timeout", help=TIMEOUT_HELP),
    memory_gb: float = typer.Option(DEFAULT_MEMORY_GB, "--memory-gb", help=MEMORY_HELP),
    out: Path | None = typer.Option(None, "--out", help="Write the policy (.npz)."),
) -> None:
    """Solve a .pomdp file, printing the bounds as they improve and the final policy size."""
    start = time.process_time()
    console = Console(soft_wrap=True)
    _check_positive(console, precision=precision, timeout=timeout, memory_gb=memory_gb)
    if out is not None:
        _check_out(console, out)  # before the solve, not after it
    try:
        pomdp = read_pomdp(file, memory_gb, solver_bytes=flat_solver_bytes)
        console.print(
            f"{file}: {pomdp.n_states} states, {pomdp.n_actions} actions, "
            f"{pomdp.n_observations} observations, discount {pomdp.discount}"
        )
        left = timeout - (time.process_time() - start)
        if left <= 0:
            raise _error(console, f"reading {file} took the whole --timeout of {timeout:g} s")
        with BoundsDisplay(console, str(file.name)) as display:
            result = solve_pomdp(pomdp, precision, left, display, memory_gb)
    except (PomdpParseError, MemoryCapError) as exc:
        raise _error(console, exc) from None
    _report(console, result, len(result.policy))
    if out is not None:
        path = _write(console, f"the policy {out}", lambda: result.policy.save(out))
        console.print(f"wrote {path}")


def _parse_size(text: str) -> tuple[int, int]:
    m = re.fullmatch(r"\s*([0-9]+)\s*[xX×]\s*([0-9]+)\s*", text)
    if not m:
        raise ValueError(f"--benchmark: expected VIEWPOINTSxCLASSES such as 128x35, got "
                         f"{text[:40]!r}")
    n_v, n_c = int(m.group(1)), int(m.group(2))
    if n_v < 1 or n_c < 2:
        raise ValueError(f"--benchmark {text.strip()}: at least 1 viewpoint and 2 classes")
    return n_v, n_c


def _workspace_problem(root: Path, model: str) -> ActiveRecognitionProblem:
    """The problem the solve stage builds from a workspace, with the workspace's configuration
    (the only command that reads the pipeline's configuration: imported here). Its errors come
    back as ValueError, the pipeline's absence (the ``rapomdp-planning`` distribution) too."""
    try:
        from rapomdp.config import Config, ConfigError
        from rapomdp.planning.stage import workspace_problem
        from rapomdp.workspace import StageError, Workspace
    except ModuleNotFoundError as exc:
        raise ValueError(f"--workspace reads a pipeline workspace, which needs the full rapomdp "
                         f"distribution (module {exc.name!r} is not installed; "
                         f"rapomdp-planning holds the solver only): use --problem or "
                         f"--benchmark") from None

    try:
        ws = Workspace(root)
        config = ws.config(default=Config())
        vptree = ws.require("vptree") if "vptree" in ws.manifest()["stages"] else None
        return workspace_problem(ws.require("observe"), ws.require("robot"), model, vptree,
                                 config.solve)
    except (StageError, ConfigError) as exc:
        raise ValueError(str(exc)) from None


@pomdp_app.command("export")
def export_cmd(
    out: Path = typer.Option(..., "--out", help="Output file: .pomdpx (MOMDP) or .pomdp (flat)."),
    problem: Path | None = typer.Option(
        None, "--problem", help="An .npz with observation_model (V,C,C), move_energy (V,V), "
        "reachable (V,) [optional].",
    ),
    benchmark: str | None = typer.Option(
        None, "--benchmark", help="Instead of --problem: a synthetic problem VxC of the "
        "pomdp-benchmarks family, e.g. 64x10.",
    ),
    workspace: Path | None = typer.Option(
        None, "--workspace", "-w", help="Instead of --problem: the workspace's problem, from its "
        "observe and robot stages and its configuration's solve section.",
    ),
    model: str = typer.Option("ra", "--model", help="With --workspace: the observation model."),
    seed: int = typer.Option(0, "--seed", help="Seed of the synthetic problem."),
    lambda_: float | None = typer.Option(
        None, "--lambda", help="Cost of a wrong declaration (λ); default: the workspace's "
        "solve.wrong_declaration_cost_m with --workspace, the benchmark family's 10 with "
        "--benchmark, else 2 (the configuration's default)."),
    discount: float = typer.Option(0.95, "--discount"),
    start: int = typer.Option(0, "--start", help="Index of the start viewpoint."),
    solve_seconds: float = typer.Option(
        0.0, "--solve", help="Also solve for this many seconds of process CPU time and print "
        "the bounds."
    ),
    memory_gb: float = typer.Option(DEFAULT_MEMORY_GB, "--memory-gb", help=MEMORY_HELP),
) -> None:
    """Write an active-recognition problem as .pomdpx (viewpoint fully observed) or .pomdp."""
    console = Console(soft_wrap=True)
    _check_positive(console, memory_gb=memory_gb)
    _check_out(console, out)
    if not (math.isfinite(solve_seconds) and solve_seconds >= 0):
        raise _error(console, f"--solve must be a finite number of seconds, got {solve_seconds}")
    ar: ActiveRecognitionProblem
    try:
        if sum(x is not None for x in (problem, benchmark, workspace)) != 1:
            raise ValueError("give exactly one of --problem, --benchmark and --workspace")
        if lambda_ is not None and not (math.isfinite(lambda_) and lambda_ >= 0):
            raise ValueError(f"--lambda must be a finite non-negative cost, got {lambda_}")
        if workspace is not None:
            ar = _workspace_problem(workspace, model)
            if lambda_ is not None:
                ar = dataclasses.replace(ar, lambda_=lambda_)
        elif benchmark is not None:
            n_v, n_c = _parse_size(benchmark)
            ar = benchmark_problem(n_v, n_c, seed,
                                   BENCHMARK_LAMBDA if lambda_ is None else lambda_, discount,
                                   memory_gb=memory_gb)
        else:
            assert problem is not None  # one of the three was given
            arrays = load_problem_arrays(problem)
            ar = build_active_recognition_problem(
                arrays["observation_model"], arrays["move_energy"], arrays.get("reachable"),
                DEFAULT_LAMBDA if lambda_ is None else lambda_, discount, start,
            )
        if out.suffix not in (".pomdp", ".pomdpx"):
            raise ValueError("--out must end in .pomdpx or .pomdp")
        flat = to_flat_pomdp(ar, memory_gb) if out.suffix == ".pomdp" else None
    except (ValueError, ArtefactError, MemoryCapError) as exc:
        raise _error(console, exc) from None
    if flat is not None:
        path = _write(console, str(out), lambda: write_pomdp(flat, out))
    else:
        path = _write(console, str(out), lambda: write_pomdpx(ar, out))
    console.print(
        f"wrote {path}: {ar.n_viewpoints} viewpoints x {ar.n_classes} classes, "
        f"{ar.targets.size} move targets"
    )
    if solve_seconds > 0:
        from rapomdp.planning.ar_solver import solve_active_recognition

        with BoundsDisplay(console, "active recognition") as display:
            try:
                result = solve_active_recognition(ar, 1e-3, solve_seconds, display,
                                                  memory_gb=memory_gb)
            except MemoryCapError as exc:
                raise _error(console, exc) from None
        _report(console, result, int(np.size(result.policy.targets)))


def main() -> None:
    """The ``rapomdp-pomdp`` console script: these commands without the pipeline's CLI (the
    ``rapomdp-planning`` distribution's command; ``rapomdp pomdp`` is the same app)."""
    pomdp_app(prog_name="rapomdp-pomdp")
