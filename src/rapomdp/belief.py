"""The class belief's rule, written once: its update, its temperature, what it declares.

Every caller of a belief uses these: the planners and simulators of :mod:`rapomdp.planning`,
the closed loop's methods and the gymnasium environments (:class:`BayesBelief`), the held-out
walks that fit the temperatures (:mod:`rapomdp.recognition.belief`), the held-out closed loop
and the headroom study. It sits beneath every stage package (NumPy and SciPy only), so the
planning package, which stands alone, and the recognition package, which comes before it,
import the same functions.

- **Update** (Eq. 5): b'(s) ∝ P(o | s, x) b(s) after label o at viewpoint x
  (:func:`update_beliefs`); over many views at once in log space from a uniform prior
  (:func:`accumulate_log_beliefs`).
- **Temperature**: P ** t renormalised over the labels (:func:`temper`), t < 1 when correlated
  views count less than independent ones; fitted by :mod:`rapomdp.recognition.belief`.
- **Declared confidence**: the class belief raised to a and renormalised
  (:func:`declared_belief`, :func:`declared_log_beliefs`): what a policy reports; it acts on
  the belief itself.

The hidden state is the class, or, with T instance types, the pair (type τ, class c) at index
τ·C + c (type-major); a class belief is its marginal (:func:`class_marginal`).
"""

from __future__ import annotations

import numpy as np
from scipy.special import logsumexp

PROBABILITY_FLOOR = 1e-300
"""A probability read as this where its logarithm is taken (log 0 would be −inf)."""


def safe_log(probabilities: np.ndarray) -> np.ndarray:
    """log p with p below :data:`PROBABILITY_FLOOR` read as the floor.

    Args:
        probabilities: probabilities of any shape.

    Returns:
        Their logarithms (float64), of the same shape, finite.
    """
    return np.log(np.maximum(probabilities, PROBABILITY_FLOOR))


def class_marginal(belief: np.ndarray, n_classes: int | None = None) -> np.ndarray:
    """The class distribution of a belief over states, state τ·C + c: the sum over types.

    Args:
        belief: (..., T·C) beliefs over the hidden states.
        n_classes: C; None, or as many states as classes: the belief itself.

    Returns:
        (..., C) the class beliefs.

    Raises:
        ValueError: the states are no whole number of types of ``n_classes`` classes.
    """
    b = np.asarray(belief)
    if n_classes is None or b.shape[-1] == n_classes:
        return b
    if b.shape[-1] % n_classes:
        raise ValueError(f"a belief over {b.shape[-1]} states is no whole number of types of "
                         f"{n_classes} classes")
    return b.reshape(*b.shape[:-1], b.shape[-1] // n_classes, n_classes).sum(axis=-2)


def update_beliefs(
    observation_model: np.ndarray,
    beliefs: np.ndarray,
    viewpoints: np.ndarray | int,
    labels: np.ndarray | int,
) -> np.ndarray:
    """Vectorised Eq. 5 over a batch: the one belief update of the closed loop and planners.

    Args:
        observation_model: (V, S, O) = P(label o | hidden state s, viewpoint v).
        beliefs: (..., S) beliefs over the hidden states (the classes, or (type, class)
            pairs), each summing to 1.
        viewpoints: The viewpoint of each image (broadcast against ``beliefs[..., 0]``).
        labels: The predicted label of each image (broadcast alike).

    Returns:
        (..., S) the posteriors b'(s) ∝ P[v, s, o] b(s).

    Raises:
        ValueError: An observation has probability 0 under its belief.

    Example:
        >>> import numpy as np
        >>> P = np.array([[[0.9, 0.1], [0.2, 0.8]]])
        >>> update_beliefs(P, np.array([0.5, 0.5]), 0, 1).round(4).tolist()
        [0.1111, 0.8889]
    """
    like = observation_model[viewpoints, :, labels]  # (..., C)
    post = beliefs * like
    total = post.sum(axis=-1, keepdims=True)
    if np.any(total <= 0):
        raise ValueError("an observation has probability 0 under the belief")
    return post / total


def accumulate_log_beliefs(log_likelihoods: np.ndarray) -> np.ndarray:
    """Eq. 5 in log space from a uniform prior, after every step of every sequence of views.

    Args:
        log_likelihoods: (..., L, C) log P(observed label | c, x) of each step (0 for a step
            that adds no evidence).

    Returns:
        (..., L, C) the log class beliefs after steps 1..L, each normalised over C.

    Example:
        >>> import numpy as np
        >>> steps = np.log(np.array([[[0.9, 0.2], [0.9, 0.2]]]))  # two views, label 0 twice
        >>> np.exp(accumulate_log_beliefs(steps)).round(4).tolist()
        [[[0.8182, 0.1818], [0.9529, 0.0471]]]
    """
    cumulative = np.cumsum(log_likelihoods, axis=-2)  # (..., L, C)
    cumulative -= cumulative.max(axis=-1, keepdims=True)
    return cumulative - np.log(np.exp(cumulative).sum(axis=-1, keepdims=True))


def temper(probabilities: np.ndarray, temperature: float | np.ndarray) -> np.ndarray:
    """P(o | c, x) ** t, renormalised over o: evidence that counts ``t`` times a naive update's.

    t < 1: correlated views count less. t = 1 returns (a copy of) the model. The Static
    method's softmax temperature T is this with t = 1 / T on its outputs (1, 1, C).

    Args:
        probabilities: (V, C, O) an observation model, rows over o summing to 1.
        temperature: t > 0, or (V,) one per viewpoint's rows.

    Returns:
        (V, C, O) the tempered model.

    Example:
        >>> import numpy as np
        >>> temper(np.array([[[0.9, 0.1]]]), 0.5).round(4).tolist()
        [[[0.75, 0.25]]]
    """
    p = np.asarray(probabilities, dtype=np.float64)
    t = np.asarray(temperature, dtype=np.float64)
    if t.ndim == 0 and float(t) == 1.0:
        return p.copy()
    if t.ndim:
        t = t.reshape(-1, *([1] * (p.ndim - 1)))
    log_p = t * safe_log(p)
    log_p -= log_p.max(axis=2, keepdims=True)
    out = np.exp(log_p)
    return out / out.sum(axis=2, keepdims=True)


def declared_log_beliefs(log_beliefs: np.ndarray, temperature: float | np.ndarray
                         ) -> np.ndarray:
    """log b' with b' ∝ b ** a over the last axis: the declared confidence's form.

    The argmax is b's (a temperature > 0 keeps the order of the classes).

    Args:
        log_beliefs: (..., C) log class beliefs.
        temperature: a > 0, or (...,) one per belief.

    Returns:
        (..., C) the declared log beliefs.
    """
    t = np.asarray(temperature, dtype=np.float64)
    scaled = (t[..., None] if t.ndim else t) * np.asarray(log_beliefs, dtype=np.float64)
    return scaled - logsumexp(scaled, axis=-1, keepdims=True)


def declared_belief(belief: np.ndarray, temperature: float) -> np.ndarray:
    """The belief reported for a class belief after its views: b ** a renormalised.

    The policy acts on the belief; only what it reports is calibrated
    (:func:`rapomdp.recognition.belief.fit_declared_temperature`). The argmax stays the
    belief's.

    Args:
        belief: a class belief (C,), or beliefs (..., C), each summing to 1.
        temperature: the declared-confidence temperature a > 0 (1: the belief itself).

    Returns:
        The declared beliefs, of ``belief``'s shape.

    Example:
        >>> import numpy as np
        >>> declared_belief(np.array([0.8, 0.2]), 0.5).round(3).tolist()
        [0.667, 0.333]
    """
    b = np.asarray(belief, dtype=np.float64)
    if temperature == 1.0:
        return b
    return np.exp(declared_log_beliefs(safe_log(b), temperature))


class BayesBelief:
    """The closed loop's belief: Eq. 5 with the observation model the planner plans with.

    The recogniser's most likely class is the observation. ``state`` is the distribution over
    the hidden states from a uniform prior, ``belief`` its class marginal; every update uses
    P (:func:`update_beliefs`). ``declared`` is what a policy reports: the class belief raised
    to ``declared_temperature`` and renormalised (:func:`declared_belief`); the policy acts on
    ``belief`` and ``state``, which it leaves alone. The methods, the learned policy and the
    recorded environment all hold one.

    Args:
        observation_model: (V, S, C) P(label | hidden state, viewpoint).
        declared_temperature: a > 0 of the declared confidence (1: the belief itself).

    Raises:
        ValueError: ``declared_temperature`` is not positive.

    Example:
        >>> import numpy as np
        >>> bayes = BayesBelief(np.array([[[0.9, 0.1], [0.2, 0.8]]]), declared_temperature=0.5)
        >>> bayes.update(0, np.array([0.3, 0.7]))  # the recogniser says class 1
        >>> bayes.belief.round(4).tolist(), bayes.declared.round(4).tolist()
        ([0.1111, 0.8889], [0.2612, 0.7388])
    """

    def __init__(self, observation_model: np.ndarray,
                 declared_temperature: float = 1.0) -> None:
        if not declared_temperature > 0:
            raise ValueError(f"the declared-confidence temperature must be positive, got "
                             f"{declared_temperature}")
        self.declared_temperature = float(declared_temperature)
        self.observation_model = np.asarray(observation_model, dtype=np.float64)
        n_s = self.observation_model.shape[1]
        self.prior = np.full(n_s, 1.0 / n_s)
        self.state = self.prior.copy()
        self.updates = 0

    @property
    def n_classes(self) -> int:
        """C: the labels observed (the observation model's last axis)."""
        return int(self.observation_model.shape[2])

    @property
    def belief(self) -> np.ndarray:
        """The class distribution (C,): the state distribution summed over instance types."""
        return class_marginal(self.state, self.n_classes)

    @property
    def declared(self) -> np.ndarray:
        """The class belief as reported (C,): ``belief`` ** ``declared_temperature``,
        renormalised (the same argmax)."""
        return declared_belief(self.belief, self.declared_temperature)

    def reset(self) -> None:
        """Back to the uniform prior."""
        self.state = self.prior.copy()
        self.updates = 0

    def update(self, viewpoint: int, output: np.ndarray) -> None:
        """Eq. 5 with the recogniser's most likely class at ``viewpoint``.

        Args:
            viewpoint: the viewpoint of the image.
            output: (C,) the recogniser's output (its argmax is the label).
        """
        label = int(np.argmax(output))
        self.state = update_beliefs(self.observation_model, self.state, viewpoint, label)
        self.updates += 1
