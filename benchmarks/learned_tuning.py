"""PPO settings of the learned baseline compared on held-out return (how the defaults were chosen).

Trains one policy at one λ with ``learn`` settings overridden (JSON), on the recorded evidence of
a workspace whose learn stage ran (``configs/learned.yaml``), and scores it on every (volume
model, reachable start) pair of that evidence: accuracy, energy and the return
−(energy + λ·(1 − accuracy)), which the choice maximises. No test model is read. Prints one JSON
line; run it once per setting (each takes about 90 s of CPU at 300 000 steps on the default).

Usage: python benchmarks/learned_tuning.py --workspace W --lambda 8 --set '{"learning_rate": 1e-3}'
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from rapomdp.experiment.episode import Motion
from rapomdp.experiment.learn_stage import belief_models, recorded_scores, train_policy
from rapomdp.experiment.learned import RECORDED_FILE, LearnedPolicy
from rapomdp.experiment.recorded_env import RecordedEvidence
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import Workspace


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", type=Path, required=True)
    parser.add_argument("--lambda", dest="lambda_", type=float, default=8.0)
    parser.add_argument("--set", default="{}", help="learn settings as JSON")
    parser.add_argument("--seed", type=int, default=123, help="the training's seed")
    args = parser.parse_args()
    ws = Workspace(args.workspace)
    config = ws.config()
    overrides = json.loads(args.set)
    config.learn = config.learn.model_copy(update=overrides)
    evidence = RecordedEvidence.load(ws.require("learn") / RECORDED_FILE)
    motion = Motion.from_robot(load_robot(ws.require("robot")))
    began = time.process_time()
    network, spec, rows = train_policy(config, evidence, ws.require("observe"), motion,
                                       args.lambda_, args.seed)
    cpu = time.process_time() - began
    belief = belief_models(config, ws.require("observe"))
    scores = recorded_scores(evidence, LearnedPolicy(network, spec, reachable=motion.reachable,
                                                     **belief),
                             motion, config.evaluate.max_moves, config.seed, "learned")
    held_out_return = -(scores["mean_energy"] + args.lambda_ * (1 - scores["accuracy"]))
    curve = [round(r["mean_return"], 2) for r in rows[:: max(1, len(rows) // 10)]]
    print(json.dumps({"lambda": args.lambda_, **overrides, "timesteps": config.learn.timesteps,
                      "cpu_s": round(cpu), "held_out_return": round(held_out_return, 3),
                      **{k: round(v, 3) for k, v in scores.items()},
                      "training_return_curve": curve}))


if __name__ == "__main__":
    main()
