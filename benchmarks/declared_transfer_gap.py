"""Is the POMDPs' extra overconfidence on the test models, over their held-out closed loop,
more than sampling noise? (docs/awareness.md §4.8, the open lead of round three.)

For each workspace and method it runs the held-out closed loop as the evaluate stage does
(``experiment.held_out.closed_loop_declared``) and reads the evaluate stage's test episodes.
Held out, each group's stops report with the a the *other* groups' stops give (what
``declared_fit.json`` scores); on the test models, the episodes report with the a fitted on
every group (what the stage applied). Per method it prints each side's confidence − accuracy,
the test minus held-out gap per workspace, and the gap pooled over the workspaces with a 95 %
percentile interval, per set of workspaces (those in one folder: a study's configuration),
that resamples, within each workspace, the test models and the held-out
volume models independently (each object's episodes together; the workspaces themselves are
fixed, so the interval is the objects' sampling only). A diagnostic: it decides nothing.

    python benchmarks/declared_transfer_gap.py -w W [W ...] [--methods ra classifier random]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from rapomdp.context import RunContext
from rapomdp.experiment.episode_table import EPISODES_FILE, EpisodeTable
from rapomdp.experiment.held_out import HELD_OUT_STARTS, closed_loop_declared
from rapomdp.pipeline import get_stage
from rapomdp.recognition.belief import declared_log_beliefs
from rapomdp.workspace import Workspace

RESAMPLES = 10_000


def held_out_gaps(log_beliefs: np.ndarray, truth: np.ndarray, groups: list[int],
                  temperatures: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """Per held-out object: its episodes' summed (declared confidence − right) and count,
    each group's stops raised to the a of the other groups. Episodes come in the loop's order:
    group by group, ``HELD_OUT_STARTS`` consecutive episodes per model."""
    if len(truth) % (len(groups) * HELD_OUT_STARTS):
        raise ValueError("the held-out groups differ in size: this split is not supported")
    per_group = len(truth) // len(groups)
    sums, counts = [], []
    for g, a in enumerate(temperatures):
        rows = slice(g * per_group, (g + 1) * per_group)
        declared = declared_log_beliefs(log_beliefs[rows], a)
        gap = np.exp(declared.max(axis=1)) - (declared.argmax(axis=1) == truth[rows])
        objects = gap.reshape(-1, HELD_OUT_STARTS)
        sums.append(objects.sum(axis=1))
        counts.append(np.full(len(objects), HELD_OUT_STARTS))
    return np.concatenate(sums), np.concatenate(counts)


def test_gaps(table: EpisodeTable, method: str) -> tuple[np.ndarray, np.ndarray]:
    """Per test model: its episodes' summed (reported confidence − right) and count."""
    mine = table.method == method
    gap = table.final_confidence()[mine] - table.correct[mine].astype(float)
    models, index = np.unique(table.model[mine], return_inverse=True)
    return (np.bincount(index, weights=gap, minlength=len(models)),
            np.bincount(index, minlength=len(models)).astype(float))


def resampled_ratio(sums: np.ndarray, counts: np.ndarray, rng: np.random.Generator
                    ) -> np.ndarray:
    """(RESAMPLES,) the ratio sum/count over objects drawn with replacement."""
    draw = rng.multinomial(len(sums), np.full(len(sums), 1.0 / len(sums)), size=RESAMPLES)
    return (draw @ sums) / (draw @ counts)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    parser.add_argument("--methods", nargs="+", default=["ra", "classifier", "vptree"])
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    draws: dict[str, list[np.ndarray]] = {}
    points: dict[str, list[float]] = {}
    print(f"{'workspace':48s} {'method':10s} {'held out':>9s} {'test':>7s} {'gap':>7s}")
    for root in args.workspace:
        ws = Workspace(root)
        config = ws.config()
        inputs = ws.inputs(get_stage("evaluate"))
        table = EpisodeTable.load(ws.require("evaluate") / EPISODES_FILE)
        with tempfile.TemporaryDirectory() as tmp:
            fits = closed_loop_declared(config, inputs, args.methods, Path(tmp),
                                        RunContext(progress=False))
        for name, fit in fits.items():
            d = fit.declared
            h_sums, h_counts = held_out_gaps(fit.log_beliefs, fit.truth, list(d.groups),
                                             list(d.held_out_temperatures))
            t_sums, t_counts = test_gaps(table, name)
            held, test = h_sums.sum() / h_counts.sum(), t_sums.sum() / t_counts.sum()
            key = f"{root.parent.name}: {name}"
            points.setdefault(key, []).append(test - held)
            draws.setdefault(key, []).append(resampled_ratio(t_sums, t_counts, rng)
                                              - resampled_ratio(h_sums, h_counts, rng))
            print(f"{str(root):48s} {name:10s} {held:+9.3f} {test:+7.3f} {test - held:+7.3f}")
    print("\npooled over each folder's workspaces: test − held-out confidence − accuracy, "
          "95 % interval (objects resampled, workspaces fixed)")
    for name, values in draws.items():
        pooled = np.mean(np.stack(values), axis=0)
        low, high = np.percentile(pooled, [2.5, 97.5])
        print(f"{name:36s} {np.mean(points[name]):+.3f} [{low:+.3f}, {high:+.3f}]  "
              f"({len(values)} workspaces)")


if __name__ == "__main__":
    main()
