"""A gymnasium environment over the closed-loop simulator, for learned or scripted policies.

One episode: a test model stands at the workspace centre and the camera starts at a reachable
test viewpoint. Each step either moves the camera (action ``j < V``: to viewpoint ``j``; reward
``-E_M[v, j]``, the next depth image is rendered) or declares a class (action ``V + k``: class
``k``; the episode terminates with reward 0 when right, ``-lambda`` when wrong). The rendering,
the sensor noise and the costs are those of the episode simulator
(:class:`~rapomdp.data.test_views.TestViews`, :class:`~rapomdp.experiment.episode.Motion`), so an
agent here sees what the methods of Table 1 see.

An invalid move (out of range, to an unreachable viewpoint, or to the current one) raises
``ValueError``; ``info["action_mask"]`` (V + C,) tells the valid actions so that a learned policy
can mask them. The ground truth reaches the agent only in the final ``info`` (like a scorer).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from rapomdp.data.dataset import load_dataset
from rapomdp.data.test_views import TestViews
from rapomdp.experiment.episode import Motion
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import StageError, Workspace

Observation = dict[str, Any]


class ActiveRecognitionEnv(gymnasium.Env):
    """Active recognition of one test model per episode: move the camera, then declare a class.

    Observations are ``{"depth": (H, W) float32 metres, "viewpoint": int}``; actions are
    ``Discrete(V + C)``. An episode is truncated after ``max_moves`` moves. ``reset`` takes
    ``options={"model": i, "start": v}`` to fix the test model and the start viewpoint (each
    drawn from the environment's RNG otherwise). The sensor noise draws from the same RNG, so
    ``reset(seed=s)`` makes an episode reproducible.
    """

    metadata: dict[str, Any] = {"render_modes": []}

    def __init__(self, scenes: Sequence[TestViews], true_classes: Sequence[int],
                 class_names: Sequence[str], motion: Motion, lambda_: float,
                 max_moves: int = 30, seed: int | None = None) -> None:
        if not scenes:
            raise ValueError("ActiveRecognitionEnv needs at least one scene (test model)")
        if len(true_classes) != len(scenes):
            raise ValueError(f"{len(scenes)} scenes but {len(true_classes)} true classes")
        classes = len(class_names)
        bad = [c for c in true_classes if not 0 <= int(c) < classes]
        if bad:
            raise ValueError(f"true classes {bad} are not in [0, {classes}) ({classes} classes)")
        views = motion.viewpoints
        if motion.energy.shape != (views, views) or motion.distance_m.shape != (views, views):
            raise ValueError(f"motion: energy {motion.energy.shape} and distance "
                             f"{motion.distance_m.shape} must be ({views}, {views})")
        for i, scene in enumerate(scenes):
            if scene.poses.shape[0] != views:
                raise ValueError(f"scene {i} has {scene.poses.shape[0]} viewpoint poses, the "
                                 f"motion {views}: build both from the same viewpoints.count")
        if not np.any(motion.reachable):
            raise ValueError("motion: no viewpoint is reachable")
        if max_moves < 1:
            raise ValueError(f"max_moves must be at least 1, got {max_moves}")
        if not lambda_ > 0:
            raise ValueError(f"lambda_ (cost of a wrong declaration) must be positive, got "
                             f"{lambda_}")
        shapes = {scene.renderer.image_shape for scene in scenes}
        if len(shapes) != 1:
            raise ValueError(f"scenes render different image sizes: {sorted(shapes)}")
        (height, width), = shapes
        self.scenes = list(scenes)
        self.true_classes = [int(c) for c in true_classes]
        self.class_names = [str(c) for c in class_names]
        self.motion = Motion(np.asarray(motion.energy, dtype=np.float64),
                             np.asarray(motion.distance_m, dtype=np.float64),
                             np.asarray(motion.reachable, dtype=bool))
        self.lambda_ = float(lambda_)
        self.max_moves = int(max_moves)
        self.observation_space = spaces.Dict({
            "depth": spaces.Box(0.0, np.inf, (height, width), np.float32),
            "viewpoint": spaces.Discrete(views),
        })
        self.action_space = spaces.Discrete(views + classes)
        if seed is not None:
            self._np_random, self._np_random_seed = gymnasium.utils.seeding.np_random(seed)
        self._model: int | None = None
        self._viewpoint = 0
        self._depth = np.zeros((height, width), dtype=np.float32)
        self._moves = 0
        self._energy = 0.0
        self._distance = 0.0
        self._done = True

    @property
    def viewpoints(self) -> int:
        return self.motion.viewpoints

    @property
    def classes(self) -> int:
        return len(self.class_names)

    @classmethod
    def from_workspace(cls, path: str | Path, max_moves: int = 30,
                       seed: int | None = None) -> ActiveRecognitionEnv:
        """The environment of a workspace whose dataset and robot stages have run.

        The scenes are its test models seen from X_rho (``viewpoints`` section) at the camera's
        resolution with ``render.noise``; the motion is ``robot.npz`` (moves to or from an
        unreachable viewpoint keep E_M = inf and are invalid); lambda is
        ``solve.wrong_declaration_cost_m``. The configuration is read from ``W/config.yaml``.
        """
        ws = Workspace(path)
        config = ws.config()
        dataset = load_dataset(ws.require("dataset"))
        robot = load_robot(ws.require("robot"))
        vp = config.viewpoints
        if robot["reachable"].size != vp.count:
            raise StageError(f"{ws.require('robot')}: robot.npz covers "
                             f"{robot['reachable'].size} viewpoints, {ws.config_path} "
                             f"viewpoints.count is {vp.count}")
        models = dataset.with_role("test")
        scenes = [TestViews.of_model(config, dataset, m) for m in models]
        motion = Motion.from_robot(robot)
        return cls(scenes, [dataset.label(m) for m in models], dataset.classes, motion,
                   config.solve.wrong_declaration_cost_m, max_moves=max_moves, seed=seed)

    def action_mask(self) -> np.ndarray:
        """(V + C,) bool: the moves to reachable viewpoints other than the current one, and
        every declaration (all False once the episode is over)."""
        mask = np.ones(self.viewpoints + self.classes, dtype=bool)
        mask[: self.viewpoints] = self.motion.reachable
        mask[self._viewpoint] = False
        return mask if not self._done else np.zeros_like(mask)

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[Observation, dict[str, Any]]:
        """Start an episode: options ``model`` (index into the scenes) and ``start`` (a
        reachable viewpoint) fix the test model and start viewpoint; unset, they are drawn."""
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = set(options) - {"model", "start"}
        if unknown:
            raise ValueError(f"reset: unknown option(s) {sorted(unknown)}; options are "
                             f"'model' and 'start'")
        model = options.get("model")
        if model is None:
            model = int(self.np_random.integers(len(self.scenes)))
        elif not (isinstance(model, int | np.integer) and 0 <= model < len(self.scenes)):
            raise ValueError(f"reset: model {model!r} is not a scene index in "
                             f"[0, {len(self.scenes)})")
        start = options.get("start")
        reachable = np.flatnonzero(self.motion.reachable)
        if start is None:
            start = int(self.np_random.choice(reachable))
        elif not (isinstance(start, int | np.integer) and 0 <= start < self.viewpoints):
            raise ValueError(f"reset: start viewpoint {start!r} is not in [0, {self.viewpoints})")
        elif not self.motion.reachable[start]:
            raise ValueError(f"reset: start viewpoint {start} is not reachable by the arm")
        self._model, self._viewpoint = int(model), int(start)
        self._moves, self._energy, self._distance, self._done = 0, 0.0, 0.0, False
        self._depth = self._look()
        return self._observation(), self._info()

    def step(self, action: int) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        """Move (``action < V``) or declare class ``action - V``; see the class docstring.

        Raises ``ValueError`` for an action out of range or an invalid move, and
        ``RuntimeError`` when the episode is over (call ``reset``)."""
        if self._model is None or self._done:
            raise RuntimeError("step: the episode is over (or never started); call reset()")
        if not (isinstance(action, int | np.integer) and 0 <= action < self.action_space.n):
            raise ValueError(f"step: action {action!r} is not in [0, {self.action_space.n}) "
                             f"({self.viewpoints} moves, then {self.classes} declarations)")
        action = int(action)
        if action >= self.viewpoints:
            declared = action - self.viewpoints
            truth = self.true_classes[self._model]
            self._done = True
            info = self._info()
            info.update(declared=declared, correct=declared == truth, true_class=truth,
                        model=self._model)
            reward = 0.0 if declared == truth else -self.lambda_
            return self._observation(), reward, True, False, info
        energy, distance_m = self.motion.move(self._viewpoint, action)
        self._energy += energy
        self._distance += distance_m
        self._moves += 1
        self._viewpoint = action
        self._depth = self._look()
        truncated = self._moves >= self.max_moves
        self._done = truncated
        return self._observation(), -energy, False, truncated, self._info()

    def _look(self) -> np.ndarray:
        depth = self.scenes[self._model].look(self._viewpoint, self.np_random)
        return np.asarray(depth, dtype=np.float32)

    def _observation(self) -> Observation:
        return {"depth": self._depth.copy(), "viewpoint": self._viewpoint}

    def _info(self) -> dict[str, Any]:
        return {"viewpoint": self._viewpoint, "action_mask": self.action_mask(),
                "moves": self._moves, "energy": self._energy, "distance_m": self._distance}
