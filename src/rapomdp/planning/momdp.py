"""The active-recognition problem as a MOMDP (paper Sec. 4.1, Eqs. 1-5).

A state is (viewpoint, class): the viewpoint is observed, the class hidden and constant. From
viewpoint v the robot may move to a reachable viewpoint j (reward −E_M[v, j], Eqs. 1 and 3),
where it observes the classifier's predicted label o with probability P[j, c, o]; or declare a
class k (reward −λ·[k ≠ c], Eq. 2) and stop in an absorbing terminal state worth 0. A belief
is therefore the pair (viewpoint, b) with b on the class simplex, and Eq. 5 reduces to
b'(c) ∝ P[j, c, o] b(c).

Array shapes (V viewpoints, C classes):

- ``observation_model`` (V, C, C): ``P[v, c, o]`` = P(predicted label o | class c, viewpoint v),
  rows over o sum to 1 (the observation stage's output). With T instance types (a per-object
  nuisance: a hidden type every view of one object shares) the hidden state is (type, class)
  at index τ·C + c and the model is (V, T·C, C): every view of one object shares its type,
  so the views are independent given (class, type), not given the class. A declaration
  names a class and is right in each of its types' states (:mod:`rapomdp.planning.rules`).
- ``move_energy`` (V, V): ``E[v, j]`` ≥ 0, the cost of moving from v to j and taking an image
  (the robot stage's E_M).
- ``reachable`` (V,) bool: viewpoints the arm can reach; only they are move targets.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from rapomdp.belief import class_marginal, update_beliefs
from rapomdp.geometry.viewsphere import fibonacci_directions, geodesic_distance_matrix
from rapomdp.planning.memory import DEFAULT_MEMORY_GB, ENTRY_BYTES, check_memory
from rapomdp.planning.pomdp import POMDP, PROB_TOL
from rapomdp.planning.rules import declare_value, move_or_declare

#: λ of Eq. 1 wherever none is given: the configuration's ``solve.wrong_declaration_cost_m``.
DEFAULT_LAMBDA = 8.0
#: λ of the synthetic family of ``pomdp-benchmarks/README.md`` (its declarations cost −10).
BENCHMARK_LAMBDA = 10.0


@dataclass
class ActiveRecognitionProblem:
    """The MOMDP's parts as arrays; see the module docstring for shapes.

    Validated when made (shapes, distributions, energies);
    :func:`build_active_recognition_problem` makes one from the stages' arrays.

    Attributes:
        observation_model: (V, S, C) P(label | hidden state, viewpoint).
        move_energy: (V, V) finite energies E_M in metres.
        reachable: (V,) bool: the move targets.
        lambda_: The cost of a wrong declaration (metres).
        discount: The discount factor.
        start_viewpoint: The first image's viewpoint.
        start_belief: (S,) the first belief (empty: uniform).
        allow_stay: Whether moving to the current viewpoint is an action.
        class_names: The classes' names.
    """

    observation_model: np.ndarray
    move_energy: np.ndarray
    reachable: np.ndarray
    lambda_: float = DEFAULT_LAMBDA
    discount: float = 0.95
    start_viewpoint: int = 0
    #: empty (the default) or None: uniform
    start_belief: np.ndarray = field(default_factory=lambda: np.zeros(0))
    allow_stay: bool = False
    class_names: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        P = np.asarray(self.observation_model, dtype=np.float64)
        E = np.asarray(self.move_energy, dtype=np.float64)
        reach = np.asarray(self.reachable, dtype=bool)
        if P.ndim != 3 or P.shape[2] == 0 or P.shape[1] % P.shape[2]:
            raise ValueError("observation_model must have shape (V, C, C), or (V, T*C, C) with "
                             f"T instance types, got {P.shape}")
        n_v, n_s, n_c = P.shape
        if n_c < 2:
            raise ValueError("the problem needs at least two classes")
        if not np.all(np.isfinite(P)) or np.any(P < 0):
            raise ValueError("observation_model has negative or non-finite probabilities")
        sums = P.sum(axis=2)
        if np.any(np.abs(sums - 1.0) > PROB_TOL):
            v, c = (int(i) for i in np.argwhere(np.abs(sums - 1.0) > PROB_TOL)[0])
            raise ValueError(
                f"observation_model[{v}, {c}, :] sums to {sums[v, c]:.6g}; rows must sum to 1"
            )
        if E.shape != (n_v, n_v):
            raise ValueError(f"move_energy must have shape ({n_v}, {n_v}), got {E.shape}")
        if not np.all(np.isfinite(E)) or np.any(E < 0):
            raise ValueError("move_energy must be finite and non-negative")
        if reach.shape != (n_v,):
            raise ValueError(f"reachable must have shape ({n_v},), got {reach.shape}")
        if not reach.any():
            raise ValueError("no viewpoint is reachable: the robot cannot take any image")
        if not 0.0 <= self.discount < 1.0:
            raise ValueError(f"discount must be in [0, 1), got {self.discount}")
        if self.lambda_ < 0:
            raise ValueError(f"lambda must be non-negative, got {self.lambda_}")
        if not 0 <= self.start_viewpoint < n_v:
            raise ValueError(f"start viewpoint {self.start_viewpoint} is not in [0, {n_v})")
        given = self.start_belief
        b0 = (
            np.full(n_s, 1.0 / n_s)
            if given is None or np.size(given) == 0
            else np.asarray(given, dtype=np.float64)
        )
        if b0.shape != (n_s,) or np.any(b0 < 0) or abs(b0.sum() - 1.0) > PROB_TOL:
            raise ValueError(f"start belief must be a distribution over {n_s} states")
        self.observation_model, self.move_energy, self.reachable = P, E, reach
        self.start_belief = b0 / b0.sum()
        if not self.class_names:
            self.class_names = [f"class{c}" for c in range(n_c)]

    @property
    def n_viewpoints(self) -> int:
        return self.observation_model.shape[0]

    @property
    def n_classes(self) -> int:
        """The classes (labels observed, classes declared)."""
        return self.observation_model.shape[2]

    @property
    def n_states(self) -> int:
        """Hidden states per viewpoint: the classes times the instance types."""
        return self.observation_model.shape[1]

    @property
    def types(self) -> int:
        """Instance types T (1: the hidden state is the class)."""
        return self.n_states // self.n_classes

    def state_class(self) -> np.ndarray:
        """The class (S,) of every hidden state."""
        return np.arange(self.n_states) % self.n_classes

    @property
    def targets(self) -> np.ndarray:
        """Indices of the move targets (the reachable viewpoints)."""
        return np.flatnonzero(self.reachable)

    def move_cost(self) -> np.ndarray:
        """(V, J) cost of moving from each viewpoint to each target; +inf where forbidden
        (staying put when ``allow_stay`` is off: the same image would be classified again)."""
        cost = self.move_energy[:, self.targets].copy()
        if not self.allow_stay:
            cost[self.targets, np.arange(self.targets.size)] = np.inf
        return cost

    def update(self, belief: np.ndarray, viewpoint: int, label: int) -> np.ndarray:
        """Eq. 5 for the MOMDP: b'(c) ∝ P[viewpoint, c, label] b(c)."""
        return update_beliefs(self.observation_model, belief, viewpoint, label)

    def declare_value(self, belief: np.ndarray) -> np.ndarray:
        """max_k −λ(1 − b_k) for beliefs (..., S), b the class marginal: the value of
        stopping now."""
        return declare_value(belief, self.lambda_, self.n_classes)


def build_active_recognition_problem(
    observation_model: np.ndarray,
    move_energy: np.ndarray,
    reachable: np.ndarray | None = None,
    lambda_: float = DEFAULT_LAMBDA,
    discount: float = 0.95,
    start_viewpoint: int = 0,
    start_belief: np.ndarray | None = None,
    allow_stay: bool = False,
    class_names: list[str] | None = None,
) -> ActiveRecognitionProblem:
    """The pipeline's entry point: the MOMDP from the observe and robot stages' arrays.

    ``move_energy`` may hold +inf for moves to or from an unreachable viewpoint, as the robot
    stage writes it: those moves are not actions, so the entries are replaced by the largest
    finite energy (``finite_move_energy``); inf between two reachable viewpoints, NaN or a
    negative energy is refused.

    Args:
        observation_model: (V, C, C) or (V, T·C, C) probabilities, rows summing to 1.
        move_energy: (V, V) energies E_M in metres (+inf allowed to or from an unreachable
            viewpoint).
        reachable: (V,) bool, or None for all.
        lambda_: The cost of a wrong declaration, in the energy's units (metres).
        discount: The discount factor in (0, 1].
        start_viewpoint: The viewpoint index of the first image.
        start_belief: (S,) the belief over the hidden states, or None for uniform.
        allow_stay: Whether moving to the current viewpoint is an action.
        class_names: The classes' names (for export and messages).

    Returns:
        The validated problem.

    Raises:
        ValueError: A shape, a probability or an energy is invalid (named).

    Example:
        >>> import numpy as np
        >>> from rapomdp.planning import build_active_recognition_problem
        >>> P = np.array([[[0.9, 0.1], [0.2, 0.8]],   # viewpoint 0: informative
        ...               [[0.6, 0.4], [0.4, 0.6]]])  # viewpoint 1: barely
        >>> E = np.array([[0.0, 1.0], [1.0, 0.0]])     # moving costs 1 m
        >>> problem = build_active_recognition_problem(P, E, lambda_=8.0, start_viewpoint=1)
        >>> problem.n_viewpoints, problem.n_classes, problem.targets.tolist()
        (2, 2, [0, 1])
        >>> problem.start_belief.tolist()
        [0.5, 0.5]
    """
    P = np.asarray(observation_model, dtype=np.float64)
    reach = np.asarray(np.ones(P.shape[0], dtype=bool) if reachable is None else reachable,
                       dtype=bool)
    return ActiveRecognitionProblem(
        P,
        finite_move_energy(move_energy, reach),
        np.asarray(reach, dtype=bool),
        float(lambda_),
        float(discount),
        int(start_viewpoint),
        np.zeros(0) if start_belief is None else np.asarray(start_belief, dtype=np.float64),
        allow_stay,
        list(class_names or []),
    )


#: The arrays of a problem file (``rapomdp pomdp export --problem``): the first two required.
PROBLEM_KEYS = ("observation_model", "move_energy", "reachable")


def load_problem_arrays(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """Read ``observation_model`` (V, C, C), ``move_energy`` (V, V) and optionally
    ``reachable`` (V,) from an ``.npz`` (no pickle); a clear ValueError when one is missing."""
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: cannot read problem arrays ({exc})") from None
    for key in PROBLEM_KEYS[:2]:
        if key not in arrays:
            raise ValueError(f"{path}: missing array {key!r} (has {sorted(arrays)})")
    return arrays


def finite_move_energy(move_energy: np.ndarray, reachable: np.ndarray) -> np.ndarray:
    """E_M with its +inf entries (moves to or from an unreachable viewpoint, never actions)
    replaced by the largest finite energy; NaN, negatives and inf between reachable viewpoints
    are refused (named)."""
    energy = np.array(move_energy, dtype=np.float64)
    reach = np.asarray(reachable, dtype=bool)
    if energy.ndim != 2 or energy.shape[0] != energy.shape[1] or energy.shape[0] != reach.size:
        raise ValueError(f"move_energy must have shape ({reach.size}, {reach.size}), got "
                         f"{energy.shape}")
    if np.isnan(energy).any() or (energy < 0).any():
        raise ValueError("move_energy has NaN or negative entries")
    infinite = np.isinf(energy)
    between_reachable = infinite & reach[:, None] & reach[None, :]
    if between_reachable.any():
        i, j = (int(k) for k in np.argwhere(between_reachable)[0])
        raise ValueError(f"move_energy[{i}, {j}] is infinite although viewpoints {i} and {j} "
                         "are both reachable")
    if infinite.any():
        finite = energy[~infinite]
        energy[infinite] = finite.max() if finite.size else 0.0
    return energy


def benchmark_problem(
    n_viewpoints: int,
    n_classes: int,
    seed: int = 0,
    lambda_: float = BENCHMARK_LAMBDA,
    discount: float = 0.95,
    memory_gb: float = DEFAULT_MEMORY_GB,
) -> ActiveRecognitionProblem:
    """A synthetic problem of the family in ``pomdp-benchmarks/README.md`` (seeded); refused
    with :class:`~rapomdp.planning.memory.MemoryCapError` before anything is allocated when its
    arrays would exceed ``memory_gb``.

    Viewpoints: a Fibonacci lattice on the upper unit hemisphere, starting at the one nearest
    the pole with a uniform belief; moving to j costs great-circle distance + 0.5 (moving to
    the current viewpoint included, as "move to viewpoint j" reads for every j); declaring is
    0 / −λ; the label is right with probability 0.3 + 0.6·f_c(j), else uniform over the other
    labels, where f_c is the larger of two von Mises bumps exp(κ(μ·v − 1)), κ ~ U[3, 8] and μ
    uniform on the hemisphere, drawn per class.

    Args:
        n_viewpoints: V.
        n_classes: C.
        seed: Seed of the class bumps.
        lambda_: The cost of a wrong declaration.
        discount: The discount factor.
        memory_gb: The memory cap in GB.

    Returns:
        The problem: (V, C, C) observation model, (V, V) move energy, every viewpoint
        reachable, staying allowed.

    Example:
        >>> problem = benchmark_problem(8, 3, seed=0)
        >>> problem.observation_model.shape, problem.move_energy.shape
        ((8, 3, 3), (8, 8))
    """
    # the distance matrix and its temporaries (V x V), the observation model (V x C x C)
    check_memory(f"the benchmark problem {n_viewpoints}x{n_classes}",
                 ENTRY_BYTES * (4 * n_viewpoints**2 + 3 * n_viewpoints * n_classes**2),
                 memory_gb)
    rng = np.random.default_rng(seed)
    dirs = fibonacci_directions(n_viewpoints, hemisphere=True)
    dist = geodesic_distance_matrix(dirs, radius_m=1.0)
    mu = rng.normal(size=(n_classes, 2, 3))
    mu /= np.linalg.norm(mu, axis=2, keepdims=True)
    mu[..., 2] = np.abs(mu[..., 2])
    kappa = rng.uniform(3.0, 8.0, size=(n_classes, 2))
    bumps = np.exp(kappa[None] * (np.einsum("vx,cbx->vcb", dirs, mu) - 1.0))  # (V, C, 2)
    acc = 0.3 + 0.6 * bumps.max(axis=2)  # (V, C)
    wrong = (1.0 - acc) / (n_classes - 1)
    P = np.broadcast_to(wrong[:, :, None], (n_viewpoints, n_classes, n_classes)).copy()
    idx = np.arange(n_classes)
    P[:, idx, idx] = acc
    return ActiveRecognitionProblem(
        P,
        dist + 0.5,
        np.ones(n_viewpoints, dtype=bool),
        lambda_,
        discount,
        start_viewpoint=0,
        allow_stay=True,
    )


#: Reward given in the flat model to the (forbidden) move to the current viewpoint.
FORBIDDEN_REWARD = -1e6


def to_flat_pomdp(problem: ActiveRecognitionProblem,
                  memory_gb: float = DEFAULT_MEMORY_GB) -> POMDP:
    """The same problem as a flat POMDP (for checks and for ``.pomdp`` export); refused with
    :class:`~rapomdp.planning.memory.MemoryCapError` before allocating when its dense arrays
    would exceed ``memory_gb``.

    States (v, s) at index v·S + s (s: the class, or (type, class) at τ·C + c), then one
    terminal state. Actions: move to each target, then declare each class. Observations
    (v, o) at v·C + o (the arrival viewpoint is observed with the label), then "done" in the
    terminal state. A forbidden stay costs ``FORBIDDEN_REWARD``.

    Args:
        problem: The MOMDP.
        memory_gb: The memory cap in GB.

    Returns:
        The flat POMDP with V·S + 1 states, J + C actions and V·C + 1 observations.

    Example:
        >>> import numpy as np
        >>> from rapomdp.planning import build_active_recognition_problem
        >>> P = np.array([[[0.9, 0.1], [0.2, 0.8]],   # viewpoint 0: informative
        ...               [[0.6, 0.4], [0.4, 0.6]]])  # viewpoint 1: barely
        >>> E = np.array([[0.0, 1.0], [1.0, 0.0]])     # moving costs 1 m
        >>> problem = build_active_recognition_problem(P, E, lambda_=8.0, start_viewpoint=1)
        >>> flat = to_flat_pomdp(problem)
        >>> flat.n_states, flat.action_names
        (5, ['move0', 'move1', 'declare_class0', 'declare_class1'])
    """
    P, n_v, n_c = problem.observation_model, problem.n_viewpoints, problem.n_classes
    n_h = problem.n_states
    targets = problem.targets
    n_s, n_j = n_v * n_h + 1, targets.size
    n_a, n_z = n_j + n_c, n_v * n_c + 1
    term = n_s - 1
    # T, Z and their copies in POMDP.from_arrays's checks
    check_memory(f"the flat POMDP of {n_v} viewpoints x {n_c} classes ({n_s} states, {n_a} "
                 "actions, dense)", ENTRY_BYTES * 2 * n_a * n_s * (n_s + n_z), memory_gb)
    v_of = np.repeat(np.arange(n_v), n_h)
    h_of = np.tile(np.arange(n_h), n_v)
    c_of = h_of % n_c
    T = np.zeros((n_a, n_s, n_s))
    R = np.zeros((n_a, n_s))
    cost = problem.move_cost()
    for a, j in enumerate(targets):
        T[a, np.arange(n_s - 1), j * n_h + h_of] = 1.0
        R[a, : n_s - 1] = np.where(np.isfinite(cost[v_of, a]), -cost[v_of, a], FORBIDDEN_REWARD)
    for k in range(n_c):
        T[n_j + k, :, term] = 1.0
        R[n_j + k, : n_s - 1] = -problem.lambda_ * (c_of != k)
    T[:, term, :] = 0.0
    T[:, term, term] = 1.0
    Z1 = np.zeros((n_s, n_z))
    rows = np.arange(n_s - 1)
    Z1[rows[:, None], (v_of * n_c)[:, None] + np.arange(n_c)[None, :]] = P[v_of, h_of]
    Z1[term, n_z - 1] = 1.0
    b0 = np.zeros(n_s)
    b0[problem.start_viewpoint * n_h : (problem.start_viewpoint + 1) * n_h] = problem.start_belief
    names = problem.class_names
    typed = [f"_t{h // n_c}" if problem.types > 1 else "" for h in h_of]
    return POMDP.from_arrays(
        T,
        np.broadcast_to(Z1, (n_a, n_s, n_z)).copy(),
        R,
        problem.discount,
        b0,
        state_names=[f"v{v}_{names[c]}{t}" for v, c, t in zip(v_of, c_of, typed, strict=True)]
        + ["done"],
        action_names=[f"move{j}" for j in targets] + [f"declare_{n}" for n in names],
        observation_names=[f"v{v}_{names[o]}" for v in range(n_v) for o in range(n_c)]
        + ["none"],
    )


@dataclass(frozen=True)
class SimulationResult:
    """Episodes of a policy on the model: discounted and plain returns, accuracy, steps."""

    discounted_return: np.ndarray  # (runs,)
    total_reward: np.ndarray  # (runs,)
    correct: np.ndarray  # (runs,) bool
    steps: np.ndarray  # (runs,) moves made

    def summary(self) -> dict[str, float]:
        n = self.discounted_return.size
        return {
            "mean_discounted_return": float(self.discounted_return.mean()),
            "stderr": float(self.discounted_return.std(ddof=1) / np.sqrt(n)) if n > 1 else 0.0,
            "mean_total_reward": float(self.total_reward.mean()),
            "accuracy": float(self.correct.mean()),
            "mean_steps": float(self.steps.mean()),
        }


def simulate_policy(
    problem: ActiveRecognitionProblem,
    policy: object,
    n_runs: int = 1000,
    seed: int = 0,
    max_steps: int = 200,
) -> SimulationResult:
    """Run ``policy`` (an ActiveRecognitionPolicy) on the model itself, all runs at once.

    The true hidden state (class, or type and class) is drawn from the start belief; each
    step the policy moves (the label is drawn from P[j, s, :]) or declares. An episode still
    running after ``max_steps`` counts as a wrong declaration then.

    Args:
        problem: The MOMDP the episodes run on.
        policy: An :class:`~rapomdp.planning.policy.ActiveRecognitionPolicy`.
        n_runs: Episodes.
        seed: Seed of the classes and labels drawn.
        max_steps: The most moves of an episode.

    Returns:
        Per episode: the discounted and plain returns, whether the declaration was right and
        the moves made (``summary()`` gives their means).

    Raises:
        TypeError: ``policy`` is not an ActiveRecognitionPolicy.

    Example:
        A policy's simulated return is close to its lower bound (the toy problem of
        :func:`~rapomdp.planning.ar_solver.solve_active_recognition`)::

            result = solve_active_recognition(problem)
            simulate_policy(problem, result.policy, n_runs=2000).summary()
            # {'mean_discounted_return': -2.09, ..., 'accuracy': 0.857, 'mean_steps': 1.0}
    """
    from rapomdp.planning.policy import ActiveRecognitionPolicy

    if not isinstance(policy, ActiveRecognitionPolicy):
        raise TypeError("policy must be an ActiveRecognitionPolicy")
    rng = np.random.default_rng(seed)
    n_c, lam, g = problem.n_classes, problem.lambda_, problem.discount
    P = problem.observation_model
    state = rng.choice(problem.n_states, size=n_runs, p=problem.start_belief)
    cls = state % n_c
    view = np.full(n_runs, problem.start_viewpoint)
    belief = np.broadcast_to(problem.start_belief, (n_runs, problem.n_states)).copy()
    disc_ret, total = np.zeros(n_runs), np.zeros(n_runs)
    correct, steps = np.zeros(n_runs, dtype=bool), np.zeros(n_runs, dtype=np.int64)
    active = np.ones(n_runs, dtype=bool)
    discount = np.ones(n_runs)
    for _ in range(max_steps):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        b = belief[idx]
        s = b @ policy.betas.T - policy.move_energy[view[idx]][:, policy.targets]
        _, m = move_or_declare(s, declare_value(b, lam, n_c))
        move_target = np.where(m >= 0, policy.targets[m] if len(policy.targets) else -1, -1)
        stop = move_target < 0
        # declarations
        d = idx[stop]
        k = class_marginal(belief[d], n_c).argmax(axis=1)
        r = np.where(k == cls[d], 0.0, -lam)
        disc_ret[d] += discount[d] * r
        total[d] += r
        correct[d] = k == cls[d]
        active[d] = False
        # moves
        mv, j = idx[~stop], move_target[~stop]
        r = -problem.move_energy[view[mv], j]
        disc_ret[mv] += discount[mv] * r
        total[mv] += r
        discount[mv] *= g
        steps[mv] += 1
        u = rng.random(mv.size)
        cdf = np.cumsum(P[j, state[mv]], axis=1)
        labels = np.minimum((u[:, None] > cdf).sum(axis=1), n_c - 1)
        belief[mv] = update_beliefs(P, belief[mv], j, labels)
        view[mv] = j
    if active.any():  # unfinished: charged as a wrong declaration
        a = np.flatnonzero(active)
        disc_ret[a] += discount[a] * -lam
        total[a] += -lam
    return SimulationResult(disc_ret, total, correct, steps)
