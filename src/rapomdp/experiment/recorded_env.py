"""An active-recognition environment over recorded evidence: fast enough to train a policy on.

The rendering environment (:mod:`rapomdp.experiment.env`) renders and classifies at every step
(milliseconds). Here the classifier's output at every test viewpoint of every *held-out* model
(:class:`RecordedEvidence`: the volume models under the trained classifier) is computed once,
so a step is a lookup plus the belief update of the closed loop
(:class:`~rapomdp.belief.BayesBelief`, Eq. 5 with the method's observation model)
and the move of the closed loop (:meth:`~rapomdp.experiment.episode.Motion.move`).

The agent sees what the POMDP methods see: its belief, its viewpoint and the viewpoints it has
visited (:func:`policy_input`). Actions, rewards and the valid actions are those of the
evaluation's closed loop (:func:`valid_actions`): ``j < V`` moves to viewpoint ``j``
(``-E_M[v, j]``), ``V + k`` declares class ``k`` (0 if right, ``-lambda`` if wrong; the episode
ends); with ``revisit`` False (``evaluate.revisit``) a visited viewpoint is not a move; once
``max_moves`` steps were spent (``evaluate.max_moves``), only declarations are (the closed loop
makes the method declare then). An action outside the mask is a no-op with
``-invalid_penalty`` that spends a step; one taken when the budget is spent truncates the
episode, so a loop of ``action_space.sample()`` always ends.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from rapomdp.belief import BayesBelief
from rapomdp.experiment.episode import Motion
from rapomdp.io import ArtefactError, load_npz, save_npz

#: The file of the recorded evidence in the learn stage's folder.
RECORDED_FILE = "recorded_evidence.npz"
FORMAT = "rapomdp.recorded-evidence.v1"


def episode_options(options: dict[str, Any] | None) -> dict[str, Any]:
    """``reset``'s options of both environments, checked: ``model`` and ``start`` only."""
    options = dict(options or {})
    unknown = set(options) - {"model", "start"}
    if unknown:
        raise ValueError(f"reset: unknown option(s) {sorted(unknown)}; options are "
                         f"'model' and 'start'")
    return options


@dataclass(frozen=True)
class RecordedEvidence:
    """The recogniser's output (M, V, C) at every test viewpoint of M held-out models, their
    ``keys`` (M,) ``"class/id"``, true ``labels`` (M,) and ``sources`` (M,): ``"volume"`` (the
    trained classifier's output)."""

    keys: np.ndarray
    labels: np.ndarray
    outputs: np.ndarray
    sources: np.ndarray

    def __post_init__(self) -> None:
        m = len(self.keys)
        if self.outputs.ndim != 3 or self.outputs.shape[0] != m:
            raise ValueError(f"recorded outputs {self.outputs.shape} must be (models={m}, V, C)")
        if self.labels.shape != (m,) or self.sources.shape != (m,):
            raise ValueError(f"{m} models but labels {self.labels.shape}, sources "
                             f"{self.sources.shape}")
        classes = self.outputs.shape[2]
        if m and not (0 <= self.labels.min() and self.labels.max() < classes):
            raise ValueError(f"labels must be class indices in [0, {classes})")

    @property
    def models(self) -> int:
        return int(len(self.keys))

    @property
    def viewpoints(self) -> int:
        return int(self.outputs.shape[1])

    @property
    def classes(self) -> int:
        return int(self.outputs.shape[2])

    @classmethod
    def concatenate(cls, parts: Sequence[RecordedEvidence]) -> RecordedEvidence:
        return cls(np.concatenate([p.keys for p in parts]),
                   np.concatenate([p.labels for p in parts]),
                   np.concatenate([p.outputs for p in parts]),
                   np.concatenate([p.sources for p in parts]))

    def save(self, path: str | Path) -> None:
        save_npz(Path(path), compressed=True, format=np.array(FORMAT),
                 keys=self.keys.astype(str), labels=self.labels.astype(np.int64),
                 outputs=self.outputs.astype(np.float32), sources=self.sources.astype(str))

    @classmethod
    def load(cls, path: str | Path) -> RecordedEvidence:
        data = load_npz(Path(path))
        if str(data.get("format", "")) != FORMAT:
            raise ArtefactError(f"{path}: not recorded evidence (format "
                                f"{str(data.get('format', ''))!r}, expected {FORMAT!r})")
        try:
            return cls(data["keys"], data["labels"], data["outputs"], data["sources"])
        except (KeyError, ValueError) as exc:
            raise ArtefactError(f"{path}: {exc}") from None


def policy_input(belief: np.ndarray, viewpoint: int, visited: np.ndarray) -> np.ndarray:
    """What a learned policy sees, as the POMDP methods do: the belief (C,), the viewpoint
    one-hot (V,) and the visited viewpoints (V,), concatenated (C + 2V,) float32 in [0, 1]."""
    views = visited.size
    out = np.zeros(belief.size + 2 * views, dtype=np.float32)
    out[: belief.size] = belief
    out[belief.size + int(viewpoint)] = 1.0
    out[belief.size + views:] = visited
    return out


def valid_actions(reachable: np.ndarray, viewpoint: int, visited: np.ndarray, steps: int,
                  max_moves: int, revisit: bool, classes: int) -> np.ndarray:
    """(V + C,) bool: the actions of the closed loop a method may take: a move to a reachable
    viewpoint other than the current one (and not visited, unless ``revisit``) while fewer than
    ``max_moves`` steps were spent, and every declaration."""
    mask = np.ones(reachable.size + classes, dtype=bool)
    if steps >= max_moves:
        mask[: reachable.size] = False
        return mask
    moves = mask[: reachable.size]
    moves[:] = reachable if revisit else reachable & ~visited
    moves[int(viewpoint)] = False
    return mask


class RecordedRecognitionEnv(gymnasium.Env):
    """Active recognition of a held-out model per episode, over its recorded evidence.

    Observations: :func:`policy_input` (Box in [0, 1], C + 2V). Actions: ``Discrete(V + C)``
    as in :class:`~rapomdp.experiment.env.ActiveRecognitionEnv`. ``reset`` takes
    ``options={"model": i, "start": v}`` (each drawn from the env's RNG otherwise). The belief
    is :class:`~rapomdp.belief.BayesBelief` of ``observation_model`` (V, C, C), as
    the evaluation builds it for a method of that model
    (:func:`~rapomdp.experiment.learn_stage.belief_models`).
    :meth:`action_masks` is what sb3-contrib's ``MaskablePPO`` reads. The final ``info`` holds
    ``correct``, ``true_class``, ``model``, ``moves`` and ``energy`` (the scorer's view).
    """

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(self, evidence: RecordedEvidence, observation_model: np.ndarray,
                 motion: Motion, lambda_: float, max_moves: int, revisit: bool = False,
                 invalid_penalty: float | None = None, seed: int | None = None) -> None:
        if evidence.models == 0:
            raise ValueError("RecordedRecognitionEnv needs at least one recorded model")
        model = np.asarray(observation_model, dtype=np.float64)
        if model.ndim != 3 or (model.shape[0], model.shape[2]) != (evidence.viewpoints,
                                                                   evidence.classes):
            raise ValueError(f"the observation model is {model.shape}, the recorded evidence "
                             f"needs ({evidence.viewpoints}, states, {evidence.classes}) "
                             "(V, S, C)")
        if motion.viewpoints != evidence.viewpoints:
            raise ValueError(f"the motion covers {motion.viewpoints} viewpoints, the recorded "
                             f"evidence {evidence.viewpoints}")
        if not np.any(motion.reachable):
            raise ValueError("motion: no viewpoint is reachable")
        if not lambda_ > 0:
            raise ValueError(f"lambda_ (cost of a wrong declaration) must be positive, got "
                             f"{lambda_}")
        if int(max_moves) < 0:
            raise ValueError(f"max_moves must be non-negative, got {max_moves}")
        self.evidence = evidence
        self.motion = motion
        self.lambda_ = float(lambda_)
        self.max_moves = int(max_moves)
        self.revisit = bool(revisit)
        self._bayes = BayesBelief(model)
        reach = motion.reachable
        valid = motion.energy[np.ix_(reach, reach)]
        valid = valid[np.isfinite(valid)]
        most = float(valid.max()) if valid.size else 0.0
        self.invalid_penalty = most if invalid_penalty is None else float(invalid_penalty)
        views, classes = evidence.viewpoints, evidence.classes
        self.observation_space = spaces.Box(0.0, 1.0, (classes + 2 * views,), np.float32)
        self.action_space = spaces.Discrete(views + classes)
        if seed is not None:
            self._np_random, self._np_random_seed = gymnasium.utils.seeding.np_random(seed)
        self._reachable_starts = np.flatnonzero(reach)
        self._model = 0
        self._viewpoint = 0
        self._visited = np.zeros(views, dtype=bool)
        self._steps = 0
        self._moves = 0
        self._energy = 0.0
        self._done = True

    @property
    def viewpoints(self) -> int:
        return self.evidence.viewpoints

    @property
    def classes(self) -> int:
        return self.evidence.classes

    @property
    def belief(self) -> np.ndarray:
        """The current belief over classes (C,)."""
        return self._bayes.belief

    def action_masks(self) -> np.ndarray:
        """(V + C,) bool: :func:`valid_actions` now (all False once the episode is over)."""
        if self._done:
            return np.zeros(self.action_space.n, dtype=bool)
        return valid_actions(self.motion.reachable, self._viewpoint, self._visited,
                             self._steps, self.max_moves, self.revisit, self.classes)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        options = episode_options(options)
        model = options.get("model")
        if model is None:
            model = int(self.np_random.integers(self.evidence.models))
        elif not 0 <= int(model) < self.evidence.models:
            raise ValueError(f"reset: model {model} is not in [0, {self.evidence.models})")
        start = options.get("start")
        if start is None:
            start = int(self.np_random.choice(self._reachable_starts))
        elif not (0 <= int(start) < self.viewpoints and self.motion.reachable[int(start)]):
            raise ValueError(f"reset: start viewpoint {start} is not a reachable viewpoint")
        self._model, self._viewpoint = int(model), int(start)
        self._visited[:] = False
        self._steps, self._moves, self._energy, self._done = 0, 0, 0.0, False
        self._bayes.reset()
        self._look()
        return self._observation(), {"viewpoint": self._viewpoint}

    def step(self, action: int) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._done:
            raise RuntimeError("step: the episode is over (or never started); call reset()")
        action = int(action)
        if not 0 <= action < self.action_space.n:
            raise ValueError(f"step: action {action} is not in [0, {self.action_space.n})")
        views = self.viewpoints
        if action >= views:
            declared = action - views
            truth = int(self.evidence.labels[self._model])
            self._done = True
            return self._observation(), (0.0 if declared == truth else -self.lambda_), True, \
                False, self._final_info(declared=declared, correct=declared == truth)
        if not self.action_masks()[action]:
            truncated = self._steps >= self.max_moves
            self._steps += 1
            self._done = truncated
            info = self._final_info() if truncated else {"viewpoint": self._viewpoint}
            info["invalid"] = True
            return self._observation(), -self.invalid_penalty, False, truncated, info
        energy, _ = self.motion.move(self._viewpoint, action)
        self._energy += energy
        self._steps += 1
        self._moves += 1
        self._viewpoint = action
        self._look()
        return self._observation(), -energy, False, False, {"viewpoint": action}

    def _look(self) -> None:
        """The recorded output at the current viewpoint enters the belief (Eq. 5)."""
        self._visited[self._viewpoint] = True
        self._bayes.update(self._viewpoint, self.evidence.outputs[self._model, self._viewpoint])

    def _observation(self) -> np.ndarray:
        return policy_input(self._bayes.belief, self._viewpoint, self._visited)

    def _final_info(self, **extra: Any) -> dict[str, Any]:
        return {"viewpoint": self._viewpoint, "model": self._model,
                "true_class": int(self.evidence.labels[self._model]), "moves": self._moves,
                "energy": self._energy, **extra}


class MapDeclaration(gymnasium.Wrapper):  # type: ignore[type-arg]
    """A policy's action space where declaring is one action, "stop": the environment then
    declares the belief's most likely class, as Random and the POMDP methods declare.
    Actions ``j < V`` move as before, ``V`` stops; the rewards and
    the episode are the wrapped environment's (a declaration of that class)."""

    def __init__(self, env: RecordedRecognitionEnv) -> None:
        super().__init__(env)
        self.viewpoints = env.viewpoints
        self.action_space = spaces.Discrete(env.viewpoints + 1)

    def action_masks(self) -> np.ndarray:
        """(V + 1,) bool: the wrapped environment's moves, then stop (any declaration)."""
        return map_mask(self.env.unwrapped.action_masks(), self.viewpoints)

    def step(self, action: int) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        belief = self.env.unwrapped.belief
        return self.env.step(closed_loop_action(int(action), belief, self.viewpoints))


def map_mask(mask: np.ndarray, viewpoints: int) -> np.ndarray:
    """A closed-loop mask (V + C,) as :class:`MapDeclaration`'s (V + 1,): moves, then stop."""
    return np.append(mask[:viewpoints], mask[viewpoints:].any())


def closed_loop_action(action: int, belief: np.ndarray, viewpoints: int) -> int:
    """The closed-loop action (``Discrete(V + C)``) of a :class:`MapDeclaration` action: a move
    is itself, stop declares the belief's most likely class."""
    return action if action < viewpoints else viewpoints + int(np.argmax(belief))


__all__ = ["RECORDED_FILE", "MapDeclaration", "RecordedEvidence", "RecordedRecognitionEnv",
           "closed_loop_action", "map_mask", "policy_input", "valid_actions"]
