"""The pooled interval on planted data: known variance components, seeds that agree or not."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.experiment.metrics import cluster_bootstrap_difference
from rapomdp.study.bootstrap import SeedClusters, hierarchical_bootstrap


def _seed(values: np.ndarray, offset: int = 0) -> SeedClusters:
    ids = np.array([f"m{offset + i:03d}" for i in range(values.size)])
    return SeedClusters(ids, values.astype(float), np.ones(values.size))


def _width(interval) -> float:
    return interval.high - interval.low


def test_nested_bootstrap_recovers_the_variance_of_the_grand_mean() -> None:
    """d = mu + a_seed + e: the interval's width is that of sigma_a^2/S + sigma_e^2/(S M)."""
    rng = np.random.default_rng(1)
    seeds, models, sigma_a, sigma_e = 40, 30, 0.10, 0.30
    effects = rng.normal(0.0, sigma_a, seeds)
    data = [_seed(0.05 + a + rng.normal(0.0, sigma_e, models), s * models)
            for s, a in enumerate(effects)]
    pooled = hierarchical_bootstrap(data, resamples=4000, seed=2)
    assert not pooled.crossed
    true_sd = np.sqrt(sigma_a**2 / seeds + sigma_e**2 / (seeds * models))
    # a 95 % percentile interval spans about 2 x 1.96 standard deviations
    assert _width(pooled) / (2 * 1.96) == pytest.approx(true_sd, rel=0.2)
    assert pooled.estimate == pytest.approx(np.mean([d.ratio for d in data]))


def test_seeds_that_disagree_widen_the_interval_seeds_that_agree_do_not() -> None:
    rng = np.random.default_rng(3)
    noise = [rng.normal(0.0, 0.3, 35) for _ in range(3)]
    agree = [_seed(0.1 + e, 100 * s) for s, e in enumerate(noise)]
    disagree = [_seed(shift + e, 100 * s) for s, (shift, e) in
                enumerate(zip([-0.3, 0.1, 0.5], noise, strict=True))]
    same = hierarchical_bootstrap(agree, resamples=4000, seed=4)
    spread = hierarchical_bootstrap(disagree, resamples=4000, seed=4)
    assert _width(spread) > 2.5 * _width(same)
    # seeds that agree: as wide as one flat bootstrap over all their models together
    flat = cluster_bootstrap_difference(np.concatenate(noise) + 0.1, np.ones(105),
                                        resamples=4000, seed=4)
    assert _width(same) == pytest.approx(flat[2] - flat[1], rel=0.15)


def test_identical_seeds_on_the_same_models_give_the_single_seed_interval() -> None:
    """Crossed: the same test models in every seed; three copies of one seed tell no more."""
    values = np.random.default_rng(5).normal(0.05, 0.4, 40)
    one = _seed(values)
    pooled = hierarchical_bootstrap([one, one, one], resamples=6000, seed=6)
    assert pooled.crossed
    _, low, high = cluster_bootstrap_difference(one.sums, one.pairs, resamples=6000, seed=6)
    assert pooled.low == pytest.approx(low, abs=0.01)
    assert pooled.high == pytest.approx(high, abs=0.01)
    nested = hierarchical_bootstrap([one, one, one], resamples=6000, seed=6, crossed=False)
    assert _width(nested) < 0.7 * _width(pooled)  # what treating them as new models would claim


def test_refusals_name_the_problem() -> None:
    with pytest.raises(ValueError, match="at least one seed"):
        hierarchical_bootstrap([])
    with pytest.raises(ValueError, match="positive pair count"):
        SeedClusters(np.array(["a"]), np.array([1.0]), np.array([0.0]))
    a, b = _seed(np.ones(3)), _seed(np.ones(3), 10)
    with pytest.raises(ValueError, match="same test models"):
        hierarchical_bootstrap([a, b], crossed=True)
