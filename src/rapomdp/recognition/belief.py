"""The multi-view belief of a recogniser's labels and its held-out temperature.

A belief over classes is updated by Bayes (Eq. 5) with an observation model P(o | c, x) (V, C, C)
at every view. Views of one object are correlated, so naive Bayes over them is overconfident;
the likelihood temperature t (P ** t, renormalised) that minimises the belief's log loss on
held-out random walks over viewpoints keeps it calibrated. Held out: the outcome rows form
groups; each group's walks are scored by the model fitted without it (leave-one-group-out).
Nothing here depends on how a model was fitted: the observe stage tempers every awareness model
with it (:func:`rapomdp.awareness.temperature.held_out_temperatures`), the vptree stage the
VP-tree's confusion. Also here: the reliability and ECE of a confidence, and the fit of the
declared confidence where held-out walks stop.

The rule itself (Eq. 5, :func:`~rapomdp.belief.temper`, the declared form b ** a) lives in
:mod:`rapomdp.belief`, which the planner, the closed loop and the environments call too; this
module fits its two temperatures.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from rapomdp.belief import accumulate_log_beliefs, declared_log_beliefs, safe_log, temper

TEMPERATURE_BOUNDS = (0.05, 2.0)
"""The interval the temperature is searched in."""
TEMPERATURE_WALK_LENGTH = 6
"""Views per held-out walk the temperature is fitted on (an active episode's few moves)."""
TEMPERATURE_WALKS_PER_ROW = 16
"""Walks started (at random viewpoints) per held-out outcome row."""
TEMPERATURE_NEIGHBOURS = 8
"""A walk moves to one of this many nearest viewpoints not yet visited."""


# -- the calibration of a confidence ---------------------------------------------------------

def reliability(confidence: np.ndarray, correct: np.ndarray, bins: int = 10
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Reliability diagram: per equal-width confidence bin, the mean confidence, the accuracy
    and the count (empty bins NaN, 0)."""
    confidence = np.clip(np.ravel(confidence).astype(np.float64), 0.0, 1.0)
    correct = np.ravel(correct).astype(np.float64)
    which = np.minimum((confidence * bins).astype(np.int64), bins - 1)
    count = np.bincount(which, minlength=bins).astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_conf = np.bincount(which, weights=confidence, minlength=bins) / count
        accuracy = np.bincount(which, weights=correct, minlength=bins) / count
    return mean_conf, accuracy, count


def expected_calibration_error(confidence: np.ndarray, correct: np.ndarray,
                               bins: int = 10) -> float:
    """ECE: the count-weighted mean |accuracy − confidence| over the reliability bins."""
    mean_conf, accuracy, count = reliability(confidence, correct, bins)
    used = count > 0
    return float(np.sum(count[used] * np.abs(accuracy[used] - mean_conf[used])) / count.sum())


CALIBRATED_ECE_DRAWS = 1000
"""Draws of :func:`calibrated_ece_draws` behind a reported sampling floor of the ECE."""
CALIBRATED_ECE_QUANTILE = 0.95
"""The quantile of those draws a report shows: an ECE below it is what sampling alone gives a
calibrated reporter of the same confidences on as many stops."""


def calibrated_ece_draws(confidence: np.ndarray, draws: int = CALIBRATED_ECE_DRAWS,
                         seed: int = 0, bins: int = 10) -> np.ndarray:
    """(draws,) the ECE (:func:`expected_calibration_error`, ``bins`` bins) of ``confidence``
    with each stop's outcome drawn as a coin of its own confidence: calibrated by construction,
    so what the ECE of these stops shows from sampling alone."""
    confidence = np.clip(np.ravel(confidence).astype(np.float64), 0.0, 1.0)
    if confidence.size == 0:
        raise ValueError("no confidences to draw outcomes for")
    which = np.minimum((confidence * bins).astype(np.int64), bins - 1)
    in_bin = np.zeros((confidence.size, bins))
    in_bin[np.arange(confidence.size), which] = 1.0
    expected = confidence @ in_bin  # per bin, the sum of confidences (= of a calibrated P(right))
    rng = np.random.default_rng(seed)
    out = np.empty(draws)
    chunk = max(1, 2_000_000 // confidence.size)  # about 16 MB of coins at a time
    for start in range(0, draws, chunk):
        stop = min(draws, start + chunk)
        right = (rng.random((stop - start, confidence.size)) < confidence).astype(np.float64)
        # count · |accuracy − mean confidence| of a bin is |Σ right − Σ confidence| there
        out[start:stop] = np.abs(right @ in_bin - expected).sum(axis=1) / confidence.size
    return out


def calibrated_ece(confidence: np.ndarray, quantile: float = CALIBRATED_ECE_QUANTILE,
                   seed: int = 0) -> float:
    """The ``quantile`` of :func:`calibrated_ece_draws`: an ECE up to it on these stops is not
    evidence of miscalibration."""
    return float(np.quantile(calibrated_ece_draws(confidence, seed=seed), quantile))


# -- the belief's temperature ----------------------------------------------------------------

def random_walks(directions: np.ndarray, starts: np.ndarray, length: int, neighbours: int,
                 rng: np.random.Generator) -> np.ndarray:
    """Viewpoint sequences (E, length): from each start, moves to a random one of the
    ``neighbours`` nearest viewpoints not yet visited (the shape of an active episode)."""
    d = np.asarray(directions, dtype=np.float64)
    angle = np.arccos(np.clip(d @ d.T, -1.0, 1.0))
    np.fill_diagonal(angle, np.inf)
    near = np.argsort(angle, axis=1)[:, :neighbours]  # (V, k)
    walks = np.empty((len(starts), length), dtype=np.int64)
    walks[:, 0] = starts
    visited = np.zeros((len(starts), d.shape[0]), dtype=bool)
    rows = np.arange(len(starts))
    visited[rows, starts] = True
    for t in range(1, length):
        candidates = near[walks[:, t - 1]]  # (E, k)
        fresh = ~visited[rows[:, None], candidates]
        keys = np.where(fresh, rng.random(candidates.shape), -1.0)
        pick = candidates[rows, keys.argmax(axis=1)]
        # a walk boxed in by visited neighbours stays where it is (no new evidence)
        stuck = ~fresh.any(axis=1)
        walks[:, t] = np.where(stuck, walks[:, t - 1], pick)
        visited[rows, walks[:, t]] = True
    return walks


def _log_likelihoods(temperature: float, models: Sequence[np.ndarray], row_model: np.ndarray,
                     predicted: np.ndarray) -> np.ndarray:
    """log P(observed label | c, x) (N, V, C) of every outcome row under its tempered model."""
    loglik = np.empty(predicted.shape + (models[0].shape[1],))  # (N, V, S)
    for m, p in enumerate(models):
        rows = np.flatnonzero(row_model == m)
        if rows.size == 0:
            continue
        log_p = safe_log(temper(p, temperature))  # (V, C, O)
        x = np.arange(p.shape[0])[None, :]
        loglik[rows] = log_p[x, :, predicted[rows]]  # (R, V, S)
    return loglik


def walk_log_beliefs(temperature: float, models: Sequence[np.ndarray], row_model: np.ndarray,
                     predicted: np.ndarray, walks: np.ndarray, walk_row: np.ndarray,
                     first_temperature: float | None = None) -> np.ndarray:
    """Log class beliefs (E, L, C) after every step of every walk, updated by Eq. 5 with the
    tempered models (row r of the outcomes uses ``models[row_model[r]]``) from a uniform prior;
    with ``first_temperature`` the first view is tempered by it instead (1: the single-view
    model, later views discounted alone). A viewpoint a walk stays on adds no evidence (the
    sensor would see the same image)."""
    loglik = _log_likelihoods(temperature, models, row_model, predicted)
    steps = loglik[walk_row[:, None], walks]  # (E, L, C)
    if first_temperature is not None:
        first = _log_likelihoods(first_temperature, models, row_model, predicted)
        steps[:, 0] = first[walk_row, walks[:, 0]]
    repeat = np.zeros(walks.shape, dtype=bool)
    repeat[:, 1:] = walks[:, 1:] == walks[:, :-1]
    steps = np.where(repeat[..., None], 0.0, steps)
    return accumulate_log_beliefs(steps)  # (E, L, C)


def belief_log_loss(temperature: float, models: Sequence[np.ndarray], row_model: np.ndarray,
                    labels: np.ndarray, predicted: np.ndarray, walks: np.ndarray,
                    walk_row: np.ndarray, first_temperature: float | None = None) -> float:
    """Mean −log belief in the true class after every step of every walk
    (:func:`walk_log_beliefs`)."""
    log_belief = walk_log_beliefs(temperature, models, row_model, predicted, walks, walk_row,
                                  first_temperature)
    return float(-np.mean(log_belief[np.arange(len(walks)), :, labels[walk_row]]))


def fit_temperature(models: Sequence[np.ndarray], row_model: np.ndarray, labels: np.ndarray,
                    predicted: np.ndarray, walks: np.ndarray, walk_row: np.ndarray,
                    bounds: tuple[float, float] = TEMPERATURE_BOUNDS,
                    first_temperature: float | None = None) -> float:
    """The temperature that minimises :func:`belief_log_loss` on held-out walks (bounded 1-D
    search). Evidence that is independent and drawn from the model gives ~1; evidence that
    repeats itself gives less. With ``first_temperature`` only the views after the first are
    tempered by the fit."""
    result = minimize_scalar(belief_log_loss, bounds=bounds, method="bounded",
                             args=(models, row_model, labels, predicted, walks, walk_row,
                                   first_temperature),
                             options={"xatol": 1e-3})
    return float(result.x)


# -- held out: the folds, their walks and the calibration of the beliefs on them -------------

def held_out_groups(labels: np.ndarray, groups: np.ndarray) -> list[np.ndarray]:
    """The rows (N,) bool of every group whose complement still covers every class: the groups
    leave-one-group-out holds out (a model fitted without one must know every class). Empty
    with one group only."""
    labels, groups = np.asarray(labels), np.asarray(groups)
    masks = []
    everything = set(labels.tolist())
    for g in np.unique(groups):
        held = groups == g
        if held.all() or set(labels[~held].tolist()) != everything:
            continue
        masks.append(held)
    return masks


def fold_of_rows(held: Sequence[np.ndarray], rows: int) -> np.ndarray:
    """Each row's fold (N,): the index of the mask in ``held`` that holds it out, −1 for none
    (``row_model`` of :func:`walk_log_beliefs`: row r is scored by the model of its fold)."""
    row_model = np.full(rows, -1, dtype=np.int64)
    for m, mask in enumerate(held):
        row_model[mask] = m
    return row_model


def held_out_walks(row_model: np.ndarray, directions: np.ndarray, rng: np.random.Generator,
                   length: int = TEMPERATURE_WALK_LENGTH,
                   starts_per_row: int = TEMPERATURE_WALKS_PER_ROW,
                   neighbours: int = TEMPERATURE_NEIGHBOURS) -> tuple[np.ndarray, np.ndarray]:
    """Random walks (E, length) over ``directions`` (V, 3), ``starts_per_row`` from random
    viewpoints per held-out row (``row_model`` >= 0), and each walk's row (E,)."""
    walk_row = np.repeat(np.flatnonzero(row_model >= 0), starts_per_row)
    starts = rng.integers(0, len(directions), size=walk_row.size)
    return random_walks(directions, starts, length, neighbours, rng), walk_row


def walk_calibration(temperature: float, models: Sequence[np.ndarray], row_model: np.ndarray,
                     labels: np.ndarray, predicted: np.ndarray, walks: np.ndarray,
                     walk_row: np.ndarray, first_temperature: float | None = None
                     ) -> dict[str, float]:
    """The calibration of the held-out beliefs on ``walks`` naive (t = 1) and at
    ``temperature``: each one's log loss (``log_loss_{naive,tempered}``) and, after the first
    and the last step, the ECE and mean of the max belief against a right argmax
    (``ece_{first,last}_*``, ``belief_{first,last}_*``; ``accuracy_{first,last}``: the
    tempered belief's, whose argmax renormalising P ** t can move)."""
    true = labels[walk_row]
    report: dict[str, float] = {"temperature": temperature}
    for label, value in (("naive", 1.0), ("tempered", temperature)):
        report[f"log_loss_{label}"] = belief_log_loss(
            value, models, row_model, labels, predicted, walks, walk_row, first_temperature)
        belief = np.exp(walk_log_beliefs(value, models, row_model, predicted, walks, walk_row,
                                         first_temperature))
        for step, at in (("first", 0), ("last", walks.shape[1] - 1)):
            confidence = belief[:, at].max(axis=1)
            right = belief[:, at].argmax(axis=1) == true
            report[f"ece_{step}_{label}"] = expected_calibration_error(confidence, right)
            report[f"belief_{step}_{label}"] = float(confidence.mean())
            report[f"accuracy_{step}"] = float(right.mean())
    return report


# -- the declared confidence: calibrated where episodes stop ---------------------------------

DECLARED_STOP_THRESHOLDS = (0.5, 0.7, 0.8, 0.9, 0.95, 0.99)
"""The max beliefs at which held-out walks are stopped to fit the declared confidence: a range
of stopping rules, since a POMDP declares at beliefs its λ decides."""
DECLARED_WALK_LENGTH = 11
"""Views per held-out walk the declared confidence is fitted on (Random's default budget of 10
moves after the first view)."""


def stop_steps(log_beliefs: np.ndarray, threshold: float) -> np.ndarray:
    """(E,) each walk's stop: the first step whose max belief reaches ``threshold``, else the
    last (``log_beliefs`` (E, L, C))."""
    reached = np.exp(np.asarray(log_beliefs)).max(axis=2) >= threshold
    reached[:, -1] = True
    return reached.argmax(axis=1)


def stopped_log_beliefs(log_beliefs: np.ndarray,
                        thresholds: Sequence[float] = DECLARED_STOP_THRESHOLDS
                        ) -> tuple[np.ndarray, np.ndarray]:
    """The log beliefs (E·T, C) where the walks (E, L, C) stop under each threshold (T of
    them, threshold-major) and each stop's walk (E·T,)."""
    walks = np.arange(log_beliefs.shape[0])
    finals = [log_beliefs[walks, stop_steps(log_beliefs, t)] for t in thresholds]
    return np.concatenate(finals), np.tile(walks, len(thresholds))


DECLARED_CRITERIA = ("log_loss", "confidence")
"""What the declared temperature minimises over the stops: ``log_loss``, the mean −log of the
declared belief in the true class; ``confidence``, the binary cross-entropy of the declared
confidence (the declared belief's maximum) against whether its argmax is the true class."""
DECLARED_CRITERION = "confidence"
"""The criterion the stages fit with: chosen on held-out walks, the second round of
``benchmarks/results/declared_confidence_rule_v2.md`` (lower held-out ECE than ``log_loss``
for RA's and the Classifier's model on both development sets)."""


def _declared_losses(temperature: float | np.ndarray, log_beliefs: np.ndarray,
                     true: np.ndarray, criterion: str) -> np.ndarray:
    """Each stop's ``criterion`` (:data:`DECLARED_CRITERIA`) of its declared belief."""
    declared = declared_log_beliefs(log_beliefs, temperature)
    if criterion == "log_loss":
        return -declared[np.arange(len(true)), true]
    right = declared.argmax(axis=1) == true
    log_confidence = np.minimum(declared.max(axis=1), -1e-12)
    log_doubt = np.log(-np.expm1(log_confidence))  # log(1 − confidence), exact near 1
    return -np.where(right, log_confidence, log_doubt)


def _declared_loss(temperature: float | np.ndarray, log_beliefs: np.ndarray, true: np.ndarray,
                   criterion: str) -> float:
    return float(_declared_losses(temperature, log_beliefs, true, criterion).mean())


def fit_declared_temperature(log_beliefs: np.ndarray, true: np.ndarray,
                             bounds: tuple[float, float] = TEMPERATURE_BOUNDS,
                             criterion: str = DECLARED_CRITERION) -> float:
    """The temperature a that minimises ``criterion`` (:data:`DECLARED_CRITERIA`) of the
    declared beliefs b' ∝ b ** a over stopped beliefs ``log_beliefs`` (M, C) of true classes
    ``true`` (M,) (bounded 1-D search)."""
    if criterion not in DECLARED_CRITERIA:
        raise ValueError(f"criterion must be one of {', '.join(DECLARED_CRITERIA)}, got "
                         f"{criterion!r}")
    if len(true) == 0:
        raise ValueError("no stopped beliefs to fit the declared confidence on")
    result = minimize_scalar(_declared_loss, bounds=bounds, method="bounded",
                             args=(np.asarray(log_beliefs, dtype=np.float64),
                                   np.asarray(true), criterion), options={"xatol": 1e-3})
    return float(result.x)


@dataclass(frozen=True)
class DeclaredConfidence:
    """The declared-confidence temperature of one model and what held out says of it:
    ``temperature`` fitted on every group's stops (every threshold pooled) by ``criterion``;
    per group (``groups``), the one fitted on the other groups' (``held_out_temperatures``);
    pooled over the groups' stops, the accuracy, the mean confidence and ECE of the belief
    (``confidence``, ``ece``) and of the declared belief each group gets from the others' fit
    (``declared_confidence``, ``declared_ece``). Per threshold (``thresholds``): the a fitted on
    that threshold's stops alone (``threshold_temperatures``) and, held out, the ECE at those
    stops of the belief, of the pooled fit and of the threshold's own fit (``threshold_ece``,
    ``threshold_declared_ece``, ``threshold_own_ece``). NaN where there are not two groups.
    ``declared_ece_if_calibrated``: what ``declared_ece`` would be from sampling alone."""

    temperature: float
    criterion: str
    groups: tuple[int, ...]
    held_out_temperatures: tuple[float, ...]
    stops: int
    accuracy: float
    confidence: float
    ece: float
    declared_confidence: float
    declared_ece: float
    thresholds: tuple[float, ...] = ()
    threshold_temperatures: tuple[float, ...] = ()
    threshold_ece: tuple[float, ...] = ()
    threshold_declared_ece: tuple[float, ...] = ()
    threshold_own_ece: tuple[float, ...] = ()
    #: The ECE a calibrated reporter of the held-out declared confidences shows on as many
    #: stops from sampling alone, 95th percentile (:func:`calibrated_ece`); NaN as above.
    declared_ece_if_calibrated: float = float("nan")

    def to_dict(self) -> dict[str, object]:
        return {name: (list(value) if isinstance(value, tuple) else value)
                for name, value in self.__dict__.items()}


def declared_confidence(log_beliefs: np.ndarray, true: np.ndarray, groups: np.ndarray,
                        thresholds: Sequence[float] = DECLARED_STOP_THRESHOLDS,
                        criterion: str = DECLARED_CRITERION) -> DeclaredConfidence:
    """Fit the declared confidence on held-out walks' log beliefs (E, L, C) of true classes
    ``true`` (E,), each walk of group ``groups`` (E,), stopped at every threshold (pooled, and
    each threshold alone); and score it leave-one-group-out (each group's stops by the
    temperature the other groups' give)."""
    final, walk = stopped_log_beliefs(log_beliefs, thresholds)
    at = np.repeat(np.arange(len(thresholds)), len(true))  # each stop's threshold
    return _declared_at_stops(final, np.asarray(true)[walk], np.asarray(groups)[walk], at,
                              thresholds, criterion)


def stops_declared_confidence(log_beliefs: np.ndarray, true: np.ndarray, groups: np.ndarray,
                              criterion: str = DECLARED_CRITERION) -> DeclaredConfidence:
    """The declared confidence fitted on stops a policy made itself, scored held out.

    As :func:`declared_confidence` does for walks, but with no thresholds: the policy's own
    stop rule made the stops. Each group's stops are scored by the a the other groups' fit.

    Args:
        log_beliefs: (M, C) log class beliefs where the policy's held-out episodes declared.
        true: (M,) each episode's true class.
        groups: (M,) each episode's held-out volume group.
        criterion: what the fit minimises (:data:`DECLARED_CRITERIA`).

    Returns:
        The fit and its held-out scores.
    """
    log_beliefs = np.asarray(log_beliefs, dtype=np.float64)
    return _declared_at_stops(log_beliefs, np.asarray(true), np.asarray(groups),
                              np.zeros(len(log_beliefs), dtype=np.int64), (), criterion)


def _declared_at_stops(final: np.ndarray, labels: np.ndarray, stop_group: np.ndarray,
                       at: np.ndarray, thresholds: Sequence[float], criterion: str
                       ) -> DeclaredConfidence:
    """:func:`declared_confidence` on stopped log beliefs ``final`` (S, C) of true classes
    ``labels``, groups ``stop_group`` and thresholds' indices ``at`` (S,) each."""
    right = final.argmax(axis=1) == labels
    confidence = np.exp(final.max(axis=1))
    names = tuple(int(g) for g in np.unique(stop_group))

    def fit(rows: np.ndarray) -> float:
        return fit_declared_temperature(final[rows], labels[rows], criterion=criterion)

    def declare(rows: np.ndarray, a: float) -> np.ndarray:
        return np.exp(declared_log_beliefs(final[rows], a).max(axis=1))

    fitted = fit(np.ones(len(labels), dtype=bool))
    own = tuple(fit(at == k) for k in range(len(thresholds)))
    held: list[float] = []
    declared = np.full(len(labels), np.nan)
    declared_own = np.full(len(labels), np.nan)
    if len(names) >= 2:
        for g in names:
            mine = stop_group == g
            a = fit(~mine)
            held.append(a)
            declared[mine] = declare(mine, a)
            for k in range(len(thresholds)):
                rows = mine & (at == k)
                declared_own[rows] = declare(rows, fit(~mine & (at == k)))
    ok = len(held) > 0
    nan = float("nan")

    def ece(values: np.ndarray, rows: np.ndarray | None = None) -> float:
        rows = np.ones(len(labels), dtype=bool) if rows is None else rows
        return expected_calibration_error(values[rows], right[rows]) if ok else nan

    per_threshold = [at == k for k in range(len(thresholds))]
    return DeclaredConfidence(
        fitted, criterion, names if ok else (), tuple(held),
        int(len(labels)), float(right.mean()), float(confidence.mean()),
        expected_calibration_error(confidence, right),
        float(declared.mean()) if ok else nan, ece(declared),
        tuple(float(t) for t in thresholds), own,
        tuple(expected_calibration_error(confidence[r], right[r]) for r in per_threshold),
        tuple(ece(declared, r) for r in per_threshold),
        tuple(ece(declared_own, r) for r in per_threshold),
        declared_ece_if_calibrated=calibrated_ece(declared) if ok else nan)
