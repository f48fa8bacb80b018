"""Time of one action of a workspace's solved RA-POMDP policy: the solved plans' first move
(``act``) against the one-step lookahead (``lookahead_act``, ``evaluate.lookahead``), on
beliefs after one to four random labels, one core; the ratio is the figure.

    OMP_NUM_THREADS=1 python benchmarks/lookahead_speed.py --workspace W [--repeats 200]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from rapomdp.awareness.artefacts import OBSERVATION_FILE
from rapomdp.experiment.episode import Motion
from rapomdp.io import load_npz
from rapomdp.planning.momdp import update_beliefs
from rapomdp.planning.policy import ActiveRecognitionPolicy
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import Workspace


def recorded_cases(workspace: Path, repeats: int) -> tuple[
        np.ndarray, ActiveRecognitionPolicy, np.ndarray, list[tuple[int, np.ndarray, np.ndarray]]]:
    """A workspace's RA observation model, its solved policy, the reachable viewpoints and
    ``repeats`` cases (viewpoint, belief after one to four random labels, visited)."""
    ws = Workspace(workspace)
    model = load_npz(ws.require("observe") / OBSERVATION_FILE)["ra"]
    policy = ActiveRecognitionPolicy.load(ws.require("solve") / "policy_ra.npz")
    reachable = Motion.from_robot(load_robot(ws.require("robot"))).reachable
    rng = np.random.default_rng(0)
    n_v, n_c = model.shape[:2]
    cases = []
    for _ in range(repeats):
        views = rng.choice(np.flatnonzero(reachable), 4, replace=False)
        b = np.full(n_c, 1.0 / n_c)
        for v in views[: rng.integers(1, 5)]:
            b = update_beliefs(model, b, int(v), int(rng.integers(n_c)))
        visited = np.zeros(n_v, dtype=bool)
        visited[views] = True
        cases.append((int(views[0]), b, visited))
    return model, policy, reachable, cases


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, required=True)
    parser.add_argument("--repeats", type=int, default=200)
    args = parser.parse_args()
    model, policy, reachable, cases = recorded_cases(Path(args.workspace), args.repeats)
    n_c = model.shape[1]
    seconds = {}
    for kind in ("act", "lookahead_act"):
        start = time.perf_counter()
        for v, b, visited in cases:
            if kind == "act":
                policy.act(v, b, visited)
            else:
                policy.lookahead_act(v, b, model, reachable, visited)
        seconds[kind] = (time.perf_counter() - start) / len(cases)
    print(f"{policy.betas.shape[0]} plans, {int(reachable.sum())} reachable viewpoints, "
          f"{n_c} classes: act {1e3 * seconds['act']:.3f} ms, lookahead_act "
          f"{1e3 * seconds['lookahead_act']:.3f} ms per action "
          f"({seconds['lookahead_act'] / seconds['act']:.0f}x)")


if __name__ == "__main__":
    main()
