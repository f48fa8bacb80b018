"""What the learn, evaluate and report stages read: the configuration sections their keys hash
(the learn stage's fingerprint too) and the report's input stages (a light module: the stage
graph, e.g. for ``rapomdp status``, is read without loading the stages' code)."""

from __future__ import annotations

from collections.abc import Sequence

from rapomdp.config import Config
from rapomdp.io import stable_hash
from rapomdp.recognition.artefacts import TRAIN_SECTIONS

EVALUATE_SECTIONS = (*TRAIN_SECTIONS, "viewpoints", "evaluate")
REPORT_SECTIONS = ("seed",)
REPORT_INPUTS = ("dataset", "train", "classifier_eval", "observe", "robot", "solve", "evaluate")

#: The method key of the learned baseline in ``evaluate.methods``.
LEARNED = "learned"
#: The learn stage's key hashes these sections (its inputs carry the rest) and
#: :func:`learn_fingerprint`.
LEARN_SECTIONS = ("seed", "learn")


def learned_lambdas(lambda_: float, sweep: Sequence[float] = ()) -> list[float]:
    """The λ a learned policy is trained at: Table 1's first, then the sweep's others (in
    order).

    Args:
        lambda_: Table 1's λ in metres (``solve.wrong_declaration_cost_m``).
        sweep: The accuracy-energy sweep's λ in metres (``evaluate.lambdas``).

    Returns:
        ``lambda_``, then each λ of ``sweep`` not (numerically) seen before.

    Example:
        >>> learned_lambdas(8.0, [2.0, 8.0, 6.0, 2.0])
        [8.0, 2.0, 6.0]
    """
    out = [float(lambda_)]
    for lam in sweep:
        if not any(abs(lam - seen) <= 1e-8 + 1e-5 * abs(seen) for seen in out):  # np.isclose
            out.append(float(lam))
    return out


def learn_fingerprint(config: Config) -> str:
    """What the learn stage reads beyond its sections: nothing unless ``learned`` is a method;
    then its λs, the closed loop's step budget and revisit rule, and Random's settings (its
    held-out comparison)."""
    ev = config.evaluate
    if LEARNED not in ev.methods:
        return stable_hash({"learned": False})
    lambdas = learned_lambdas(config.solve.wrong_declaration_cost_m, ev.lambdas)
    return stable_hash({"learned": True, "lambdas": lambdas,
                        "max_moves": ev.max_moves, "revisit": ev.revisit,
                        "random": ev.random.model_dump(mode="json"),
                        "random_thresholds": list(ev.random_thresholds)})
