"""The hand-written statistics against the dependencies' (issue 28): values and speed.

Compares, on seeded synthetic data of the pipeline's sizes,
* the closed-form Wilson interval against SciPy's ``binomtest(k, n).proportion_ci("wilson")``;
* the rank-sum ROC AUC against scikit-learn's ``roc_auc_score``;
* the ridge-penalised Newton logistic fit against scikit-learn's ``LogisticRegression``
  (``C = 1 / ridge``, no separate intercept: the design matrix holds it, as in the calibrations).

The former functions are copied here; the new ones are the library's (``wilson_interval``,
``roc_auc``, ``ridge_logistic``).

Prints the largest difference of the values and the median time of one call of each.

Usage: OMP_NUM_THREADS=1 PYTHONPATH=src python benchmarks/statistic_replacements.py
Writes nothing (prints); quoted in the report of issue 28.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
from scipy import stats
from scipy.stats import rankdata

from rapomdp.awareness.observation import ridge_logistic
from rapomdp.awareness.quality import roc_auc
from rapomdp.experiment.metrics import wilson_interval

Z95 = float(stats.norm.ppf(0.975))


def wilson_closed_form(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """The former ``metrics.wilson_interval``."""
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return float(max(0.0, centre - half)), float(min(1.0, centre + half))


def auc_ranks(scores: np.ndarray, positive: np.ndarray) -> float:
    """The former ``quality.roc_auc``."""
    n_pos, n_neg = int(positive.sum()), int((~positive).sum())
    ranks = rankdata(scores)
    return float((ranks[positive].sum() - n_pos * (n_pos + 1) / 2) / (n_pos * n_neg))


def newton(x: np.ndarray, y: np.ndarray, ridge: float) -> np.ndarray:
    """The former ``observation.newton_logistic``."""
    w = np.zeros(x.shape[1])
    for _ in range(50):
        p = 1.0 / (1.0 + np.exp(-(x @ w)))
        grad = x.T @ (p - y) + ridge * w
        hess = (x * (p * (1 - p))[:, None]).T @ x + ridge * np.eye(x.shape[1])
        step = np.linalg.solve(hess, grad)
        w = w - step
        if np.max(np.abs(step)) < 1e-10:
            break
    return w


def median_ms(function: Callable[[], object], repeat: int = 20) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return 1e3 * float(np.median(times))


def per_class_design(rng: np.random.Generator, rows: int, classes: int) -> tuple[np.ndarray,
                                                                                 np.ndarray]:
    """One-hot class columns and a score column, rightness rising with the score."""
    g = rng.integers(0, classes, rows)
    s = rng.random(rows)
    x = np.zeros((rows, classes + 1))
    x[np.arange(rows), g] = 1.0
    x[:, classes] = s
    logit = rng.normal(0.0, 1.0, classes)[g] + 2.0 * s
    return x, (rng.random(rows) < 1 / (1 + np.exp(-logit))).astype(np.float64)


def main() -> None:
    rng = np.random.default_rng(0)
    print("Wilson interval, every k of n = 1..60:")
    gap, below = 0.0, 0
    for n in range(1, 61):
        for k in range(n + 1):
            a, b = wilson_closed_form(k, n), wilson_interval(k, n)
            gap = max(gap, abs(a[0] - b[0]), abs(a[1] - b[1]))
            below += a[0] > k / n or a[1] < k / n
    print(f"  largest difference {gap:.2e}; closed form excluding the proportion: {below} "
          f"of {sum(n + 1 for n in range(1, 61))}")
    print(f"  time per call: closed form {median_ms(lambda: wilson_closed_form(7, 12)):.3f} ms, "
          f"SciPy {median_ms(lambda: wilson_interval(7, 12)):.3f} ms")

    print("ROC AUC (ties: scores rounded to 2 decimals):")
    for n in (100, 2_000, 50_000):
        scores = np.round(rng.random(n), 2)
        positive = rng.random(n) < scores
        a, b = auc_ranks(scores, positive), roc_auc(scores, positive)
        ranks_ms = median_ms(lambda s=scores, p=positive: auc_ranks(s, p))
        sklearn_ms = median_ms(lambda s=scores, p=positive: roc_auc(s, p))
        print(f"  n={n:>6}: |difference| {abs(a - b):.2e}; ranks {ranks_ms:.3f} ms, "
              f"scikit-learn {sklearn_ms:.3f} ms")

    print("ridge logistic fit (ridge 1e-2; columns: one-hot classes + score):")
    for rows, classes in ((200, 1), (2_000, 3), (20_000, 35), (200_000, 35)):
        x, y = per_class_design(rng, rows, classes)
        if classes == 1:
            x[:, 0] = 1.0
        a, b = newton(x, y, 1e-2), ridge_logistic(x, y, 1e-2)
        repeat = 5 if rows >= 100_000 else 20
        newton_ms = median_ms(lambda x=x, y=y: newton(x, y, 1e-2), repeat)
        sklearn_ms = median_ms(lambda x=x, y=y: ridge_logistic(x, y, 1e-2), repeat)
        print(f"  {rows:>7} rows x {x.shape[1]:>2}: max |w difference| "
              f"{np.max(np.abs(a - b)):.2e}; Newton {newton_ms:.2f} ms, scikit-learn "
              f"{sklearn_ms:.2f} ms")
    x, y = per_class_design(rng, 500, 3)
    y[:] = 1.0  # every outcome right: scikit-learn needs the two zero rows of ridge_logistic
    print(f"  all right, 500 rows x 4: max |w difference| "
          f"{np.max(np.abs(newton(x, y, 1e-2) - ridge_logistic(x, y, 1e-2))):.2e}")

if __name__ == "__main__":
    main()
