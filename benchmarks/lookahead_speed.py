"""Time of one closed-loop step of a workspace's solved RA-POMDP policy, one core: the belief
update (``BayesBelief.update``, Eq. 5) and the one-step lookahead action (``lookahead_act``,
how the POMDP methods act) against the previous lookahead (every move valued exactly; kept here as
the reference) and the solved plans' first move (``act``), on recorded cases: beliefs after one
to four random labels with random visited sets. It counts the cases where the lookahead returns
the reference's action (kind and target); the speed issue asks for all of them.

    OMP_NUM_THREADS=1 python benchmarks/lookahead_speed.py --workspace W [--repeats 400] \
        [--models ra classifier vptree] [--rounds 5]

Times are medians over ``--rounds`` interleaved passes over the cases (the machine may be
shared), wall time with CPU time in brackets, per call.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rapomdp.awareness.artefacts import OBSERVATION_FILE
from rapomdp.belief import BayesBelief, update_beliefs
from rapomdp.experiment.episode import Motion
from rapomdp.io import load_npz
from rapomdp.planning.policy import ActiveRecognitionPolicy
from rapomdp.recognition.artefacts import VPTREE_OBSERVATION_FILE
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import Workspace

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from tests.planning.planning_fixtures import reference_lookahead_act  # noqa: E402


def recorded_cases(workspace: Path, repeats: int, model_name: str = "ra") -> tuple[
        np.ndarray, ActiveRecognitionPolicy, np.ndarray, list[tuple[int, np.ndarray, np.ndarray]]]:
    """A workspace's observation model ``model_name`` (the observe stage's, or the vptree
    stage's for "vptree"), its solved policy, the reachable
    viewpoints and ``repeats`` cases (viewpoint, belief after one to four random labels,
    visited)."""
    ws = Workspace(workspace)
    model = (load_npz(ws.require("vptree") / VPTREE_OBSERVATION_FILE) if model_name == "vptree"
             else load_npz(ws.require("observe") / OBSERVATION_FILE))[model_name]
    policy = ActiveRecognitionPolicy.load(ws.require("solve") / f"policy_{model_name}.npz")
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


def median_times(calls: dict[str, Callable[[], None]], count: int, rounds: int
                 ) -> dict[str, tuple[float, float]]:
    """Median over ``rounds`` interleaved passes of each call's (wall, CPU) seconds per item,
    each pass doing ``count`` items."""
    wall: dict[str, list[float]] = {name: [] for name in calls}
    cpu: dict[str, list[float]] = {name: [] for name in calls}
    for _ in range(rounds):
        for name, call in calls.items():
            w, c = time.perf_counter(), time.process_time()
            call()
            wall[name].append((time.perf_counter() - w) / count)
            cpu[name].append((time.process_time() - c) / count)
    return {name: (float(np.median(wall[name])), float(np.median(cpu[name]))) for name in calls}


def report(workspace: Path, name: str, repeats: int, rounds: int) -> None:
    """Print the identical-action count and the times of one solved model's policy."""
    model, policy, reachable, cases = recorded_cases(workspace, repeats, name)
    n_o = model.shape[2]
    expected = [reference_lookahead_act(policy, v, b, model, reachable, vis)
                for v, b, vis in cases]
    got = [policy.lookahead_act(v, b, model, reachable, vis) for v, b, vis in cases]
    same = sum(a == b for a, b in zip(expected, got, strict=True))
    moves = sum(a.kind == "move" for a in expected)
    # the closed loop's update: a one-hot recogniser output at each case's viewpoint, four
    # views an episode
    rng = np.random.default_rng(1)
    outputs = [(v, np.eye(n_o)[rng.integers(n_o)]) for v, _, _ in cases]
    bayes = BayesBelief(model)

    def updates() -> None:
        for i, (v, out) in enumerate(outputs):
            if i % 4 == 0:
                bayes.reset()
            bayes.update(v, out)

    times = median_times({
        "reference": lambda: [reference_lookahead_act(policy, v, b, model, reachable, vis)
                              for v, b, vis in cases],
        "lookahead_act": lambda: [policy.lookahead_act(v, b, model, reachable, vis)
                                  for v, b, vis in cases],
        "act": lambda: [policy.act(v, b, vis) for v, b, vis in cases],
        "update": updates,
    }, len(cases), rounds)

    def ms(key: str) -> str:
        return f"{1e3 * times[key][0]:.3f} ms ({1e3 * times[key][1]:.3f} CPU)"

    ratio = [times["reference"][i] / times["lookahead_act"][i] for i in (0, 1)]
    step = [times["update"][i] + times["lookahead_act"][i] for i in (0, 1)]
    print(f"{name}: {policy.betas.shape[0]} plans, {int(reachable.sum())} reachable viewpoints, "
          f"{model.shape[1]} states, {len(cases)} recorded cases ({moves} moves): the "
          f"reference's action {same}/{len(cases)}")
    print(f"  per call: reference lookahead {ms('reference')}, lookahead_act "
          f"{ms('lookahead_act')} ({ratio[0]:.2f}x, {ratio[1]:.2f}x CPU), act {ms('act')}, "
          f"belief update {ms('update')}; update + lookahead_act {1e3 * step[0]:.3f} ms "
          f"({1e3 * step[1]:.3f} CPU)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, required=True)
    parser.add_argument("--repeats", type=int, default=400)
    parser.add_argument("--models", nargs="+", default=["ra"])
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    for name in args.models:
        report(Path(args.workspace), name, args.repeats, args.rounds)


if __name__ == "__main__":
    main()
