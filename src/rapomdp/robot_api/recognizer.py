"""The recogniser-and-planner a robot program calls with depth images: :class:`ActiveRecognizer`.

One object per finished workspace and method. A robot program resets it at the start of an
episode, hands it each depth image with the camera pose it was taken from
(:meth:`ActiveRecognizer.observe`: the belief over the classes, the class the method would
declare and its declared confidence) and asks where to look next
(:meth:`ActiveRecognizer.next_view`: a viewpoint of X_rho with its camera pose, the Panda joint
configuration that reaches it and the move's energy, or a declaration). The rules are the closed
loop's own: the belief update, the policy's action, the visited set, the stop rule and the step
budget are :func:`rapomdp.experiment.episode.closed_loop_step`, the methods are those
:class:`rapomdp.experiment.evaluation.ClosedLoop` builds, the declared confidence is
:mod:`rapomdp.belief`'s, and the image reaches the network through the project's one
preprocessing (:func:`rapomdp.recognition.preprocess.preprocess`, via ``Classifier.predict``).

Frames: every pose is camera-to-world (4, 4), in metres, in the world frame of the robot stage's
scene (docs/robot.md): Z up, the floor at z = 0, the object's centroid at ``robot.centroid_m``;
the camera frame is OpenCV's (x right, y down, z along the optical axis).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rapomdp.config import METHOD_NAMES, Config
from rapomdp.experiment.episode import Policy, Recogniser, Step, closed_loop_step
from rapomdp.experiment.evaluation import ClosedLoop
from rapomdp.experiment.held_out import load_declared_fit
from rapomdp.geometry.camera import Intrinsics, xtion_intrinsics
from rapomdp.recognition.classifier import Classifier
from rapomdp.workspace import StageError, StageInputs, Workspace

#: The stages whose folders the closed loop reads (those that have not run are left out).
LOOP_STAGES = ("dataset", "train", "classifier_eval", "robot", "observe", "vptree", "solve",
               "learn")
#: Millimetres per metre: a uint16 depth image holds millimetres.
MM_PER_M = 1000.0
#: The median depth (metres) above which a float image is taken for millimetres and refused.
MAX_FLOAT_DEPTH_M = 20.0


class OutOfOrderError(RuntimeError):
    """A call the episode's state does not allow: ``observe`` before ``reset``, ``next_view``
    before any ``observe``, ``observe`` after the method declared. ``code`` names it."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code


def depth_in_metres(depth: np.ndarray) -> np.ndarray:
    """A real depth image as the recogniser reads it: (H, W) float32 metres, 0 where no depth.

    Args:
        depth: (H, W) uint16 millimetres (a sensor's raw image) or floating-point metres;
            zeros, NaN, infinities and negative values are holes. A float image whose median
            depth exceeds :data:`MAX_FLOAT_DEPTH_M` is refused (millimetres sent as floats).

    Returns:
        (H, W) float32 metres with every hole 0 (the network's background).

    Example:
        >>> metres = depth_in_metres(np.array([[0, 650, 65535]], dtype=np.uint16))
        >>> metres.dtype, metres.astype(float).round(3).tolist()
        (dtype('float32'), [[0.0, 0.65, 65.535]])
    """
    depth = np.asarray(depth)
    if depth.ndim != 2 or min(depth.shape) < 1:
        raise ValueError(f"a depth image must be (H, W), got shape {depth.shape}")
    if depth.dtype == np.uint16:
        metres = depth.astype(np.float64) / MM_PER_M
    elif depth.dtype.kind == "f":
        metres = depth.astype(np.float64)
    else:
        raise ValueError(f"a depth image must be uint16 millimetres or float metres, got "
                         f"dtype {depth.dtype}")
    metres[~np.isfinite(metres) | (metres < 0)] = 0.0
    seen = metres[metres > 0]
    if depth.dtype.kind == "f" and seen.size and float(np.median(seen)) > MAX_FLOAT_DEPTH_M:
        raise ValueError(f"a float depth image holds metres, but its median depth is "
                         f"{float(np.median(seen)):.0f}: millimetres? Send them as uint16 or "
                         "divide by 1000")
    return metres.astype(np.float32)


def intrinsics_for(depth: np.ndarray, given: Intrinsics | Mapping[str, float] | None
                   ) -> Intrinsics:
    """The pinhole intrinsics of a depth image.

    Args:
        depth: the (H, W) image.
        given: :class:`~rapomdp.geometry.camera.Intrinsics`, or ``{"fx", "fy", "cx", "cy"}``
            in pixels at the image's resolution; None: the simulated Xtion at that resolution
            (the workspace camera's model).

    Returns:
        Intrinsics whose width and height are the image's.
    """
    height, width = depth.shape
    if given is None:
        return xtion_intrinsics(width, height)
    if isinstance(given, Intrinsics):
        if (given.height, given.width) != (height, width):
            raise ValueError(f"intrinsics are for {given.width}x{given.height} px, the depth "
                             f"image is {width}x{height} px")
        return given
    missing = {"fx", "fy", "cx", "cy"} - set(given)
    if missing:
        raise ValueError(f"intrinsics lack {sorted(missing)} (fx, fy, cx, cy in pixels)")
    values = {k: float(given[k]) for k in ("fx", "fy", "cx", "cy")}
    if not all(math.isfinite(v) for v in values.values()):
        raise ValueError(f"intrinsics must be finite, got {values}")
    return Intrinsics(width, height, **values)


@dataclass(frozen=True)
class Observation:
    """What :meth:`ActiveRecognizer.observe` answers.

    ``viewpoint``: the index in X_rho the image was counted at, ``off_viewpoint_m`` how far the
    camera centre was from it (metres); ``output`` (C,) the recogniser's class probabilities;
    ``belief`` (C,) the method's belief as it reports it (the declared confidence rule,
    :func:`rapomdp.belief.declared_belief`); ``declared_class`` the class it declares if it
    stops now (its declaration when ``done``, else the belief's most likely class) and
    ``declared_confidence`` its belief in that class; ``done``: the method stops here
    (``exhausted``: forced by the step budget); ``moves``: moves made before this image.
    """

    viewpoint: int
    off_viewpoint_m: float
    output: np.ndarray
    belief: np.ndarray
    declared_class: int
    declared_class_name: str
    declared_confidence: float
    done: bool
    exhausted: bool
    moves: int


@dataclass(frozen=True)
class NextView:
    """What :meth:`ActiveRecognizer.next_view` answers: ``action`` "move" or "declare".

    For a move: ``viewpoint`` (index in X_rho), ``camera_pose_world`` (4, 4) camera-to-world
    in the scene's world frame, the pose the robot stage's IK solution reaches,
    ``q_rad`` (7,) that Panda joint configuration, ``energy_m`` the move's E_M (Eq. 3) and
    ``distance_m`` its geodesic length. For a declaration those are -1 and NaN, and
    ``declared_class`` / ``declared_confidence`` are the answer.
    """

    action: str
    viewpoint: int
    camera_pose_world: np.ndarray
    q_rad: np.ndarray
    energy_m: float
    distance_m: float
    declared_class: int
    declared_class_name: str
    declared_confidence: float

    @property
    def is_declare(self) -> bool:
        return self.action == "declare"


@dataclass
class _Episode:
    rng: np.random.Generator
    started: bool = False
    viewpoint: int = -1
    moves: int = 0
    step: Step | None = None
    visited: list[int] = field(default_factory=list)


class ActiveRecognizer:
    """A method of a finished workspace, driven by a robot program's depth images.

    Build it with :meth:`load`. Per episode: :meth:`reset`, then alternately :meth:`observe`
    and :meth:`next_view` until ``next_view`` declares. Fed the images the closed loop renders,
    it takes the closed loop's actions and declarations (``tests/robot_api``).

    Example:
        >>> rec = ActiveRecognizer.load("runs/demo", method="ra")  # doctest: +SKIP
        >>> rec.reset(seed=0)  # doctest: +SKIP
        >>> seen = rec.observe(depth_u16, camera_pose)  # doctest: +SKIP
        >>> rec.next_view().action  # doctest: +SKIP
        'move'
    """

    def __init__(self, method: str, policy: Policy, recogniser: Recogniser, loop: ClosedLoop,
                 robot: Mapping[str, np.ndarray], centroid_m: np.ndarray,
                 declared_source: str) -> None:
        self.method = method
        self.policy = policy
        self.recogniser = recogniser
        self.classes = list(loop.dataset.classes)
        self.motion = loop.motion
        self.max_moves = int(loop.config.evaluate.max_moves)
        self.viewpoints_m = np.asarray(robot["viewpoints_m"], dtype=np.float64)
        self.camera_poses_world = np.asarray(robot["camera_pose_world"], dtype=np.float64)
        self.q_rad = np.asarray(robot["q_rad"], dtype=np.float64)
        self.centroid_m = np.asarray(centroid_m, dtype=np.float64)
        self.config: Config = loop.config
        self.declared_source = declared_source
        self._episode: _Episode | None = None

    @classmethod
    def load(cls, workspace: str | Path, method: str = "ra", threads: int | None = 1
             ) -> ActiveRecognizer:
        """The method ``method`` of the workspace ``workspace``, as its evaluate stage runs it.

        Args:
            workspace: a workspace folder whose stages up to ``solve`` (``learn`` for the
                learned baseline) have run; ``W/config.yaml`` is its configuration.
            method: a key of :data:`rapomdp.config.METHOD_NAMES`: "static", "random" or a
                method the solve stage solved ("ra", "classifier", "vptree"), or "learned".
            threads: PyTorch's CPU threads for the CNN (None: the project's default).

        Returns:
            The recogniser, waiting for :meth:`reset`. Its declared confidence is the one the
            evaluate stage fitted on its held-out closed loop where that stage has run, else
            the observe stage's walks' (``declared_source`` says which).
        """
        if method not in METHOD_NAMES:
            raise ValueError(f"method {method!r} is not one of {', '.join(METHOD_NAMES)}")
        ws = Workspace(workspace)
        config = ws.config()
        ran = ws.manifest()["stages"]
        finished = {name: ws.stage_dir(name) for name in LOOP_STAGES
                    if ran.get(name) and ws.stage_dir(name).is_dir()}
        inputs = StageInputs.of("evaluate", finished)
        declared_fit: dict[str, float] | None = None
        source = "walks"
        record = None
        if ran.get("evaluate") and ws.stage_dir("evaluate").is_dir():
            record = load_declared_fit(ws.stage_dir("evaluate"))
        if record is not None and method in record.get("methods", {}):
            fitted = record["methods"][method]["declared_confidence"]["temperature"]
            declared_fit, source = {method: float(fitted)}, "closed_loop"
        one = config.model_copy(update={"evaluate": config.evaluate.model_copy(
            update={"methods": [method]})})
        try:
            loop = ClosedLoop.load(one, inputs, threads=threads, declared_fit=declared_fit)
        except StageError as exc:
            raise StageError(f"{ws.root}: method {method!r} cannot run here: {exc}") from exc
        from rapomdp.robot.artefacts import load_robot

        robot = load_robot(inputs.robot)
        if "camera_pose_world" not in robot or "viewpoints_m" not in robot:
            raise StageError(f"{inputs.robot}: robot.npz lacks camera_pose_world or "
                             "viewpoints_m; run the robot stage again")
        policy = loop.methods[method]
        return cls(method, policy, loop.recognisers[policy.recogniser], loop, robot,
                   np.asarray(config.robot.centroid_m, dtype=np.float64), source)

    # -- the episode -------------------------------------------------------------------------

    def reset(self, seed: int | None = None, rng: np.random.Generator | None = None) -> None:
        """Start an episode: forget every view.

        Args:
            seed: seeds the method's draws (Random's moves); ignored when ``rng`` is given.
            rng: the generator the method draws from (the closed loop's ``episode_rng``
                reproduces an evaluate-stage episode).
        """
        self._episode = _Episode(rng if rng is not None else np.random.default_rng(seed))

    def nearest_viewpoint(self, camera_pose: np.ndarray) -> tuple[int, float]:
        """The viewpoint of X_rho whose camera centre is nearest a camera pose's.

        Args:
            camera_pose: (4, 4) camera-to-world, metres, the scene's world frame.

        Returns:
            (index, distance in metres from the pose's centre to the viewpoint's).
        """
        pose = np.asarray(camera_pose, dtype=np.float64)
        if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
            raise ValueError(f"a camera pose must be a finite (4, 4) matrix, got shape "
                             f"{pose.shape}")
        if not np.allclose(pose[3], [0.0, 0.0, 0.0, 1.0], atol=1e-6):
            raise ValueError(f"a camera pose's last row must be [0, 0, 0, 1], got "
                             f"{pose[3].tolist()}")
        gaps_m = np.linalg.norm(self.viewpoints_m - pose[:3, 3], axis=1)
        index = int(np.argmin(gaps_m))
        return index, float(gaps_m[index])

    def classify(self, depth: np.ndarray,
                 intrinsics: Intrinsics | Mapping[str, float] | None = None) -> np.ndarray:
        """The recogniser's class probabilities (C,) for one real depth image.

        Args:
            depth: (H, W) uint16 millimetres or float metres, any resolution; holes 0 or NaN.
            intrinsics: the image's focal lengths and principal point (see
                :func:`intrinsics_for`); the CNN sizes its crop in metres with fx, fy.

        Returns:
            (C,) float64 probabilities, columns in :attr:`classes`' order.
        """
        metres = depth_in_metres(depth)
        camera = intrinsics_for(metres, intrinsics)
        if isinstance(self.recogniser, Classifier):
            out = self.recogniser.predict(metres[None], fx_px=camera.fx, fy_px=camera.fy)
        else:  # the VP-tree's features assume the workspace camera
            out = self.recogniser.predict(metres[None])
        return np.array(out[0], dtype=np.float64)

    def observe(self, depth: np.ndarray, camera_pose: np.ndarray | None = None,
                intrinsics: Intrinsics | Mapping[str, float] | None = None,
                viewpoint: int | None = None) -> Observation:
        """Count one depth image: classify it and update the method's belief.

        Args:
            depth: (H, W) uint16 millimetres or float metres (see :func:`depth_in_metres`).
            camera_pose: (4, 4) camera-to-world where it was taken; mapped to the nearest
                viewpoint of X_rho (the answer's ``off_viewpoint_m`` says how far).
            intrinsics: the image's intrinsics (see :func:`intrinsics_for`).
            viewpoint: the viewpoint's index instead of ``camera_pose``.

        Returns:
            The :class:`Observation`: belief, declared class and confidence, whether it stops.
        """
        return self.observe_output(self.classify(depth, intrinsics), camera_pose, viewpoint)

    def observe_output(self, output: np.ndarray, camera_pose: np.ndarray | None = None,
                       viewpoint: int | None = None) -> Observation:
        """:meth:`observe` with the recogniser's output (C,) already computed (an image
        classified elsewhere, or a recogniser of one's own)."""
        episode = self._require_episode()
        if episode.step is not None and episode.step.action.is_declare:
            raise OutOfOrderError("episode_over", "the method has declared: reset to start "
                                  "the next episode")
        if (camera_pose is None) == (viewpoint is None):
            raise ValueError("give exactly one of camera_pose and viewpoint")
        if viewpoint is not None:
            views = self.viewpoints_m.shape[0]
            if isinstance(viewpoint, bool) or not 0 <= int(viewpoint) < views:
                raise ValueError(f"viewpoint {viewpoint} is not in [0, {views})")
            index, gap_m = int(viewpoint), 0.0
        else:
            index, gap_m = self.nearest_viewpoint(np.asarray(camera_pose))
        output = np.array(output, dtype=np.float64)
        if output.shape != (len(self.classes),) or not np.all(np.isfinite(output)):
            raise ValueError(f"the recogniser's output must be {len(self.classes)} finite "
                             f"probabilities, got shape {output.shape}")
        if not episode.started:  # the closed loop resets the method at its first image
            self.policy.reset(index, episode.rng)
            episode.started = True
        else:
            episode.moves += 1
        step = closed_loop_step(self.policy, index, output, episode.moves, self.max_moves)
        episode.step, episode.viewpoint = step, index
        episode.visited.append(index)
        declared = (int(step.action.target) if step.action.is_declare
                    else int(np.argmax(step.belief)))
        return Observation(index, gap_m, output, step.belief, declared, self.classes[declared],
                           float(step.belief[declared]), step.action.is_declare,
                           step.exhausted, episode.moves)

    def next_view(self) -> NextView:
        """Where to look next, or the declaration, by the last :meth:`observe`'s step.

        Returns:
            The :class:`NextView`; a move's pose, joints and energy come from the robot
            stage's IK solutions and E_M.
        """
        episode = self._require_episode()
        step = episode.step
        if step is None:
            raise OutOfOrderError("no_observation", "next_view needs an observe first")
        belief = step.belief
        if step.action.is_declare:
            k = int(step.action.target)
            nan_pose = np.full((4, 4), np.nan)
            return NextView("declare", -1, nan_pose, np.full(self.q_rad.shape[1], np.nan),
                            math.nan, math.nan, k, self.classes[k], float(belief[k]))
        target = int(step.action.target)
        energy_m, distance_m = self.motion.move(episode.viewpoint, target)
        k = int(np.argmax(belief))
        return NextView("move", target, self.camera_poses_world[target].copy(),
                        self.q_rad[target].copy(), energy_m, distance_m, k, self.classes[k],
                        float(belief[k]))

    def forget(self) -> None:
        """End the episode without a declaration: the next :meth:`observe` needs a
        :meth:`reset` (the server calls it when a client disconnects)."""
        self._episode = None

    @property
    def visited(self) -> list[int]:
        """The viewpoints observed this episode, in order."""
        return list(self._episode.visited) if self._episode is not None else []

    def info(self) -> dict[str, Any]:
        """What a robot program needs once: the method, the classes, X_rho and the frames."""
        return {
            "method": self.method,
            "method_name": METHOD_NAMES[self.method],
            "classes": list(self.classes),
            "viewpoints": int(self.viewpoints_m.shape[0]),
            "reachable": self.motion.reachable.astype(bool),
            "viewpoints_m": self.viewpoints_m,
            "camera_poses_world": self.camera_poses_world,
            "centroid_m": self.centroid_m,
            "camera_mount_xyz_m": np.asarray(self.config.robot.camera_mount_xyz_m, float),
            "camera_mount_rpy_deg": np.asarray(self.config.robot.camera_mount_rpy_deg, float),
            "max_moves": self.max_moves,
            "declared_confidence_from": self.declared_source,
        }

    def _require_episode(self) -> _Episode:
        if self._episode is None:
            raise OutOfOrderError("not_reset", "reset before the first observe")
        return self._episode
