"""The solve stage's artefacts: their names, and the reader every later stage goes through.

``W/solve/policy_<model>.npz`` (:func:`policy_file`: one
:class:`~rapomdp.planning.policy.ActiveRecognitionPolicy` per observation model) and
``solve_summary.json`` (:data:`SOLVE_SUMMARY`: per model the bounds reached, CPU seconds,
iterations, ``timed_out``, the policy size and the memory plan's note). The evaluate stage's
accuracy-energy sweep writes the same names under ``W/evaluate/sweep/lambda_<λ>/``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rapomdp.io import read_json

SOLVE_SUMMARY = "solve_summary.json"


def policy_file(model: str) -> str:
    """The file name of one observation model's policy (``policy_ra.npz``)."""
    return f"policy_{model}.npz"


def load_solve_summary(folder: str | Path) -> dict[str, Any]:
    """The summary of a finished solve (``solve_summary.json`` in ``folder``)."""
    return read_json(Path(folder) / SOLVE_SUMMARY)
