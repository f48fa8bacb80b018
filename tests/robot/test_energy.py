"""Movement energy E_M: penalty forms, matrix invariants, errors."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.geometry.viewsphere import fibonacci_directions, geodesic_distance_matrix
from rapomdp.robot.energy import joint_distance_matrix, movement_energy, singularity_penalty


@pytest.mark.parametrize(
    ("form", "at_half"), [("inverse", 1.0), ("log", np.log(2.0)), ("linear", 0.5)]
)
def test_penalty_forms(form: str, at_half: float) -> None:
    m = np.array([0.1, 0.05, 0.02, 0.0])
    penalty = singularity_penalty(m, reference=0.1, form=form)
    assert penalty[0] == 0.0
    assert penalty[1] == pytest.approx(at_half)
    assert np.all(np.diff(penalty) > 0)  # grows as manipulability falls
    assert penalty[3] == (1.0 if form == "linear" else np.inf)


def test_penalty_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="reference manipulability must be positive"):
        singularity_penalty(np.array([0.1]), reference=0.0)
    with pytest.raises(ValueError, match="unknown penalty form 'cubic'"):
        singularity_penalty(np.array([0.1]), reference=0.1, form="cubic")  # type: ignore[arg-type]


def _problem(n: int = 40, seed: int = 0):
    rng = np.random.default_rng(seed)
    distance = geodesic_distance_matrix(fibonacci_directions(n, hemisphere=True), 0.6)
    reachable = rng.random(n) < 0.7
    reachable[0] = True
    manipulability = np.where(reachable, rng.uniform(0.01, 0.1, n), np.nan)
    q = np.where(reachable[:, None], rng.uniform(-1, 1, (n, 7)), np.nan)
    return distance, manipulability, reachable, q


def test_energy_matrix_invariants() -> None:
    distance, m, reachable, q = _problem()
    energy = movement_energy(distance, m, reachable, kappa_m=0.1, penalty="inverse")
    assert np.all(np.diag(energy) == 0.0)
    assert np.all(energy >= 0.0)
    off = ~np.eye(len(m), dtype=bool)
    both = reachable[:, None] & reachable[None, :]
    assert np.all(np.isinf(energy[off & ~both]))
    assert np.all(np.isfinite(energy[both]))
    # the distance part is a metric: triangle inequality over every triple
    triple = distance[:, :, None] + distance[None, :, :]  # d(i, j) + d(j, k) at [i, j, k]
    assert np.all(distance[:, None, :] <= triple + 1e-12)
    # and E_M keeps it on the reachable set (the penalty depends only on the target)
    e = energy[np.ix_(reachable, reachable)]
    assert np.all(e[:, None, :] <= e[:, :, None] + e[None, :, :] + 1e-12)


def test_energy_is_distance_plus_penalty_of_the_target() -> None:
    distance, m, reachable, q = _problem()
    energy = movement_energy(distance, m, reachable, kappa_m=0.2, penalty="log")
    best = int(np.nanargmax(m))
    other = int(np.flatnonzero(reachable & (np.arange(m.size) != best))[0])
    assert energy[other, best] == pytest.approx(distance[other, best])
    expected = distance[best, other] + 0.2 * -np.log(m[other] / m[best])
    assert energy[best, other] == pytest.approx(expected)
    plain = movement_energy(distance, m, reachable, kappa_m=0.0)
    np.testing.assert_allclose(plain[np.ix_(reachable, reachable)],
                               distance[np.ix_(reachable, reachable)])


def test_joint_term_adds_joint_distance() -> None:
    distance, m, reachable, q = _problem()
    without = movement_energy(distance, m, reachable, kappa_m=0.1)
    with_joints = movement_energy(distance, m, reachable, kappa_m=0.1, q_rad=q,
                                  joint_weight_m_per_rad=0.05)
    i, j = np.flatnonzero(reachable)[:2]
    assert with_joints[i, j] - without[i, j] == pytest.approx(
        0.05 * np.linalg.norm(q[i] - q[j])
    )
    assert np.all(np.diag(with_joints) == 0.0)
    np.testing.assert_allclose(joint_distance_matrix(q[reachable]),
                               joint_distance_matrix(q[reachable]).T)


def test_energy_errors_name_the_problem() -> None:
    distance, m, reachable, q = _problem()
    with pytest.raises(ValueError, match="no viewpoint is reachable"):
        movement_energy(distance, m, np.zeros_like(reachable))
    with pytest.raises(ValueError, match="needs the joint solutions"):
        movement_energy(distance, m, reachable, joint_weight_m_per_rad=1.0)
    with pytest.raises(ValueError, match="shapes disagree"):
        movement_energy(distance[:-1, :-1], m, reachable)
