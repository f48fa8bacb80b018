"""The belief's rule in its one home: Eq. 5 in both forms, the temperature, the declared
confidence, the closed loop's BayesBelief, and that every caller reads these same functions."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from rapomdp.belief import (
    BayesBelief,
    accumulate_log_beliefs,
    class_marginal,
    declared_belief,
    safe_log,
    temper,
    update_beliefs,
)

SOURCE = Path(__file__).resolve().parents[1] / "src" / "rapomdp"
#: The rule's functions: defined in rapomdp/belief.py and nowhere else.
RULE = {"update_beliefs", "accumulate_log_beliefs", "temper", "declared_log_beliefs",
        "declared_belief", "class_marginal", "safe_log", "BayesBelief"}


def _planted_model(views: int, classes: int, rng: np.random.Generator) -> np.ndarray:
    p = rng.dirichlet(np.ones(classes), size=(views, classes))
    p = 0.4 * p + 0.6 * np.eye(classes)[None]
    return p / p.sum(axis=2, keepdims=True)


def test_the_rule_is_defined_once_and_every_caller_reads_that_one() -> None:
    defined = sorted(
        f"{path.relative_to(SOURCE)}:{node.name}" for path in sorted(SOURCE.rglob("*.py"))
        for node in ast.walk(ast.parse(path.read_text(), str(path)))
        if isinstance(node, ast.FunctionDef | ast.ClassDef) and node.name in RULE)
    assert defined == sorted(f"belief.py:{name}" for name in RULE)
    import rapomdp.experiment.methods as methods
    import rapomdp.experiment.recorded_env as recorded_env
    import rapomdp.planning as planning
    import rapomdp.planning.momdp as momdp
    import rapomdp.recognition.belief as recognition_belief

    assert planning.update_beliefs is momdp.update_beliefs is update_beliefs
    assert methods.BayesBelief is recorded_env.BayesBelief is BayesBelief
    assert recognition_belief.temper is methods.temper is temper


def test_the_update_and_its_log_form_give_the_same_beliefs() -> None:
    rng = np.random.default_rng(3)
    p = _planted_model(5, 4, rng)
    views = np.array([[0, 2, 4], [1, 1, 3]])
    labels = np.array([[1, 1, 3], [0, 2, 2]])
    b = np.full((2, 4), 0.25)
    steps = []
    for k in range(3):
        b = update_beliefs(p, b, views[:, k], labels[:, k])
        steps.append(b)
    log_lik = safe_log(p[views[..., None], np.arange(4), labels[..., None]])  # (2, 3, 4)
    np.testing.assert_allclose(np.exp(accumulate_log_beliefs(log_lik)),
                               np.stack(steps, axis=1), rtol=1e-12)
    with pytest.raises(ValueError, match="probability 0"):
        update_beliefs(np.array([[[1.0, 0.0], [1.0, 0.0]]]), np.array([0.5, 0.5]), 0, 1)


def test_temper_keeps_rows_normalised_and_flattens_them() -> None:
    rng = np.random.default_rng(4)
    p = _planted_model(5, 4, rng)
    assert np.array_equal(temper(p, 1.0), p)
    cooled = temper(p, 0.5)
    assert np.allclose(cooled.sum(axis=2), 1.0)
    entropy = [-(q * np.log(q)).sum(axis=2) for q in (p, cooled)]
    assert np.all(entropy[1] > entropy[0])
    assert np.allclose(temper(p, 0.5), np.sqrt(p) / np.sqrt(p).sum(axis=2, keepdims=True))


def test_temper_takes_one_temperature_per_viewpoint() -> None:
    rng = np.random.default_rng(6)
    p = _planted_model(4, 3, rng)
    t = np.array([1.0, 0.5, 0.0, 2.0])
    out = temper(p, t)
    for v in range(4):
        np.testing.assert_allclose(out[v], temper(p[v:v + 1], float(t[v]))[0])
    np.testing.assert_allclose(out[2], 1.0 / 3)  # weight 0: no evidence


def test_the_declared_belief_keeps_the_argmax_and_flattens_below_one() -> None:
    belief = np.array([[0.7, 0.2, 0.1], [0.1, 0.05, 0.85]])
    flat = declared_belief(belief, 0.5)
    assert np.allclose(flat.sum(axis=1), 1.0)
    assert np.array_equal(flat.argmax(axis=1), belief.argmax(axis=1))
    assert np.allclose(flat[0], np.sqrt(belief[0]) / np.sqrt(belief[0]).sum())
    assert np.all(flat.max(axis=1) < belief.max(axis=1))
    assert np.array_equal(declared_belief(belief[0], 1.0), belief[0])


def test_the_class_marginal_sums_the_types() -> None:
    b = np.array([0.1, 0.2, 0.3, 0.4])  # two types of two classes, type-major
    np.testing.assert_allclose(class_marginal(b, 2), [0.4, 0.6])
    assert class_marginal(b, 4) is b and class_marginal(b) is b
    with pytest.raises(ValueError, match="no whole number of types"):
        class_marginal(b, 3)


def test_bayes_belief_updates_every_view_by_the_model_and_restarts_uniform() -> None:
    model = np.full((2, 2, 2), 0.5)
    model[:, 0] = [0.6, 0.4]
    belief = BayesBelief(model)
    np.testing.assert_allclose(belief.belief, [0.5, 0.5])
    output = np.array([1.0, 0.0])  # label 0
    belief.update(0, output)
    assert np.allclose(belief.belief, np.array([0.6, 0.5]) / 1.1)
    belief.update(1, output)
    assert np.allclose(belief.belief, np.array([0.36, 0.25]) / 0.61)
    assert belief.updates == 2
    belief.reset()
    assert belief.updates == 0 and np.allclose(belief.belief, [0.5, 0.5])


def test_bayes_belief_declares_its_class_belief_raised_to_a() -> None:
    model = np.array([[[0.9, 0.1], [0.2, 0.8]]] * 2)
    bayes = BayesBelief(np.concatenate([model, model[:, ::-1, ::-1]], axis=1), 0.5)  # 2 types
    bayes.update(1, np.array([0.2, 0.8]))
    np.testing.assert_allclose(bayes.belief, [0.15, 0.85])  # (0.1 + 0.2, 0.8 + 0.9) / 2
    root = np.sqrt(bayes.belief)
    np.testing.assert_allclose(bayes.declared, root / root.sum())
    with pytest.raises(ValueError, match="must be positive"):
        BayesBelief(model, 0.0)
