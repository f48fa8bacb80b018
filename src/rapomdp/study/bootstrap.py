"""A paired difference pooled over seeds, with an interval that carries both sources of
variance: which seed (split, classifier, starts) and which test models.

Each seed contributes its test models' summed paired differences and pair counts (the
clusters of :func:`rapomdp.experiment.metrics.cluster_bootstrap_difference`). The pooled
estimate is the mean over seeds of each seed's ratio sum(d) / sum(n). A resample draws seeds
with replacement and then, within each drawn seed, its test models with replacement (a
two-stage bootstrap). Done naively that counts the test-model variance twice (the spread of
the seed means already holds it), so each seed's mean is first shrunk toward the grand mean
until the seeds' spread is the between-seed variance alone, estimated by moments: the spread
of the seed means less their mean within-seed variance (Davison & Hinkley 1997, Sec. 3.8).
When every seed evaluated the *same* test models (the dataset stage is shared: the study
varied the classifier only), models are crossed with seeds: one draw of models is applied to
every seed, so identical seeds give the single-seed interval instead of a falsely narrower one.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SeedClusters:
    """One seed's test models: their ids, summed paired differences and pair counts."""

    models: np.ndarray
    sums: np.ndarray
    pairs: np.ndarray

    def __post_init__(self) -> None:
        if not (self.models.shape == self.sums.shape == self.pairs.shape) \
                or self.sums.ndim != 1 or self.sums.size == 0 or np.any(self.pairs <= 0):
            raise ValueError("a seed needs one positive pair count per model and at least one "
                             "model")

    @property
    def ratio(self) -> float:
        return float(self.sums.sum() / self.pairs.sum())


@dataclass(frozen=True)
class PooledInterval:
    """The mean over seeds of a per-seed paired difference and its 95 % interval."""

    estimate: float
    low: float
    high: float
    seeds: int
    crossed: bool


def _crossed(seeds: Sequence[SeedClusters]) -> bool:
    first = seeds[0].models
    return all(s.models.shape == first.shape and np.array_equal(s.models, first) for s in seeds)


def hierarchical_bootstrap(seeds: Sequence[SeedClusters], resamples: int = 10_000,
                           seed: int = 0, level: float = 0.95,
                           crossed: bool | None = None) -> PooledInterval:
    """The pooled paired difference over ``seeds`` and its percentile interval.

    ``crossed``: resample one set of test models for every seed (they are the same models);
    None decides it from the ids (every seed lists the same models).

    Args:
        seeds: Each seed's test models: ids, summed paired differences and pair counts.
        resamples: Bootstrap resamples.
        seed: Seed of the resampling.
        level: The interval's coverage (0.95: the 2.5th and 97.5th percentiles).
        crossed: Whether the seeds share their test models (None: from the ids).

    Returns:
        The mean over seeds of each seed's ratio sum(d) / sum(n), its interval, the number
        of seeds and whether models were crossed with seeds.

    Raises:
        ValueError: No seed, ``resamples`` < 1, or ``crossed`` with different models.

    Example:
        >>> import numpy as np
        >>> from rapomdp.study.bootstrap import SeedClusters, hierarchical_bootstrap
        >>> models, pairs = np.array([0, 1, 2]), np.array([4, 4, 4])
        >>> seeds = [SeedClusters(models, np.array([1.0, 0.0, 2.0]), pairs),
        ...          SeedClusters(models, np.array([2.0, 1.0, 1.0]), pairs)]
        >>> pooled = hierarchical_bootstrap(seeds, resamples=2000)
        >>> round(pooled.estimate, 4), pooled.low <= pooled.estimate <= pooled.high
        (0.2917, True)
        >>> pooled.crossed  # the same test models in both seeds
        True
    """
    if not seeds:
        raise ValueError("a pooled interval needs at least one seed")
    if resamples < 1:
        raise ValueError(f"resamples must be at least 1, got {resamples}")
    crossed = _crossed(seeds) if crossed is None else crossed
    if crossed and not _crossed(seeds):
        raise ValueError("crossed resampling needs the same test models in every seed")
    rng = np.random.default_rng(seed)
    k = len(seeds)
    ratios = np.array([s.ratio for s in seeds])
    estimate = float(ratios.mean())
    drawn = rng.integers(0, k, size=(resamples, k))  # which seed fills each slot
    deviation = np.empty((resamples, k))  # each slot's within-seed draw minus its seed's ratio
    if crossed:
        m = seeds[0].sums.size
        counts = rng.multinomial(m, np.full(m, 1.0 / m), size=resamples)  # shared by all seeds
        sums = np.stack([s.sums for s in seeds])          # (k, m)
        pairs = np.stack([s.pairs for s in seeds])
        per_seed = (counts @ sums.T) / (counts @ pairs.T) - ratios  # (resamples, k)
        deviation = np.take_along_axis(per_seed, drawn, axis=1)
        # only the part of the model draw that seeds do not share spreads the seed means
        within = float((per_seed - per_seed.mean(axis=1, keepdims=True)).var(axis=0).mean())
    else:
        variances = []
        for index, clusters in enumerate(seeds):
            m = clusters.sums.size
            slots = drawn == index  # each slot this seed fills gets its own draw of models
            counts = rng.multinomial(m, np.full(m, 1.0 / m), size=max(int(slots.sum()), 2))
            mine = (counts @ clusters.sums) / (counts @ clusters.pairs) - ratios[index]
            deviation[slots] = mine[:int(slots.sum())]
            variances.append(mine.var())
        within = float(np.mean(variances))
    between = max(0.0, float(ratios.var(ddof=1)) - within) if k > 1 else 0.0
    spread = float(ratios.var())
    shrink = np.sqrt(between / spread) if spread > 0 else 0.0
    centres = estimate + shrink * (ratios - estimate)
    draws = centres[drawn] + deviation
    pooled = draws.mean(axis=1)
    tail = (1.0 - level) / 2.0 * 100.0
    low, high = np.percentile(pooled, [tail, 100.0 - tail])
    return PooledInterval(estimate, float(low), float(high), k, crossed)
