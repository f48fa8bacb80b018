"""A gymnasium environment over the closed-loop simulator, for learned or scripted policies.

One episode: a test model stands at the workspace centre and the camera starts at a reachable
test viewpoint. Each step either moves the camera (action ``j < V``: to viewpoint ``j``; reward
``-E_M[v, j]``, the next depth image is rendered) or declares a class (action ``V + k``: class
``k``; the episode terminates with reward 0 when right, ``-lambda`` when wrong). The rendering,
the sensor noise and the costs are those of the episode simulator
(:class:`~rapomdp.data.test_views.TestViews`, :class:`~rapomdp.experiment.episode.Motion`), so an
agent here sees what the methods of Table 1 see.

An action of ``action_space`` outside ``info["action_mask"]`` (a move to an unreachable viewpoint
or to the current one) is a no-op: the camera stays, the observation is unchanged, the reward is
``-invalid_penalty`` (default: the most a valid move costs, so it never pays) and
``info["invalid"]`` is True; it counts as a step towards truncation, so a loop of
``env.action_space.sample()`` always ends. ``info["action_mask"]`` (V + C,) tells the valid
actions so that a learned policy can mask them. The ground truth reaches the agent only in the
final ``info`` (at termination and at truncation, like a scorer).

Importing this module registers it with gymnasium as :data:`ENV_ID`
(``gymnasium.make("rapomdp/ActiveRecognition-v0", workspace=W)``); without the import,
``gymnasium.make("rapomdp.experiment.env:rapomdp/ActiveRecognition-v0", workspace=W)`` imports
it.
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
from rapomdp.experiment.recorded_env import episode_options
from rapomdp.geometry.viewsphere import azimuth_zenith, fibonacci_directions
from rapomdp.planning.policy import ARAction
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import StageError, Workspace

Observation = dict[str, Any]
#: The gymnasium id this module registers on import.
ENV_ID = "rapomdp/ActiveRecognition-v0"


def whole_number(value: object) -> int | None:
    """``value`` as an int when it is one as ``Discrete.contains`` sees it (a Python or NumPy
    integer, or a 0-d integer array), else None: a bool, a float (``2.7``, ``inf``, ``nan``),
    anything else."""
    if isinstance(value, bool | np.bool_):
        return None
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, np.ndarray) and value.shape == () and value.dtype.kind in "iu":
        return int(value)
    return None


class ActiveRecognitionEnv(gymnasium.Env):
    """Active recognition of one test model per episode: move the camera, then declare a class.

    Observations are ``{"depth": (H, W) float32 metres, "viewpoint": int}``; actions are
    ``Discrete(V + C)``. An episode is truncated after ``max_moves`` steps that did not
    declare (moves and invalid actions). ``reset`` takes ``options={"model": i, "start": v}``
    to fix the test model and the start viewpoint (each drawn from the environment's RNG
    otherwise). The sensor noise draws from the same RNG, so ``reset(seed=s)`` makes an episode
    reproducible. ``render_mode="rgb_array"``: :meth:`render` returns the depth image beside
    the hemisphere seen from above with the current viewpoint and the path.
    """

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(self, scenes: Sequence[TestViews], true_classes: Sequence[int],
                 class_names: Sequence[str], motion: Motion, lambda_: float,
                 max_moves: int = 30, seed: int | None = None,
                 render_mode: str | None = None, invalid_penalty: float | None = None,
                 revisit: bool = True) -> None:
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
        moves = whole_number(max_moves)
        if moves is None or moves < 1:
            raise ValueError(f"max_moves must be a whole number of at least 1, got "
                             f"{max_moves!r}")
        if not lambda_ > 0:
            raise ValueError(f"lambda_ (cost of a wrong declaration) must be positive, got "
                             f"{lambda_}")
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode {render_mode!r} is not one of "
                             f"{self.metadata['render_modes']} (or None)")
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
        self.max_moves = moves
        self.render_mode = render_mode
        valid = self.motion.energy[np.ix_(self.motion.reachable, self.motion.reachable)]
        valid = valid[np.isfinite(valid)]
        most = float(valid.max()) if valid.size else 0.0
        self.invalid_penalty = most if invalid_penalty is None else float(invalid_penalty)
        if not (np.isfinite(self.invalid_penalty) and self.invalid_penalty >= 0):
            raise ValueError(f"invalid_penalty must be finite and non-negative, got "
                             f"{invalid_penalty}")
        self.revisit = bool(revisit)
        self.max_depth_m = max_depth_m(self.scenes)
        self.observation_space = spaces.Dict({
            "depth": spaces.Box(0.0, self.max_depth_m, (height, width), np.float32),
            "viewpoint": spaces.Discrete(views),
        })
        self.action_space = spaces.Discrete(views + classes)
        if seed is not None:
            self._np_random, self._np_random_seed = gymnasium.utils.seeding.np_random(seed)
        self._model: int | None = None
        self._viewpoint = 0
        self._depth = np.zeros((height, width), dtype=np.float32)
        self._moves = 0
        self._steps = 0
        self._energy = 0.0
        self._distance = 0.0
        self._done = True
        self._path: list[int] = []
        self._hemisphere_px: np.ndarray | None = None

    @property
    def viewpoints(self) -> int:
        return self.motion.viewpoints

    @property
    def classes(self) -> int:
        return len(self.class_names)

    @classmethod
    def from_workspace(cls, path: str | Path, max_moves: int = 30, seed: int | None = None,
                       render_mode: str | None = None, invalid_penalty: float | None = None,
                       revisit: bool = True) -> ActiveRecognitionEnv:
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
        scenes = [TestViews.of_model(dataset, m, vp, config.camera, config.render.noise)
                  for m in models]
        motion = Motion.from_robot(robot)
        return cls(scenes, [dataset.label(m) for m in models], dataset.classes, motion,
                   config.solve.wrong_declaration_cost_m, max_moves=max_moves, seed=seed,
                   render_mode=render_mode, invalid_penalty=invalid_penalty, revisit=revisit)

    def action_index(self, action: ARAction) -> int:
        """The action of this space for a planner's :class:`ARAction` (a policy's ``act``):
        a move to viewpoint j is ``j``, declaring class k is ``V + k``."""
        return int(action.target) + (self.viewpoints if action.is_declare else 0)

    def ar_action(self, action: int) -> ARAction:
        """The :class:`ARAction` of an action of this space (the inverse of
        :meth:`action_index`)."""
        action = int(action)
        if action >= self.viewpoints:
            return ARAction("declare", action - self.viewpoints)
        return ARAction("move", action)

    def action_mask(self) -> np.ndarray:
        """(V + C,) bool: the moves to reachable viewpoints other than the current one (and,
        with ``revisit`` False, not visited), and every declaration (all False once the
        episode is over)."""
        mask = np.ones(self.viewpoints + self.classes, dtype=bool)
        mask[: self.viewpoints] = self.motion.reachable
        if not self.revisit:
            mask[self._path] = False
        mask[self._viewpoint] = False
        return mask if not self._done else np.zeros_like(mask)

    def action_masks(self) -> np.ndarray:
        """:meth:`action_mask`, by the name sb3-contrib's ``MaskablePPO`` calls."""
        return self.action_mask()

    def reset(self, *, seed: int | None = None,
              options: dict[str, Any] | None = None) -> tuple[Observation, dict[str, Any]]:
        """Start an episode: options ``model`` (index into the scenes) and ``start`` (a
        reachable viewpoint) fix the test model and start viewpoint; unset, they are drawn."""
        super().reset(seed=seed)
        options = episode_options(options)
        given, start_given = options.get("model"), options.get("start")
        model, start = whole_number(given), whole_number(start_given)
        if given is None:
            model = int(self.np_random.integers(len(self.scenes)))
        elif model is None or not 0 <= model < len(self.scenes):
            raise ValueError(f"reset: model {given!r} is not a scene index in "
                             f"[0, {len(self.scenes)}) (a whole number)")
        reachable = np.flatnonzero(self.motion.reachable)
        if start_given is None:
            start = int(self.np_random.choice(reachable))
        elif start is None or not 0 <= start < self.viewpoints:
            raise ValueError(f"reset: start viewpoint {start_given!r} is not in "
                             f"[0, {self.viewpoints}) (a whole number)")
        elif not self.motion.reachable[start]:
            raise ValueError(f"reset: start viewpoint {start} is not reachable by the arm")
        self._model, self._viewpoint = int(model), int(start)
        self._moves, self._steps, self._energy, self._distance = 0, 0, 0.0, 0.0
        self._done = False
        self._path = [self._viewpoint]
        self._depth = self._look()
        return self._observation(), self._info()

    def step(self, action: int) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        """Move (``action < V``) or declare class ``action - V``; see the class docstring.

        An action outside the mask is a no-op with ``-invalid_penalty`` and
        ``info["invalid"]``. Raises ``ValueError`` for an action outside ``action_space`` and
        ``RuntimeError`` when the episode is over (call ``reset``)."""
        if self._model is None or self._done:
            raise RuntimeError("step: the episode is over (or never started); call reset()")
        index = whole_number(action)
        if index is None or not 0 <= index < self.action_space.n:
            raise ValueError(f"step: action {action!r} is not in [0, {self.action_space.n}) "
                             f"({self.viewpoints} moves, then {self.classes} declarations)")
        action = index
        if action >= self.viewpoints:
            return self.declare(action - self.viewpoints)
        if not self.action_mask()[action]:
            return self.invalid(action)
        return self.move(action)

    def move(self, target: int) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        """A valid move to ``target``: pay E_M (the closed loop's :meth:`Motion.move`), render
        the new view."""
        energy, distance_m = self.motion.move(self._viewpoint, target)
        self._energy += energy
        self._distance += distance_m
        self._moves += 1
        self._viewpoint = int(target)
        self._path.append(self._viewpoint)
        self._depth = self._look()
        return self._after_step(-energy, invalid=False)

    def invalid(self, action: int) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        """An action outside the mask: nothing moves, ``-invalid_penalty``."""
        info_reason = self._invalid_reason(action)
        observation, reward, terminated, truncated, info = self._after_step(
            -self.invalid_penalty, invalid=True)
        info["invalid_reason"] = info_reason
        return observation, reward, terminated, truncated, info

    def declare(self, declared: int) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        """Declare class ``declared``: 0 if right, ``-lambda_`` if wrong; the episode ends."""
        truth = self.true_classes[self._model]
        self._done = True
        self._steps += 1
        info = self._info()
        info.update(declared=int(declared), correct=int(declared) == truth, true_class=truth,
                    model=self._model, invalid=False)
        reward = 0.0 if declared == truth else -self.lambda_
        return self._observation(), reward, True, False, info

    def _after_step(self, reward: float, invalid: bool
                    ) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        self._steps += 1
        truncated = self._steps >= self.max_moves
        self._done = truncated
        info = self._info()
        info["invalid"] = invalid
        if truncated:  # the episode ends without a declaration: the scorer's view
            info.update(true_class=self.true_classes[self._model], model=self._model)
        return self._observation(), reward, False, truncated, info

    def _invalid_reason(self, target: int) -> str:
        try:
            self.motion.check_move(self._viewpoint, target)
        except ValueError as exc:
            return str(exc)
        if not self.revisit and target in self._path:
            return f"move to viewpoint {target}: already visited (revisit is off)"
        return f"move to viewpoint {target}: not allowed"

    def render(self) -> np.ndarray | None:
        """``render_mode="rgb_array"``: (H', W', 3) uint8, the depth image (near = yellow,
        no hit = white) beside the hemisphere seen from above (grey: reachable, pink:
        unreachable, blue: visited, orange: the current viewpoint). None without a mode."""
        if self.render_mode is None:
            return None
        scale = -(-96 // self._depth.shape[0])  # at least 96 px high
        depth = np.repeat(np.repeat(self._depth, scale, axis=0), scale, axis=1)
        return np.concatenate([_colourise_depth(depth), self._hemisphere(depth.shape[0])],
                              axis=1)

    def _hemisphere(self, side: int) -> np.ndarray:
        if self._hemisphere_px is None or self._hemisphere_px.shape[0] != side:
            self._hemisphere_px = _hemisphere_pixels(self.viewpoints, side)
        state = np.where(self.motion.reachable, 2, 3)
        state[self._path] = 4
        state[self._viewpoint] = 5
        which = self._hemisphere_px
        codes = np.where(which >= 0, state[np.maximum(which, 0)], -which - 1)
        return _PALETTE[codes]

    def _look(self) -> np.ndarray:
        depth = self.scenes[self._model].look(self._viewpoint, self.np_random)
        return np.minimum(np.asarray(depth, dtype=np.float32), np.float32(self.max_depth_m))

    def _observation(self) -> Observation:
        return {"depth": self._depth.copy(), "viewpoint": self._viewpoint}

    def _info(self) -> dict[str, Any]:
        return {"viewpoint": self._viewpoint, "action_mask": self.action_mask(),
                "moves": self._moves, "steps": self._steps, "energy": self._energy,
                "distance_m": self._distance}


#: Room above the farthest surface point for the sensor noise (a reading moves by about 1 %
#: at the default camera: quantisation and axial noise at 0.8 m).
DEPTH_NOISE_MARGIN = 0.1


def max_depth_m(scenes: Sequence[TestViews]) -> float:
    """The observation's finite upper bound: the largest distance from any camera of any
    scene to a corner of its mesh's bounding box (no surface point is farther: z-depth is at
    most that distance, and a box's farthest point is a corner), plus
    :data:`DEPTH_NOISE_MARGIN` of it for the sensor noise."""
    farthest = 0.0
    for scene in scenes:
        corners = box_corners(np.asarray(scene.renderer.mesh.bounds, dtype=np.float64))
        eyes = np.asarray(scene.poses, dtype=np.float64)[:, :3, 3]
        farthest = max(farthest, float(np.linalg.norm(
            eyes[:, None, :] - corners[None], axis=2).max()))
    return farthest * (1.0 + DEPTH_NOISE_MARGIN)


def box_corners(bounds: np.ndarray) -> np.ndarray:
    """The 8 corners (8, 3) of an axis-aligned box given as ``[[min], [max]]``."""
    pick = np.array(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij")).reshape(3, -1).T
    return bounds[pick, np.arange(3)]


#: Colours of :meth:`ActiveRecognitionEnv.render`'s hemisphere: background, disc, reachable,
#: unreachable, visited, current.
_PALETTE = np.array([[255, 255, 255], [235, 235, 235], [130, 130, 130], [240, 170, 170],
                     [0, 114, 178], [230, 159, 0]], dtype=np.uint8)


def _hemisphere_pixels(viewpoints: int, side: int) -> np.ndarray:
    """(side, side) int: the viewpoint drawn at each pixel of the hemisphere's top view, or
    -1 (background) / -2 (the disc) where none is (the polar plot of the figures: radius =
    angle from the zenith). Viewpoints are X_rho's directions (Fibonacci order)."""
    azimuth, zenith = azimuth_zenith(fibonacci_directions(viewpoints, hemisphere=True))
    radius = zenith / (np.pi / 2) * 0.46 * side
    centres = np.stack([side / 2 - radius * np.sin(azimuth),
                        side / 2 + radius * np.cos(azimuth)], axis=1)  # (row, col), +y up
    from scipy.spatial import cKDTree

    rows, cols = np.mgrid[0:side, 0:side] + 0.5
    pixels = np.stack([rows.ravel(), cols.ravel()], axis=1)
    distance, nearest = cKDTree(centres).query(pixels)
    dot = max(1.5, 0.55 * side / np.sqrt(4 * viewpoints))
    in_disc = np.linalg.norm(pixels - side / 2, axis=1) <= 0.48 * side
    out = np.where(distance <= dot, nearest, np.where(in_disc, -2, -1))
    return out.reshape(side, side)


def _colourise_depth(depth: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 of a depth image: viridis reversed over the hit pixels' range."""
    from matplotlib import colormaps

    hit = depth > 0
    image = np.full((*depth.shape, 3), 255, dtype=np.uint8)
    if hit.any():
        near, far = float(depth[hit].min()), float(depth[hit].max())
        level = (far - depth[hit]) / max(far - near, 1e-9)
        image[hit] = (colormaps["viridis"](level)[:, :3] * 255).astype(np.uint8)
    return image


def make_env(workspace: str | Path, **kwargs: Any) -> ActiveRecognitionEnv:
    """The entry point of ``gymnasium.make(ENV_ID, workspace=W, ...)``: keyword arguments
    are :meth:`ActiveRecognitionEnv.from_workspace`'s."""
    return ActiveRecognitionEnv.from_workspace(workspace, **kwargs)


if ENV_ID not in gymnasium.registry:
    gymnasium.register(ENV_ID, entry_point="rapomdp.experiment.env:make_env")

__all__ = ["ENV_ID", "ActiveRecognitionEnv", "make_env"]
