"""A point-based POMDP solver in the manner of SARSOP (Kurniawati, Hsu & Lee, RSS 2008).

Both bounds are kept throughout, so the solver is anytime: the lower bound is the value of the
policy in hand, the upper bound says how far from optimal it can be. Each iteration samples one
trajectory from the initial belief, choosing the action with the best upper bound (this keeps
the samples near the beliefs the optimal policy reaches) and the observation with the largest
weighted excess gap p(o|b,a)·(U − L − ε γ^{-t}), as HSVI and SARSOP do; it stops where the gap
falls under ε γ^{-t}, with ε a fraction of the current gap at the root. Then it backs the
beliefs on the path up in reverse order, adding one alpha vector and one upper-bound point per
belief. Alpha vectors that are best at none of the sampled beliefs are pruned (SARSOP's
pruning over the sampled belief tree); redundant upper-bound points are dropped.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import numpy as np

from rapomdp.planning.bounds import (
    AlphaVectorSet,
    SawtoothUpperBound,
    blind_policy_alphas,
    fast_informed_bound,
    flat_solver_bytes,
)
from rapomdp.planning.memory import (
    DEFAULT_MEMORY_GB,
    ENTRY_BYTES,
    cap_bytes,
    check_memory,
    format_bytes,
)
from rapomdp.planning.policy import AlphaVectorPolicy
from rapomdp.planning.pomdp import POMDP
from rapomdp.planning.rules import (
    IMPROVEMENT_TOL,
    NEGLIGIBLE_PROBABILITY,
    POINT_IMPROVEMENT_TOL,
)


@dataclass(frozen=True)
class Progress:
    """One snapshot of an anytime solve: bounds at the initial belief and sizes.

    Attributes:
        elapsed: Seconds of the solver's clock since the solve began.
        lower: The lower bound (a policy's guaranteed value) at the initial belief.
        upper: The upper bound on the optimal value there.
        n_alpha: Lower-bound vectors held.
        n_points: Upper-bound points held.
        iterations: Sampling rounds so far.
    """

    elapsed: float
    lower: float
    upper: float
    n_alpha: int
    n_points: int
    iterations: int

    @property
    def gap(self) -> float:
        return self.upper - self.lower


ProgressCallback = Callable[[Progress], None]


PolicyT = TypeVar("PolicyT")


@dataclass
class SolveResult(Generic[PolicyT]):
    """What a solve returns: the policy (an :class:`AlphaVectorPolicy` from the flat solver,
    an ActiveRecognitionPolicy from the structured one), the final bounds and their history."""

    policy: PolicyT
    lower: float
    upper: float
    elapsed: float
    iterations: int
    converged: bool
    history: list[Progress] = field(default_factory=list)
    #: One line on the bounds used where a memory cap or the time budget bound (or "").
    note: str = ""


#: The clocks a solver's budget can run on: "process" (CPU time of this process, all its
#: threads; time asleep or waiting does not count) or "wall".
CLOCKS: dict[str, Callable[[], float]] = {
    "process": time.process_time,
    "wall": time.perf_counter,
}


#: Prune schedule of the flat solver: after 16 iterations, then at ⌊1.5·it⌋ + 1 (and after
#: every batched sweep of the lower bound).
FIRST_PRUNE, PRUNE_GROWTH = 16, 1.5


def check_budget(precision: float, timeout: float) -> None:
    """ValueError unless ``precision`` and ``timeout`` are positive finite numbers."""
    for name, value in (("precision", precision), ("timeout", timeout)):
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a positive finite number, got {value!r}")


class FlatSarsop:
    """SARSOP-style solver for a flat POMDP (dense arrays; beliefs over all states).

    The arrays it needs are estimated from the problem's sizes and refused with
    :class:`~rapomdp.planning.memory.MemoryCapError` when over ``memory_gb``; the initial
    bounds (blind policies, fast informed bound) are computed inside the solve's budget.
    """

    def __init__(self, pomdp: POMDP, memory_gb: float = DEFAULT_MEMORY_GB) -> None:
        self.pomdp = pomdp
        n_s, n_a, n_z = pomdp.n_states, pomdp.n_actions, pomdp.n_observations
        self.fixed_bytes = flat_solver_bytes(n_s, n_a, n_z)
        check_memory(f"the flat solver on {n_s} states x {n_a} actions x {n_z} observations",
                     self.fixed_bytes, memory_gb)
        self.cap = cap_bytes(memory_gb)
        self.clock: Callable[[], float] = time.process_time
        # trivial bounds until the solve computes the initial ones within its budget
        r = pomdp.R
        self.lower = AlphaVectorSet(np.full((n_a, n_s), r.min() / (1 - pomdp.discount)),
                                    np.arange(n_a))
        self.upper = SawtoothUpperBound(np.full(n_s, r.max() / (1 - pomdp.discount)))
        self.initialised = False
        self.sampled: list[np.ndarray] = [pomdp.initial_belief]
        # TZ[a, s, s', o] is too big in general; keep T and Z and combine per backup.

    def _initial_bounds(self, deadline: float) -> None:
        """Blind-policy alphas and the fast informed bound within a quarter and a third of
        the time to ``deadline`` (the rest is the trajectories'); each stops at its share."""
        p = self.pomdp
        now = self.clock()
        left = max(0.0, deadline - now)
        self.lower = AlphaVectorSet(blind_policy_alphas(p, now + left / 4, self.clock),
                                    np.arange(p.n_actions))
        fib = fast_informed_bound(p, deadline=now + left * 7 / 12, clock=self.clock)
        self.upper = SawtoothUpperBound(fib.max(axis=0))
        self.initialised = True

    def library_bytes(self) -> int:
        """Bytes of the alpha vectors (and their copies when pruned) and upper points."""
        n_s = self.pomdp.n_states
        return ENTRY_BYTES * (2 * len(self.lower) * n_s + 6 * len(self.upper) * n_s
                              + 2 * len(self.sampled) * n_s)

    # -- one belief ----------------------------------------------------------------------
    def _expand(self, b: np.ndarray) -> dict[str, np.ndarray]:
        """Children of b under every (a, o), both bounds there, and both backups at b."""
        p = self.pomdp
        g = p.discount
        tau = np.einsum("s,ast->at", b, p.T)  # (A, S')
        bao = tau[:, :, None] * p.Z  # (A, S', Zo), unnormalised children
        prob = bao.sum(axis=1)  # (A, Zo)
        # lower bound: best alpha at each child, and the backed-up vector per action
        scores = self.lower.alphas @ bao  # (A, N, Zo)
        best = scores.argmax(axis=1)  # (A, Zo)
        low_child = np.take_along_axis(scores, best[:, None, :], axis=1)[:, 0, :]
        G = self.lower.alphas[best]  # (A, Zo, S')
        gz = np.einsum("ato,aot->at", p.Z, G)
        alphas = p.R + g * np.einsum("ast,at->as", p.T, gz)  # (A, S)
        q_low = alphas @ b
        # upper bound at the normalised children
        n_a, n_z = prob.shape
        safe = np.where(prob > 0, prob, 1.0)
        children = (bao / safe[:, None, :]).transpose(0, 2, 1).reshape(n_a * n_z, -1)
        live = prob.reshape(-1) > NEGLIGIBLE_PROBABILITY
        up_child = np.zeros(n_a * n_z)
        up_child[live] = self.upper.values(children[live])
        up_child = up_child.reshape(n_a, n_z)
        q_up = p.R @ b + g * (prob * up_child).sum(axis=1)
        return {
            "prob": prob,
            "children": children.reshape(n_a, n_z, -1),
            "low_child": np.where(prob > 0, low_child / safe, 0.0),
            "up_child": up_child,
            "alphas": alphas,
            "q_low": q_low,
            "q_up": q_up,
        }

    def _backup(
        self, b: np.ndarray, ex: dict[str, np.ndarray] | None = None
    ) -> tuple[float, float]:
        """Point-based backup of both bounds at b; returns the new (lower, upper) at b."""
        ex = self._expand(b) if ex is None else ex
        a = int(np.argmax(ex["q_low"]))
        low_b = float(self.lower.values(b))
        if ex["q_low"][a] > low_b + POINT_IMPROVEMENT_TOL:
            self.lower.add(ex["alphas"][a], a)
            low_b = float(ex["q_low"][a])
        up_b = float(self.upper.values(b))
        q = float(ex["q_up"].max())
        if q < up_b - POINT_IMPROVEMENT_TOL:
            self.upper.add(b, q)
            up_b = q
        return low_b, up_b

    # -- the loop ------------------------------------------------------------------------
    def _trajectory(
        self,
        eps: float,
        max_depth: int,
        deadline: float,
        follow_lower: bool = False,
        rng: np.random.Generator | None = None,
    ) -> None:
        """One sampled trajectory from b0, then backups in reverse order.

        By default (SARSOP) the action is the upper bound's best and the observation the one
        with the largest weighted excess gap. With ``follow_lower`` the action is the current
        policy's and the observation is drawn from p(o | b, a): such trajectories visit the
        beliefs the policy in hand meets, where backups improve the lower bound fastest.
        """
        g = self.pomdp.discount
        path: list[tuple[np.ndarray, dict[str, np.ndarray], int, int]] = []
        b = self.pomdp.initial_belief
        for depth in range(max_depth):
            ex = self._expand(b)
            low_b, up_b = self._backup(b, ex)
            target = eps * g ** (-depth)
            if up_b - low_b <= target or self.clock() > deadline:
                path.append((b, ex, -1, -1))
                break
            if follow_lower and rng is not None:
                a = int(np.argmax(ex["q_low"]))
                pr = ex["prob"][a]
                o = int(rng.choice(pr.size, p=pr / pr.sum()))
                gap_o = ex["up_child"][a, o] - ex["low_child"][a, o]
                path.append((b, ex, a, o))
                if gap_o <= target / g:
                    break
            else:
                a = int(np.argmax(ex["q_up"]))
                excess = ex["prob"][a] * (ex["up_child"][a] - ex["low_child"][a] - target / g)
                o = int(np.argmax(excess))
                path.append((b, ex, a, o))
                if excess[o] <= 0:
                    break
            b = ex["children"][a, o]
        # Back up in reverse. The children's upper values cached on the way down stay valid
        # (the bound only decreases); only the child on the path is refreshed, which saves
        # re-interpolating the upper bound at every child. The lower backup is redone fully.
        child_upper: float | None = None
        for belief, ex, a, o in reversed(path):
            if self.clock() > deadline:  # fewer backups: both bounds stay valid
                break
            if a >= 0 and child_upper is not None:
                ex["up_child"][a, o] = min(ex["up_child"][a, o], child_upper)
                ex["q_up"][a] = self.pomdp.R[a] @ belief + self.pomdp.discount * float(
                    ex["prob"][a] @ ex["up_child"][a]
                )
            self._lower_refresh(belief, ex)
            _, child_upper = self._backup(belief, ex)
        self.sampled.extend(item[0] for item in path)

    def _lower_refresh(self, b: np.ndarray, ex: dict[str, np.ndarray]) -> None:
        """Recompute the lower-bound part of ``ex`` (best alphas at the children) in place."""
        p = self.pomdp
        tau = np.einsum("s,ast->at", b, p.T)
        bao = tau[:, :, None] * p.Z
        scores = self.lower.alphas @ bao
        best = scores.argmax(axis=1)
        G = self.lower.alphas[best]
        gz = np.einsum("ato,aot->at", p.Z, G)
        ex["alphas"] = p.R + p.discount * np.einsum("ast,at->as", p.T, gz)
        ex["q_low"] = ex["alphas"] @ b

    def solve(
        self,
        precision: float = 1e-3,
        timeout: float = 60.0,
        callback: ProgressCallback | None = None,
        report_every: float = 0.5,
        max_depth: int = 500,
        gap_fraction: float = 0.5,
        max_iterations: int | None = None,
        sweep_every: int = 1,
        policy_trajectories: bool = True,
        seed: int = 0,
        clock: str = "process",
    ) -> SolveResult[AlphaVectorPolicy]:
        """Improve both bounds until U − L ≤ ``precision`` at b0 or ``timeout`` seconds of
        ``clock`` pass ("process": CPU time of this process, the default; or "wall"). Every
        phase — initial bounds, trajectories, backups, sweeps — checks the deadline.

        Args:
            precision: The gap U − L at b0 at which it stops.
            timeout: Seconds of ``clock``.
            callback: Called with each history entry.
            report_every: Seconds between history entries.
            max_depth: The longest sampled trajectory (steps).
            gap_fraction: A trajectory's target gap, as a share of the current one.
            max_iterations: Stop after this many trajectories (None: no limit).
            sweep_every: Back up the lower bound at every sampled belief after this many
                trajectories (0: never).
            policy_trajectories: Alternate upper-bound-guided trajectories with ones that
                follow the lower bound's policy.
            seed: Seed of the sampled observations.
            clock: ``"process"`` or ``"wall"``.

        Returns:
            The alpha-vector policy, the bounds at b0, the seconds, the trajectories, whether
            the gap closed, the history, and a note when the memory cap stopped it.
        """
        check_budget(precision, timeout)
        self.clock = CLOCKS[clock]
        start = self.clock()
        deadline = start + timeout
        if not self.initialised:
            self._initial_bounds(deadline)
        note = ""
        b0 = self.pomdp.initial_belief
        history: list[Progress] = []
        it = 0
        last_report = -np.inf
        next_prune = FIRST_PRUNE
        rng = np.random.default_rng(seed)

        def snapshot() -> Progress:
            return Progress(
                self.clock() - start,
                float(self.lower.values(b0)),
                float(self.upper.values(b0)),
                len(self.lower),
                len(self.upper),
                it,
            )

        converged = False
        while True:
            snap = snapshot()
            converged = snap.gap <= precision
            now = self.clock()
            full = self.fixed_bytes + self.library_bytes() > self.cap
            if full:
                note = (f"stopped: {len(self.lower)} alpha vectors and {len(self.upper)} points "
                        f"fill the memory cap of {format_bytes(self.cap)}")
            done = (
                converged
                or full
                or now > deadline
                or (max_iterations is not None and it >= max_iterations)
            )
            if done or now - last_report >= report_every:
                history.append(snap)
                last_report = now
                if callback is not None:
                    callback(snap)
            if done:
                break
            eps = max(precision, gap_fraction * snap.gap)
            lower_turn = policy_trajectories and it % 2 == 1
            self._trajectory(eps, max_depth, deadline, lower_turn, rng)
            it += 1
            if self.clock() > deadline:  # the next snapshot ends the solve
                continue
            if it >= next_prune:
                self._prune()
                next_prune = int(it * PRUNE_GROWTH) + 1
            if sweep_every and it % sweep_every == 0:
                self._sweep_lower(np.vstack(self.sampled[::-1]), deadline)
                self._prune()
        # the policy keeps the vectors best at a sampled belief (duplicates change nothing)
        self.lower.prune(np.vstack(self.sampled))
        final = history[-1]
        policy = AlphaVectorPolicy(
            self.lower.alphas.copy(), self.lower.actions.copy(), self.pomdp.discount
        )
        return SolveResult(
            policy, final.lower, final.upper, final.elapsed, it, converged, history, note
        )

    def _sweep_lower(self, beliefs: np.ndarray, deadline: float = np.inf,
                     chunk: int = 4_000_000) -> int:
        """Batched point-based backup of the lower bound at many beliefs (a PBVI-style sweep
        over the sampled beliefs): cheap matrix products that spread values found deep in a
        trajectory to every sampled belief. Returns the number of vectors added."""
        p = self.pomdp
        n_a, n_s, n_z = p.Z.shape
        new_alphas: list[np.ndarray] = []
        new_actions: list[np.ndarray] = []
        # entries per belief: its children, their scores, and the A·S² products behind them
        # (a block is also the unit of time between deadline checks); vectors are appended
        # only after the loop, so the blocks do not change the result
        per = n_a * n_s * n_z + n_a * len(self.lower) * n_z + n_a * n_s * n_s
        step = max(1, chunk // per)
        for i in range(0, beliefs.shape[0], step):
            if self.clock() > deadline:
                break
            B = beliefs[i : i + step]  # (K, S)
            tau = np.einsum("ks,ast->kat", B, p.T)  # (K, A, S')
            bao = tau[:, :, :, None] * p.Z[None]  # (K, A, S', Zo)
            scores = np.einsum("ns,kaso->kano", self.lower.alphas, bao, optimize=True)
            best = scores.argmax(axis=2)  # (K, A, Zo)
            G = self.lower.alphas[best]  # (K, A, Zo, S')
            gz = np.einsum("ato,kaot->kat", p.Z, G)
            alphas = p.R[None] + p.discount * np.einsum("ast,kat->kas", p.T, gz)  # (K, A, S)
            q = np.einsum("kas,ks->ka", alphas, B)
            a = q.argmax(axis=1)
            improve = q[np.arange(len(B)), a] > self.lower.values(B) + IMPROVEMENT_TOL
            if improve.any():
                rows = np.flatnonzero(improve)
                new_alphas.append(alphas[rows, a[rows]])
                new_actions.append(a[rows])
        if not new_alphas:
            return 0
        alphas = np.vstack(new_alphas)
        self.lower.alphas = np.vstack([self.lower.alphas, alphas])
        self.lower.actions = np.concatenate([self.lower.actions, *new_actions])
        return alphas.shape[0]

    def _prune(self) -> None:
        beliefs = np.unique(np.vstack(self.sampled), axis=0)
        self.sampled = list(beliefs)
        self.lower.prune(beliefs)
        self.upper.prune()


def solve_pomdp(
    pomdp: POMDP,
    precision: float = 1e-3,
    timeout: float = 60.0,
    callback: ProgressCallback | None = None,
    memory_gb: float = DEFAULT_MEMORY_GB,
    **options: Any,
) -> SolveResult[AlphaVectorPolicy]:
    """Solve a flat POMDP with :class:`FlatSarsop` within ``timeout`` seconds of process CPU
    time and ``memory_gb``; see :meth:`FlatSarsop.solve`.

    Args:
        pomdp: The flat POMDP (:func:`~rapomdp.planning.io_pomdp.read_pomdp`).
        precision: The gap between the bounds at the initial belief at which it stops.
        timeout: Seconds of process CPU time.
        callback: Called with each :class:`Progress` snapshot.
        memory_gb: The memory cap in GB.
        **options: More settings of :meth:`FlatSarsop.solve`.

    Returns:
        The alpha-vector policy, the bounds at the initial belief, the seconds, the
        iterations, whether the gap closed and the history.

    Raises:
        MemoryCapError: The solver's arrays would exceed ``memory_gb``.

    Example:
        Tiger converges to the reference SARSOP's value (19.37) in well under a second::

            result = solve_pomdp(read_pomdp("tests/planning/data/Tiger.pomdp"), precision=0.01)
            result.converged, round(result.lower, 1)   # (True, 19.4)
            result.policy.act([0.5, 0.5])  # 0: listen first
    """
    check_budget(precision, timeout)
    return FlatSarsop(pomdp, memory_gb).solve(precision, timeout, callback, **options)
