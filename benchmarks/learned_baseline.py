"""The learned baseline against RA-POMDP and Random on a finished workspace (issue 27).

Reads a workspace whose stages ran with ``learned`` among ``evaluate.methods``
(``configs/learned.yaml``) and writes nothing into it. Prints and writes:

1. the speed of the environment over recorded evidence (steps per second on one core, valid
   random actions, the belief update included) and of the rendering environment;
2. the learn stage's training: timesteps, CPU seconds and the plateau per λ
   (``plateau_timesteps`` of its training curves), wall time;
3. held out: every method of the evaluation (and its sweep settings) on the recorded evidence
   of the volume models, ``--starts`` seeded starts a model, through the closed loop's own
   methods (``ClosedLoop.load``) and ``run_episode`` — in-sample for the learned policy (it
   trained on these models) and for the observation models (fitted on them);
4. the test models: Table 1's rows, the paired difference against RA-POMDP and the
   accuracy-energy points of Learned, RA-POMDP and Random, as ``evaluate`` wrote them.

Usage: python benchmarks/learned_baseline.py --workspace W [--name default] [--starts 4]
Writes benchmarks/results/learned_<name>.txt.
"""

from __future__ import annotations

import argparse
import csv
import os
import platform
import time
from pathlib import Path

import numpy as np

from rapomdp.config import METHOD_NAMES
from rapomdp.experiment.env import ActiveRecognitionEnv
from rapomdp.experiment.evaluation import ClosedLoop, sweep_settings
from rapomdp.experiment.learn_stage import (
    load_learn_summary,
    plateau_timesteps,
    recorded_environment,
    recorded_scores,
    recorded_starts,
)
from rapomdp.experiment.learned import CURVES_CSV, RECORDED_FILE
from rapomdp.experiment.recorded_env import RecordedEvidence
from rapomdp.pipeline import get_stage
from rapomdp.workspace import Workspace

RESULTS = Path(__file__).parent / "results"
SHOWN = ("learned", "ra", "random")


def env_speed(ws: Workspace, evidence: RecordedEvidence, loop: ClosedLoop,
              steps: int) -> tuple[float, float]:
    """Steps per second of the recorded environment (valid random actions, a declaration
    one step in six) and milliseconds a step of the rendering one (moves only)."""
    from rapomdp.experiment.learn_stage import belief_models

    config = loop.config
    belief = belief_models(ws.require("observe"), config.learn.observation_model)
    env = recorded_environment(evidence, belief, loop.motion,
                               config.solve.wrong_declaration_cost_m, config.evaluate, seed=0)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    done = 0
    began = time.perf_counter()
    while done < steps:
        mask = env.action_masks()
        moves = np.flatnonzero(mask[: env.viewpoints])
        action = (env.viewpoints + int(rng.integers(env.classes))
                  if moves.size == 0 or rng.random() < 1 / 6 else int(rng.choice(moves)))
        _, _, end, cut, _ = env.step(action)
        done += 1
        if end or cut:
            env.reset()
    fast = steps / (time.perf_counter() - began)
    rendering = ActiveRecognitionEnv.from_workspace(ws.root, max_moves=10**6, seed=0)
    obs, info = rendering.reset(seed=0)
    began, count = time.perf_counter(), 0
    while count < 200:
        move = np.flatnonzero(info["action_mask"][: rendering.viewpoints])
        obs, _, _, _, info = rendering.step(int(rng.choice(move)))
        count += 1
    return fast, (time.perf_counter() - began) / count * 1e3


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", type=Path, required=True)
    parser.add_argument("--name", default="default", help="results file: learned_<name>.txt")
    parser.add_argument("--starts", type=int, default=4, help="held-out starts per model")
    parser.add_argument("--steps", type=int, default=200_000, help="env steps timed")
    args = parser.parse_args()
    ws = Workspace(args.workspace)
    config = ws.config()
    lines: list[str] = []

    def say(text: str = "") -> None:
        print(text, flush=True)
        lines.append(text)

    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    say(f"# The learned baseline on {ws.root} ({platform.node()}, {os.cpu_count()} cores, "
        f"load average {load} at the start, {time.strftime('%Y-%m-%d %H:%M')})")
    summary = load_learn_summary(ws.require("learn"))
    if not summary.get("trained"):
        raise SystemExit(f"{ws.require('learn')}: the learn stage trained nothing "
                         "(evaluate.methods lacks 'learned'; run with configs/learned.yaml)")
    evidence = RecordedEvidence.load(ws.require("learn") / RECORDED_FILE)
    inputs = ws.inputs(get_stage("evaluate"))
    sweep = ws.require("evaluate") / "sweep"
    swept = sweep_settings(config.evaluate, config.solve.wrong_declaration_cost_m)
    loop = ClosedLoop.load(config, inputs, threads=1, sweep_dir=sweep if swept else None)

    fast, slow_ms = env_speed(ws, evidence, loop, args.steps)
    say("\n## Environment speed (one process, one thread)\n")
    say(f"recorded evidence: {fast:,.0f} steps/s ({args.steps:,} steps, belief update and mask "
        "included)")
    say(f"rendering environment: {slow_ms:.2f} ms a step (render only; the classifier adds "
        "its forward pass)")

    say("\n## Training (learn stage)\n")
    say(f"evidence: {summary['evidence']['models']} held-out volume models; "
        f"belief: {summary['observation_model']}; {summary['timesteps']:,} "
        f"timesteps per λ; {summary['workers']} worker process(es)")
    curves = read_csv(ws.require("learn") / CURVES_CSV)
    say("| λ (m) | CPU s | plateau (timesteps) | final update: return | accuracy | energy (m) |")
    say("|---|---|---|---|---|---|")
    for lam, row in summary["policies"].items():
        final = row["final"] or {}
        mine = [{k: float(v) for k, v in r.items()} for r in curves
                if float(r["lambda"]) == float(lam)]
        plateau = plateau_timesteps(mine) or float("nan")
        say(f"| {lam} | {row['cpu_seconds']:.0f} | {plateau:,.0f} | "
            f"{final.get('mean_return', float('nan')):.3f} | "
            f"{final.get('accuracy', float('nan')):.3f} | "
            f"{final.get('mean_energy', float('nan')):.3f} |")
    for lam in summary["policies"]:
        mine = [r for r in curves if float(r["lambda"]) == float(lam)]
        shown = mine[:: max(1, len(mine) // 10)] + mine[-1:]
        say(f"λ = {lam}: mean return (timesteps) " + ", ".join(
            f"{float(r['mean_return']):.2f} ({float(r['timesteps']):,.0f})" for r in shown))
    seconds = summary["seconds"]
    say(f"wall: record {seconds['record']:.0f} s, train {seconds['train_wall']:.0f} s "
        f"(CPU {seconds['train_cpu']:.0f} s), stage total {seconds['total']:.0f} s")

    say(f"\n## Held out: the volume models' recorded evidence, {args.starts} starts a model "
        "(in-sample for Learned, which trained on them)\n")
    starts = recorded_starts(evidence, loop.motion.reachable, config.seed, args.starts)
    say("| method | setting | accuracy | energy (m) | moves | episodes | seconds |")
    say("|---|---|---|---|---|---|---|")
    held: list[tuple[str, str, float, str]] = []
    for key in loop.methods:
        base, _, setting = key.partition("@")
        if base not in SHOWN:
            continue
        if setting:
            parameter, _, value = setting.partition("=")
            shown = f"{parameter} {value}"
        else:
            shown = (f"threshold {config.evaluate.random.belief_threshold:g} *" if base ==
                     "random" else f"lambda {config.solve.wrong_declaration_cost_m:g} *")
        held.append((base, shown, float(shown.split()[1]), key))
    for base, shown, _, key in sorted(held, key=lambda h: (SHOWN.index(h[0]), h[2])):
        began = time.perf_counter()
        scores = recorded_scores(evidence, loop.methods[key], loop.motion,
                                 config.evaluate.max_moves, config.seed, base, starts)
        say(f"| {METHOD_NAMES[base]} | {shown} | {scores['accuracy']:.3f} | "
            f"{scores['mean_energy']:.3f} | {scores['mean_moves']:.2f} | {scores['episodes']} "
            f"| {time.perf_counter() - began:.0f} |")

    out = ws.require("evaluate")
    say("\n## Test models (evaluate: Table 1, paired, accuracy-energy)\n")
    paired = {r["method"]: r for r in read_csv(out / "paired.csv")}
    say("| method | accuracy [95 % CI] | energy (m) | moves | Δ vs RA-POMDP [95 % CI] |")
    say("|---|---|---|---|---|")
    for row in read_csv(out / "table1.csv"):
        if row["method"] not in SHOWN:
            continue
        p = paired.get(row["method"])
        delta = ("—" if p is None else f"{float(p['accuracy_difference']):+.3f} "
                 f"[{float(p['ci95_low']):+.3f}, {float(p['ci95_high']):+.3f}]")
        say(f"| {METHOD_NAMES[row['method']]} | {float(row['accuracy']):.3f} "
            f"[{float(row['accuracy_low']):.3f}, {float(row['accuracy_high']):.3f}] | "
            f"{float(row['energy']):.3f} | {float(row['moves']):.2f} | {delta} |")
    say("\n| method | setting | accuracy | energy (m) | moves |")
    say("|---|---|---|---|---|")
    for row in read_csv(out / "tradeoff.csv"):
        if row["method"] in SHOWN:
            mark = " *" if row["configured"] == "1" else ""
            say(f"| {METHOD_NAMES[row['method']]} | {row['parameter']} {row['value']}{mark} | "
                f"{float(row['accuracy']):.3f} | {float(row['energy']):.3f} | "
                f"{float(row['moves']):.2f} |")
    say("\n(* Table 1's setting)")
    path = RESULTS / f"learned_{args.name}.txt"
    path.write_text("\n".join(lines) + "\n")
    print(f"\nwritten: {path}")


if __name__ == "__main__":
    main()
