"""The episode simulator: a test model, a start viewpoint and a method, closed in a loop.

At each step the method either moves — the test model is rendered at the new viewpoint with the
configured sensor noise, the recogniser classifies the image and the method updates its belief —
or declares a class and the episode ends. Nothing here reads the ground truth: an
:class:`Episode` holds what the robot did and saw; :func:`score` alone compares it with the true
class.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from rapomdp.planning.policy import ARAction


class Recogniser(Protocol):
    """Anything that maps depth images (n, H, W) in metres to class probabilities (n, C)."""

    def predict(self, depth_images: np.ndarray) -> np.ndarray: ...


class Policy(Protocol):
    """A method of the closed loop. ``recogniser`` names the recogniser whose output it reads
    ("cnn" or "vptree"); the simulator calls ``reset`` once, then ``observe`` after every image
    and ``act`` after every ``observe``; ``belief`` is the method's current class distribution."""

    name: str
    recogniser: str

    def reset(self, start_viewpoint: int, rng: np.random.Generator) -> None: ...

    def observe(self, viewpoint: int, output: np.ndarray) -> None: ...

    @property
    def belief(self) -> np.ndarray: ...

    def act(self, viewpoint: int) -> ARAction: ...


@dataclass(frozen=True)
class Motion:
    """What moving costs: E_M (V, V) of Eq. 3, geodesic distances (V, V) and reachability (V,).

    A move to an unreachable viewpoint, or to the current one, is refused."""

    energy: np.ndarray
    distance_m: np.ndarray
    reachable: np.ndarray

    @classmethod
    def from_robot(cls, robot: dict[str, np.ndarray]) -> Motion:
        """From the robot stage's arrays (``rapomdp.robot.stage.load_robot``)."""
        return cls(robot["energy"], robot["distance_m"], robot["reachable"].astype(bool))

    @property
    def viewpoints(self) -> int:
        return int(self.reachable.size)

    def check_move(self, source: int, target: int) -> None:
        if not 0 <= target < self.viewpoints:
            raise ValueError(f"move to viewpoint {target}: not in [0, {self.viewpoints})")
        if not self.reachable[target]:
            raise ValueError(f"move to viewpoint {target}: the arm cannot reach it")
        if target == source:
            raise ValueError(f"move to viewpoint {target}: the camera is already there")

    def move(self, source: int, target: int) -> tuple[float, float]:
        """One closed-loop move, checked: its energy E_M[source, target] and its geodesic
        distance in metres (the episode simulator and the gymnasium environment both step
        through here)."""
        self.check_move(source, target)
        return float(self.energy[source, target]), float(self.distance_m[source, target])


@dataclass(frozen=True)
class Episode:
    """What happened, step by step: image t was taken at ``viewpoints[t]`` (t = 0 is the start),
    the recogniser returned ``outputs[t]`` (C,) and the method's belief became ``beliefs[t]``;
    move t (t ≥ 1) cost ``move_energy[t - 1]`` and ``move_distance_m[t - 1]``. The method then
    declared ``declared``; ``exhausted`` marks an episode stopped by the step budget."""

    viewpoints: np.ndarray  # (T + 1,)
    outputs: np.ndarray  # (T + 1, C)
    beliefs: np.ndarray  # (T + 1, C)
    move_energy: np.ndarray  # (T,)
    move_distance_m: np.ndarray  # (T,)
    declared: int
    exhausted: bool

    @property
    def moves(self) -> int:
        return int(self.move_energy.size)

    @property
    def actions(self) -> list[ARAction]:
        """The actions taken: each move, then the declaration."""
        moves = [ARAction("move", int(v)) for v in self.viewpoints[1:]]
        return [*moves, ARAction("declare", self.declared)]


class Scene(Protocol):
    """What the closed loop looks at: the sensor's depth image (H, W) from a viewpoint."""

    def look(self, viewpoint: int, rng: np.random.Generator) -> np.ndarray: ...


@dataclass(frozen=True)
class Step:
    """What the closed loop decides after one image: the method's ``belief`` (C,) after it
    (a copy), the ``action`` it takes (a move, or a declaration) and whether the step budget
    forced that declaration (``exhausted``)."""

    belief: np.ndarray
    action: ARAction
    exhausted: bool


def closed_loop_step(policy: Policy, viewpoint: int, output: np.ndarray, moves_made: int,
                     max_moves: int) -> Step:
    """One step of the closed loop, the one rule :func:`run_episode` and
    :class:`rapomdp.robot_api.ActiveRecognizer` both follow: the method updates its belief with
    the recogniser's ``output`` (C,) at ``viewpoint`` (Eq. 5; its visited set), then acts (its
    lookahead or walk, its stop rule); after ``max_moves`` moves (``moves_made`` so far) a
    move becomes the declaration of the belief's most likely class (the step budget).

    Args:
        policy: the method, reset at the episode's start.
        viewpoint: the index in X_rho the image was taken from.
        output: the recogniser's class probabilities (C,) for the image.
        moves_made: the moves made since the episode's first image.
        max_moves: the step budget (``evaluate.max_moves``).

    Returns:
        The :class:`Step`: belief, action, exhausted.
    """
    policy.observe(viewpoint, output)
    belief = np.array(policy.belief, dtype=np.float64)
    action = policy.act(viewpoint)
    if not action.is_declare and moves_made >= max_moves:
        return Step(belief, ARAction("declare", int(np.argmax(belief))), True)
    return Step(belief, action, False)


def run_episode(scene: Scene, recogniser: Recogniser, policy: Policy, motion: Motion,
                start_viewpoint: int, max_moves: int, rng: np.random.Generator,
                memo: dict[int, np.ndarray] | None = None) -> Episode:
    """One closed-loop episode from ``start_viewpoint``; after ``max_moves`` moves the method
    must declare its belief's most likely class (the step budget).

    ``memo`` (viewpoint → the recogniser's output there), when given, is read before rendering
    and filled after: pass one dict per (scene, recogniser) to all the episodes of a scene, and
    only where every look from a viewpoint sees the same image and draws nothing from ``rng``
    (a noiseless sensor, ``TestViews.noise.enabled`` false); the episodes are then the same as
    without it, each (viewpoint, recogniser) rendered and classified once.
    """
    if not motion.reachable[start_viewpoint]:
        raise ValueError(f"start viewpoint {start_viewpoint} is not reachable")
    policy.reset(start_viewpoint, rng)
    viewpoint = start_viewpoint
    views, outputs, beliefs, energy, distance = [], [], [], [], []
    while True:
        raw = memo.get(viewpoint) if memo is not None else None
        if raw is None:
            raw = recogniser.predict(scene.look(viewpoint, rng)[None])[0]
            if memo is not None:
                memo[viewpoint] = raw
        output = np.array(raw, dtype=np.float64)  # a copy: the method may keep it
        step = closed_loop_step(policy, viewpoint, output, len(energy), max_moves)
        views.append(viewpoint)
        outputs.append(output)
        beliefs.append(step.belief)
        action, exhausted = step.action, step.exhausted
        if action.is_declare:
            break
        move_energy, move_distance_m = motion.move(viewpoint, action.target)
        energy.append(move_energy)
        distance.append(move_distance_m)
        viewpoint = action.target
    return Episode(np.array(views), np.stack(outputs), np.stack(beliefs), np.array(energy),
                   np.array(distance), int(action.target), exhausted)


@dataclass(frozen=True)
class EpisodeScore:
    """The paper's Table 1 quantities for one episode."""

    correct: bool
    belief: float  # final belief in the true class
    moves: int
    distance_m: float
    energy: float


def score(episode: Episode, true_class: int) -> EpisodeScore:
    """The only place the ground truth is read."""
    return EpisodeScore(
        correct=episode.declared == true_class,
        belief=float(episode.beliefs[-1, true_class]),
        moves=episode.moves,
        distance_m=float(episode.move_distance_m.sum()),
        energy=float(episode.move_energy.sum()),
    )
