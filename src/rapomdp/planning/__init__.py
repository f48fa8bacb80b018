"""POMDP planning: flat and active-recognition (MOMDP) models, the SARSOP-style solvers,
policies as ``.npz`` artefacts, and ``.pomdp`` / ``.pomdpx`` I/O. See docs/planning.md.

Standalone: importing it loads NumPy (and SciPy for the grid bound), never torch, the robot or
the pipeline's stages. Both solvers budget process CPU time and size their arrays against a
memory cap (``memory_gb``, default 4) before allocating them.
"""

from rapomdp.belief import update_beliefs
from rapomdp.planning.ar_solver import ActiveRecognitionSolver, solve_active_recognition
from rapomdp.planning.io_pomdp import (
    PomdpParseError,
    format_pomdp,
    parse_pomdp,
    read_pomdp,
    write_pomdp,
)
from rapomdp.planning.io_pomdpx import format_pomdpx, write_pomdpx
from rapomdp.planning.memory import DEFAULT_MEMORY_GB, MemoryCapError
from rapomdp.planning.momdp import (
    DEFAULT_LAMBDA,
    ActiveRecognitionProblem,
    SimulationResult,
    benchmark_problem,
    build_active_recognition_problem,
    finite_move_energy,
    simulate_policy,
    to_flat_pomdp,
)
from rapomdp.planning.policy import ActiveRecognitionPolicy, AlphaVectorPolicy, ARAction
from rapomdp.planning.pomdp import POMDP, belief_update
from rapomdp.planning.sarsop import FlatSarsop, Progress, SolveResult, solve_pomdp

__all__ = [
    "DEFAULT_MEMORY_GB",
    "POMDP",
    "ARAction",
    "ActiveRecognitionPolicy",
    "ActiveRecognitionProblem",
    "ActiveRecognitionSolver",
    "AlphaVectorPolicy",
    "FlatSarsop",
    "MemoryCapError",
    "PomdpParseError",
    "Progress",
    "SimulationResult",
    "SolveResult",
    "belief_update",
    "benchmark_problem",
    "DEFAULT_LAMBDA",
    "build_active_recognition_problem",
    "finite_move_energy",
    "format_pomdp",
    "format_pomdpx",
    "parse_pomdp",
    "read_pomdp",
    "simulate_policy",
    "solve_active_recognition",
    "solve_pomdp",
    "to_flat_pomdp",
    "update_beliefs",
    "write_pomdp",
    "write_pomdpx",
]
