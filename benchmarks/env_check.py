"""gymnasium's ``check_env`` and a random agent on a workspace's environment, over many seeds.

For each seed: ``gymnasium.make("rapomdp/ActiveRecognition-v0", workspace=W, seed=s,
render_mode="rgb_array")``, ``check_env`` on it (its only expected warning, the unbounded depth
Box, is counted apart), then one episode of ``env.action_space.sample()``. Prints how many seeds
passed, the arm's reachability, the random agent's steps, invalid actions and endings, and the
time per seed. Needs the workspace's ``dataset`` and ``robot`` stages (``rapomdp robot -w W``).

    OMP_NUM_THREADS=1 python benchmarks/env_check.py W [--seeds 20] [--max-moves 30]
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import gymnasium
import numpy as np
from gymnasium.utils.env_checker import check_env

from rapomdp.experiment.env import ENV_ID

EXPECTED = "Box observation space maximum value is infinity"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("workspace", type=Path)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--max-moves", type=int, default=30)
    args = ap.parse_args()
    passed, other_warnings, steps, invalid, declared, truncated = 0, [], [], 0, 0, 0
    start = time.perf_counter()
    for seed in range(args.seeds):
        env = gymnasium.make(ENV_ID, workspace=args.workspace, seed=seed,
                             max_moves=args.max_moves, render_mode="rgb_array").unwrapped
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(env)
        env.action_space.seed(seed)  # after check_env, which seeds it with its own seed
        passed += 1
        other_warnings += [str(w.message) for w in caught if EXPECTED not in str(w.message)]
        obs, info = env.reset(seed=seed)
        while True:
            obs, reward, term, trunc, info = env.step(env.action_space.sample())
            invalid += bool(info["invalid"])
            if term or trunc:
                break
        steps.append(info["steps"])
        declared += bool(term)
        truncated += bool(trunc)
        assert "true_class" in info
    seconds = time.perf_counter() - start
    print(f"workspace {args.workspace}: {env.viewpoints} viewpoints "
          f"({int(env.motion.reachable.sum())} reachable), {env.classes} classes, "
          f"{len(env.scenes)} test models, depth {env.observation_space['depth'].shape}")
    print(f"check_env passed for {passed}/{args.seeds} seeds; other warnings: "
          f"{sorted(set(other_warnings)) or 'none'}")
    print(f"random agent (action_space.sample()): {args.seeds} episodes, {np.mean(steps):.1f} "
          f"steps on average, {invalid} invalid actions (no-ops), {declared} declared, "
          f"{truncated} truncated; frame {env.render().shape}")
    print(f"{seconds / args.seeds:.2f} s per seed (make + check_env + one episode)")


if __name__ == "__main__":
    main()
