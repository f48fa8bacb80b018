"""How hard a workspace's benchmark is for its classifier, and how much moving the camera can win.

Reads a workspace where ``rapomdp run`` has reached ``classifier_eval`` (the trained CNN's class
probabilities for every test model at every test viewpoint X_rho) and prints:

1. single-view accuracy over X_rho on the test models, overall and per class (with the class
   each is most often taken for);
2. the spread of per-viewpoint accuracy: for each class the accuracy at each viewpoint over its
   test models, the share of viewpoints where nearly every test model is right (>= 0.75) and
   where nearly none is (<= 0.25), and the standard deviation over viewpoints against the one a
   viewpoint-independent classifier would show (binomial over the class's test models);
3. oracle accuracy from k = 1, 2, 3 views fused by Bayes' rule (the product of the CNN's
   probabilities, uniform prior): k views drawn at random (what a method that does not choose
   gets), the best k viewpoints for each class in hindsight (one set per class, the same for all
   its test models; k = 3 extends the best pair greedily), and the best k viewpoints for each
   test model in hindsight (an upper bound). All over the 128 viewpoints of X_rho, reachable or
   not.

These are properties of the benchmark measured on its test models (nothing is chosen from them).

Usage: OMP_NUM_THREADS=1 python benchmarks/dataset_difficulty.py --workspace runs/demo
Writes benchmarks/results/dataset_difficulty.txt (or --out).
"""

from __future__ import annotations

import argparse
import shlex
import sys
from itertools import combinations
from pathlib import Path

import numpy as np

from rapomdp.data.procedural import CLASSES
from rapomdp.io import load_npz, read_json, write_text_atomic

RESULTS = Path(__file__).parent / "results" / "dataset_difficulty.txt"


def fused_correct(log_p: np.ndarray, labels: np.ndarray, sets: np.ndarray) -> np.ndarray:
    """(models, sets) whether fusing each view set (sets, k) declares the true class."""
    fused = log_p[:, sets].sum(axis=2)  # (models, sets, C)
    return fused.argmax(axis=2) == labels[:, None]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", type=Path, default=Path("runs/demo"))
    parser.add_argument("--out", type=Path, default=RESULTS)
    parser.add_argument("--random-draws", type=int, default=400)
    args = parser.parse_args()
    lines: list[str] = []

    def out(text: str = "") -> None:
        print(text, flush=True)
        lines.append(text)

    out("command: " + shlex.join([Path(sys.executable).name, *sys.argv]))
    root = args.workspace
    arrays = load_npz(root / "classifier_eval" / "probabilities.npz")
    probs = arrays["xrho"].astype(np.float64)  # (models, views, C)
    labels = arrays["labels"].astype(np.int64)
    classes = [str(c) for c in arrays["classes"]]
    train = read_json(root / "train" / "metrics.json")
    models, views, count = probs.shape
    correct = probs.argmax(axis=2) == labels[:, None]
    out(f"workspace: {root.resolve()}")
    out(f"{count} classes, {models} test models ({models // count} a class), {views} test "
        f"viewpoints; classifier: {train['train_images']} training images, "
        f"{train['epochs']} epochs, validation accuracy {train['final_validation_accuracy']:.3f}")
    out()
    out("## 1. Single-view accuracy over X_rho on the test models")
    out()
    out(f"overall {correct.mean():.3f} (chance {1 / count:.3f})")
    confusion = np.zeros((count, count))
    np.add.at(confusion, (np.repeat(labels, views), probs.argmax(axis=2).ravel()), 1)
    family = {name: CLASSES[name].family if name in CLASSES else "-" for name in classes}
    out()
    out("| class | family | accuracy | most often taken for |")
    out("|---|---|---|---|")
    for c in np.argsort(-confusion.diagonal() / confusion.sum(axis=1)):
        row = confusion[c] / confusion[c].sum()
        other = [j for j in np.argsort(-row) if j != c][0]
        out(f"| {classes[c]} | {family[classes[c]]} | {row[c]:.2f} | {classes[other]} "
            f"({row[other]:.2f}) |")
    out()
    out("## 2. Per-viewpoint accuracy over the hemisphere")
    out()
    out("| class | mean | share of viewpoints >= 0.75 | share <= 0.25 | sd over viewpoints "
        "| sd if viewpoint-independent |")
    out("|---|---|---|---|---|---|")
    strong, excess = 0, []
    for c in range(count):
        per_view = correct[labels == c].mean(axis=0)
        n = int((labels == c).sum())
        mean = per_view.mean()
        high, low = (per_view >= 0.75).mean(), (per_view <= 0.25).mean()
        sd, sd0 = per_view.std(), np.sqrt(mean * (1 - mean) / n)
        strong += high >= 0.1 and low >= 0.1
        excess.append(sd / sd0 if sd0 > 0 else np.nan)
        out(f"| {classes[c]} | {mean:.2f} | {high:.2f} | {low:.2f} | {sd:.3f} | {sd0:.3f} |")
    out()
    out(f"classes with >= 10 % of viewpoints at >= 0.75 and >= 10 % at <= 0.25: {strong} of "
        f"{count}; median sd ratio (observed / viewpoint-independent): "
        f"{np.nanmedian(excess):.2f}")
    out()
    out("## 3. Oracle accuracy from k views (Bayes fusion of the CNN's probabilities)")
    out()
    log_p = np.log(np.clip(probs, 1e-12, 1.0))
    rng = np.random.default_rng(0)
    pairs = np.array(list(combinations(range(views), 2)))
    per_class_best: dict[int, list[float]] = {1: [], 2: [], 3: []}
    per_model_best: dict[int, list[bool]] = {1: [], 2: [], 3: []}
    for c in range(count):
        rows = labels == c
        lp, lab = log_p[rows], labels[rows]
        single = correct[rows]
        per_class_best[1].append(single.mean(axis=0).max())
        per_model_best[1] += list(single.any(axis=1))
        pair_ok = fused_correct(lp, lab, pairs)  # (n, pairs)
        best_pair = pairs[np.argmax(pair_ok.mean(axis=0))]
        per_class_best[2].append(pair_ok.mean(axis=0).max())
        per_model_best[2] += list(pair_ok.any(axis=1))
        triples = np.array([[*best_pair, v] for v in range(views) if v not in best_pair])
        per_class_best[3].append(fused_correct(lp, lab, triples).mean(axis=0).max())
        # per model, k = 3: the model's best pair extended greedily
        for i in range(lp.shape[0]):
            best = pairs[np.argmax(pair_ok[i])]
            extra = np.array([[*best, v] for v in range(views) if v not in best])
            per_model_best[3].append(bool(fused_correct(lp[i:i + 1], lab[i:i + 1],
                                                        extra).any()))
    out("| views k | random k views | best k per class (hindsight) | best k per test model "
        "(hindsight) |")
    out("|---|---|---|---|")
    # "best k" is the best set of at most k views: an active method may stop early
    best_class = np.maximum.accumulate(np.array([per_class_best[k] for k in (1, 2, 3)]), axis=0)
    best_model = np.maximum.accumulate(np.array([per_model_best[k] for k in (1, 2, 3)]), axis=0)
    for k in (1, 2, 3):
        draws = np.stack([rng.choice(views, size=k, replace=False)
                          for _ in range(args.random_draws)])
        random_acc = fused_correct(log_p, labels, draws).mean()
        out(f"| {k} | {random_acc:.3f} | {best_class[k - 1].mean():.3f} | "
            f"{best_model[k - 1].mean():.3f} |")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(args.out, "\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
