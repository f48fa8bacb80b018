"""The methods compared in the paper's Table 1 (Sec. 5.2), each a :class:`Policy`.

- :class:`StaticPolicy`: one view, the recogniser's most likely class.
- :class:`RandomWalkPolicy`: a random walk over the nearest reachable viewpoints, never
  revisiting one; stops when its belief is confident enough or its move budget is spent.
- :class:`POMDPPolicy`: a solved active-recognition policy with its observation model (the
  Classifier, RA-POMDP and VP-tree methods differ only in the recogniser and the model).

A user's own method is any object with the same five members (``name``, ``recogniser``,
``reset``, ``observe``, ``belief``, ``act``); see :class:`rapomdp.experiment.episode.Policy`.
Every belief here is :class:`rapomdp.belief.BayesBelief` (Eq. 5 and the declared confidence) or,
for Static, the output tempered by :func:`rapomdp.belief.temper`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rapomdp.belief import BayesBelief, temper
from rapomdp.config import EvaluateConfig
from rapomdp.geometry.viewsphere import k_nearest
from rapomdp.planning.policy import ActiveRecognitionPolicy, ARAction


class StaticPolicy:
    """Passive recognition: classify the start view and declare; the belief is the recogniser's
    output itself (a passive classifier has no other), temperature-scaled by
    ``softmax_temperature`` (fitted on held-out objects by the observe stage; 1: as output).
    The declared class, the output's argmax, does not depend on it."""

    def __init__(self, name: str = "Static", recogniser: str = "cnn",
                 softmax_temperature: float = 1.0) -> None:
        if not softmax_temperature > 0:
            raise ValueError(f"softmax_temperature must be positive, got {softmax_temperature}")
        self.name, self.recogniser = name, recogniser
        self.softmax_temperature = float(softmax_temperature)
        self._belief = np.empty(0)

    def reset(self, start_viewpoint: int, rng: np.random.Generator) -> None:
        self._belief = np.empty(0)

    def observe(self, viewpoint: int, output: np.ndarray) -> None:
        output = np.asarray(output, dtype=np.float64)[None, None]  # (1, 1, C)
        self._belief = temper(output, 1.0 / self.softmax_temperature)[0, 0]

    @property
    def belief(self) -> np.ndarray:
        return self._belief

    def act(self, viewpoint: int) -> ARAction:
        return ARAction("declare", int(np.argmax(self._belief)))


class RandomWalkPolicy:
    """A random walk among the ``neighbours`` nearest reachable viewpoints, never revisiting one.

    The belief is updated with ``observation_model`` (Eq. 5). Stop rule: declare the most likely
    class once the belief's maximum reaches ``belief_threshold``, after ``max_moves`` moves, or
    when every neighbour has been visited. What it reports (``belief``) is that belief raised
    to ``declared_temperature`` and renormalised; it stops and declares by the belief itself.
    """

    def __init__(self, observation_model: np.ndarray, distance_m: np.ndarray,
                 reachable: np.ndarray, neighbours: int = 8, belief_threshold: float = 0.9,
                 max_moves: int = 10, name: str = "Random", recogniser: str = "cnn",
                 declared_temperature: float = 1.0) -> None:
        if not 0.0 < belief_threshold <= 1.0:
            raise ValueError(f"belief_threshold must be in (0, 1], got {belief_threshold}")
        if max_moves < 0:
            raise ValueError(f"max_moves must be non-negative, got {max_moves}")
        self.name, self.recogniser = name, recogniser
        self.neighbours = k_nearest(distance_m, neighbours, allowed=reachable)
        self.belief_threshold, self.max_moves = float(belief_threshold), int(max_moves)
        self._bayes = BayesBelief(observation_model, declared_temperature)
        self._visited: set[int] = set()
        self._rng = np.random.default_rng()

    def reset(self, start_viewpoint: int, rng: np.random.Generator) -> None:
        self._bayes.reset()
        self._visited = set()
        self._rng = rng

    def observe(self, viewpoint: int, output: np.ndarray) -> None:
        self._visited.add(viewpoint)
        self._bayes.update(viewpoint, output)

    @property
    def belief(self) -> np.ndarray:
        return self._bayes.declared

    def act(self, viewpoint: int) -> ARAction:
        belief = self._bayes.belief
        declare = ARAction("declare", int(np.argmax(belief)))
        if belief.max() >= self.belief_threshold or len(self._visited) > self.max_moves:
            return declare
        candidates = [int(j) for j in self.neighbours[viewpoint]
                      if j >= 0 and int(j) not in self._visited]
        if not candidates:
            return declare
        return ARAction("move", candidates[int(self._rng.integers(len(candidates)))])


class POMDPPolicy:
    """A solved active-recognition policy acting on the belief of its own observation model.

    With ``revisit`` False (the default) it never moves back to a viewpoint it has seen: the
    POMDP treats images from one viewpoint as independent draws, but a noiseless sensor sees
    the same image again, which would count one piece of evidence twice. It acts by a one-step
    lookahead on the policy's value over the viewpoints ``lookahead_over`` (V,) bool (default:
    every one; :meth:`ActiveRecognitionPolicy.lookahead_act`). It reports its belief raised to
    ``declared_temperature`` and renormalised and acts on the belief itself.
    """

    def __init__(self, policy: ActiveRecognitionPolicy, observation_model: np.ndarray,
                 name: str, recogniser: str = "cnn", revisit: bool = False,
                 lookahead_over: np.ndarray | None = None,
                 declared_temperature: float = 1.0) -> None:
        if observation_model.shape[0] != policy.n_viewpoints or \
                observation_model.shape[1] != policy.n_states or \
                observation_model.shape[2] != policy.n_classes:
            raise ValueError(
                f"{name}: the policy covers {policy.n_viewpoints} viewpoints, "
                f"{policy.n_states} hidden states and {policy.n_classes} classes, the "
                f"observation model {observation_model.shape}")
        self.name, self.recogniser, self.revisit = name, recogniser, revisit
        self.policy = policy
        self.observation_model = observation_model
        self.lookahead_over = (np.ones(policy.n_viewpoints, dtype=bool) if lookahead_over is None
                               else np.asarray(lookahead_over, dtype=bool))
        self._bayes = BayesBelief(observation_model, declared_temperature)
        self._visited = np.zeros(policy.n_viewpoints, dtype=bool)

    @classmethod
    def configured(cls, cfg: EvaluateConfig, policy: ActiveRecognitionPolicy,
                   observation_model: np.ndarray, name: str, reachable: np.ndarray,
                   recogniser: str = "cnn", **belief: Any) -> POMDPPolicy:
        """The method as the evaluate stage configures it (``cfg``: its revisit rule; the
        lookahead over the ``reachable`` viewpoints); ``belief``: the belief's keyword
        arguments (``declared_temperature``)."""
        return cls(policy, observation_model, name, recogniser, cfg.revisit,
                   lookahead_over=reachable, **belief)

    def reset(self, start_viewpoint: int, rng: np.random.Generator) -> None:
        self._bayes.reset()
        self._visited[:] = False

    def observe(self, viewpoint: int, output: np.ndarray) -> None:
        self._visited[viewpoint] = True
        self._bayes.update(viewpoint, output)

    @property
    def belief(self) -> np.ndarray:
        return self._bayes.declared

    def act(self, viewpoint: int) -> ARAction:
        forbidden = None if self.revisit else self._visited
        # the children of the next view as the belief will update, valued by the policy
        return self.policy.lookahead_act(viewpoint, self._bayes.state, self.observation_model,
                                         self.lookahead_over, forbidden)
