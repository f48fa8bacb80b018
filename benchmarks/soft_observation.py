"""Would the classifier's confidence, which the top label throws away, recognise held-out
objects better? (rule: ``benchmarks/results/soft_observation_rule.md``.) Never reads the test
models.

For each workspace it takes the evaluate stage's held-out folds of the chosen RA model and the
Classifier model (``experiment.held_out.held_out_folds``: each fitted without its volume group
and tempered by the belief's t) and walks 16 random walks of 8 views per held-out object,
updating three kinds of belief on the same walks:

- ``label``: the model's P_t(label | c, x), today's observation;
- ``label+bin``: times P(bin | label right) or P(bin | label wrong), the bin one of K = 3
  tertiles of the classifier's top tempered softmax probability, both counted on the other
  groups;
- ``softmax τ``: the tempered softmax p_T(c | image)^τ as the likelihood, τ ∈ {0.3, 0.5, 1}.

It prints per workspace and kind the accuracy of the belief's argmax after 1, 3, 5 and 8
views, the mean after 3..8 views (walk accuracy) and the accuracy where the max belief first
reaches 0.9, then the mean walk accuracy per folder (a study's configuration) and kind.

    python benchmarks/soft_observation.py -w W [W ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from rapomdp.awareness.choices import RecordedObservation
from rapomdp.experiment.held_out import held_out_folds
from rapomdp.pipeline import get_stage
from rapomdp.recognition.belief import random_walks, temper
from rapomdp.workspace import Workspace

sys.path.insert(0, str(Path(__file__).parent))
from train_recipe import volume_outputs  # noqa: E402  (reads the volume models only)

WALKS_PER_OBJECT = 16
WALK_VIEWS = 8
NEIGHBOURS = 8
BINS = 3
STOP_BELIEF = 0.9
SOFTMAX_POWERS = (0.3, 0.5, 1.0)


def bin_log_factor(confidence: np.ndarray, correct: np.ndarray, train: np.ndarray
                   ) -> np.ndarray:
    """(N, V, 2) log P(bin | label right) and log P(bin | label wrong) of every view, the
    bins and both distributions counted on the ``train`` rows only."""
    edges = np.quantile(confidence[train].ravel(), np.linspace(0, 1, BINS + 1)[1:-1])
    bins = np.digitize(confidence, edges)
    right = np.bincount(bins[train][correct[train]], minlength=BINS) + 1.0
    wrong = np.bincount(bins[train][~correct[train]], minlength=BINS) + 1.0
    log_right, log_wrong = np.log(right / right.sum()), np.log(wrong / wrong.sum())
    return np.stack([log_right[bins], log_wrong[bins]], axis=-1)  # (N, V, 2)


def walk_figures(log_likelihood: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Accuracy after each view (WALK_VIEWS,) and at the STOP_BELIEF stop, from per-step
    log-likelihoods (E, L, C)."""
    log_b = np.cumsum(log_likelihood, axis=1)
    log_b -= log_b.max(axis=-1, keepdims=True)
    belief = np.exp(log_b)
    belief /= belief.sum(axis=-1, keepdims=True)
    right = belief.argmax(axis=-1) == truth[:, None]  # (E, L)
    reached = belief.max(axis=-1) >= STOP_BELIEF
    stop = np.where(reached.any(axis=1), reached.argmax(axis=1), log_likelihood.shape[1] - 1)
    return np.append(right.mean(axis=0), right[np.arange(len(truth)), stop].mean())


def workspace_figures(root: Path, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Every kind's figures on one workspace's held-out groups, pooled over the walks."""
    ws = Workspace(root)
    config = ws.config()
    inputs = ws.inputs(get_stage("evaluate"))
    recorded = RecordedObservation.load(inputs.observe)
    evidence = recorded.evidence
    views = len(recorded.arrays["directions"])
    flat, _ = volume_outputs(root)  # the volume models' outputs, one row a view
    volume = flat.reshape(-1, views, flat.shape[1])  # (M, V, C)
    if not np.array_equal(volume.argmax(axis=-1), evidence.predicted):
        raise ValueError(f"{root}: the volume outputs do not match the observe evidence")
    groups = evidence.groups
    labels = evidence.labels
    # softmax at temperature T: p ** (1 / T), renormalised
    soft = temper(volume, 1.0 / float(recorded.arrays["softmax_temperature"]))
    confidence, predicted = soft.max(axis=-1), volume.argmax(axis=-1)
    correct = predicted == labels[:, None]
    directions = recorded.arrays["directions"]
    folds = held_out_folds(config, inputs, ["ra", "classifier"])
    classes = volume.shape[-1]
    sums: dict[str, list[np.ndarray]] = {}
    for ra_fold, classifier_fold in zip(folds["ra"], folds["classifier"], strict=True):
        held = groups == ra_fold.group
        rows = np.repeat(np.flatnonzero(held), WALKS_PER_OBJECT)
        starts = rng.integers(0, len(directions), size=rows.size)
        walks = random_walks(directions, starts, WALK_VIEWS, NEIGHBOURS, rng)  # (E, L)
        seen = predicted[rows[:, None], walks]  # (E, L) labels
        truth = labels[rows]
        bins = bin_log_factor(confidence, correct, ~held)[rows[:, None], walks]
        is_label = seen[..., None] == np.arange(classes)  # (E, L, C)
        bin_term = np.where(is_label, bins[..., :1], bins[..., 1:])
        for name, fold in (("ra", ra_fold), ("classifier", classifier_fold)):
            label = np.log(np.maximum(fold.model[walks[..., None], np.arange(classes),
                                                 seen[..., None]], 1e-300))
            sums.setdefault(f"{name} label", []).append(walk_figures(label, truth) * len(rows))
            sums.setdefault(f"{name} label+bin", []).append(
                walk_figures(label + bin_term, truth) * len(rows))
        for power in SOFTMAX_POWERS:
            log_soft = power * np.log(np.maximum(soft[rows[:, None], walks], 1e-300))
            sums.setdefault(f"softmax {power}", []).append(
                walk_figures(log_soft, truth) * len(rows))
    walks_total = WALKS_PER_OBJECT * int(sum((groups == f.group).sum() for f in folds["ra"]))
    return {kind: np.sum(parts, axis=0) / walks_total for kind, parts in sums.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    pooled: dict[str, list[float]] = {}
    print(f"{'workspace':44s} {'kind':22s} {'@1':>6s} {'@3':>6s} {'@5':>6s} {'@8':>6s} "
          f"{'walk':>6s} {'stop':>6s}")
    for root in args.workspace:
        for kind, f in workspace_figures(root, rng).items():
            walk = float(f[2:WALK_VIEWS].mean())
            pooled.setdefault(f"{root.parent.name}: {kind}", []).append(walk)
            print(f"{str(root):44s} {kind:22s} {f[0]:6.3f} {f[2]:6.3f} {f[4]:6.3f} "
                  f"{f[WALK_VIEWS - 1]:6.3f} {walk:6.3f} {f[WALK_VIEWS]:6.3f}")
    print("\nmean walk accuracy (after 3..8 views) over each folder's workspaces")
    for key, values in pooled.items():
        print(f"{key:50s} {np.mean(values):.3f}  ({len(values)} workspaces)")


if __name__ == "__main__":
    main()
