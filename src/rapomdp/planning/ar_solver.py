"""SARSOP-style solver for the active-recognition MOMDP, exploiting its structure.

Because the class never changes and the viewpoint is observed, a belief is (v, b) with b on the
|C|-simplex, and the value function is one convex function of b per viewpoint. Three facts make
it cheap:

* Moving to j costs E[v, j] whatever the class, so the value of "move to j, then act" is
  β·b − E[v, j] with β independent of the viewpoint v we leave. One lower-bound backup at b
  therefore yields plans for *every* viewpoint at once: the solver keeps one library of
  vectors β_m (each tagged with its target j_m) and the set for viewpoint v is
  {β_m − E[v, j_m]} plus the declare vectors −λ(1 − e_k). Likewise one upper-bound backup at b
  gives an upper value for every viewpoint: the points are beliefs b_i with a value per
  viewpoint U_i[v].
* The upper bound starts from a grid bound where the grid is affordable (few classes; see
  :mod:`rapomdp.planning.grid_bound`): value iteration on a Freudenthal grid over the simplex,
  interpolated — far tighter than the trivial corners (0 where the class is known). Points
  added by backups refine it by sawtooth interpolation: U(v, b) = min(0, grid(v, b),
  min_i φ_i(b) U_i[v]), φ_i(b) = min_c b(c)/b_i(c).
* Where the labels' confusion is "right with probability a_j(c), else the same probability
  w_j(c) for each wrong label" (the synthetic family), a child is b ⊙ w_j plus one bump at the
  observed label, so dot products with the library and sawtooth ratios at all |C| children of
  a move cost O(|C|) instead of O(|C|²). General confusion matrices take the plain path.

Sampling: trajectories from (v0, b0) guided by the upper bound (the action with the best
upper value, the label with the largest weighted excess gap, as HSVI / SARSOP) with
reverse-order backups of both bounds; alternately, a batch of episodes of the policy in hand
with sampled classes and labels, whose beliefs are backed up (lower bound, deepest step
first) so the plans improve where the policy actually goes. Library vectors best at none of
the visited (belief, viewpoint) pairs are pruned. All clocks (time limit, checkpoints,
``Progress.elapsed``) use ``clock`` ("process": CPU time of this process, or "wall").
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from rapomdp.belief import class_marginal, update_beliefs
from rapomdp.planning.ar_children import MoveChildren, min_ratio
from rapomdp.planning.ar_memory import (
    KEEP_PAIRS,
    fit_chunk,
    grid_resolutions,
    plan_grid,
    plan_library,
    working_bytes,
)
from rapomdp.planning.grid_bound import GridUpperBound, grid_entries, grid_upper_bound
from rapomdp.planning.memory import DEFAULT_MEMORY_GB, cap_bytes
from rapomdp.planning.momdp import ActiveRecognitionProblem
from rapomdp.planning.policy import ActiveRecognitionPolicy
from rapomdp.planning.rules import (
    BELIEF_DECIMALS,
    EQUAL_TOL,
    IMPROVEMENT_TOL,
    declare_alphas,
    declare_value,
    move_or_declare,
    unnormalised_declare_value,
)
from rapomdp.planning.sarsop import CLOCKS, Progress, ProgressCallback, SolveResult, check_budget

#: Prune schedule: first after this many iterations, then at iteration ⌊1.3·it⌋ + 4, and
#: whenever the library has grown past 2 × its size after the last pruning + 256 vectors.
FIRST_PRUNE, PRUNE_GROWTH, PRUNE_STEP = 8, 1.3, 4
LIBRARY_GROWTH, LIBRARY_SLACK = 2, 256


class ActiveRecognitionSolver:
    """Point-based solver with one shared library of continuation vectors over the simplex.

    One backup serves every viewpoint (the module docstring says why); every structure is
    sized against ``memory_gb`` before it is allocated (:mod:`rapomdp.planning.ar_memory`).
    :func:`solve_active_recognition` makes one, with the same arguments, and solves; a
    problem whose smallest working blocks exceed the cap raises
    :class:`~rapomdp.planning.memory.MemoryCapError`.
    """

    def __init__(
        self,
        problem: ActiveRecognitionProblem,
        chunk: int = 2_000_000,
        grid: bool | int = True,
        grid_entries: int = 12_000_000,
        memory_gb: float = DEFAULT_MEMORY_GB,
    ) -> None:
        self.problem = problem
        self.targets = problem.targets  # (J,) viewpoint index of each move target
        # beliefs live on the simplex of the hidden states (the classes, or (type, class));
        # declarations read their class marginal (rules.declare_value with n_classes)
        n_c, n_v, n_j = problem.n_states, problem.n_viewpoints, problem.targets.size
        self.n_classes = problem.n_classes
        self.memory_gb = memory_gb
        self.chunk = fit_chunk(chunk, n_v, n_j, n_c, cap_bytes(memory_gb))
        self.cost = problem.move_cost()  # (V, J)
        self.cost_tt = self.cost[self.targets]  # (J, J): from a target to a target
        self.min_cost = self.cost.min(axis=1)  # (V,) a move costs at least this much
        self.moves = MoveChildren(
            np.ascontiguousarray(problem.observation_model[self.targets].transpose(0, 2, 1))
        )
        self.lam = problem.lambda_
        self.g = problem.discount
        self.betas = np.zeros((0, n_c))
        self.slots = np.zeros(0, dtype=np.int64)  # target slot (index into targets) of β
        self.up_points = np.zeros((0, n_c))
        self.up_inv = np.zeros((0, n_c))
        self.up_off = np.zeros((0, n_c))
        self.up_values = np.zeros((0, n_v))
        self.grid: GridUpperBound | None = None
        self.grid_option = grid
        self.grid_entries = grid_entries
        # visited (belief, viewpoint) pairs: pruning keeps the vectors best at one of them
        self.visited_b: list[np.ndarray] = [problem.start_belief[None]]
        self.visited_v: list[np.ndarray] = [np.array([problem.start_viewpoint])]
        self.clock: Callable[[], float] = time.process_time
        self.deadline = np.inf
        shape = (n_v, n_c, n_j, problem.n_classes)
        self.max_resolution, grid_note = plan_grid(shape, self.chunk, memory_gb, grid,
                                                   grid_entries)
        self.max_vectors, self.max_points = plan_library(shape, self.chunk, memory_gb,
                                                         self.max_resolution)
        self.notes: list[str] = [grid_note]

    #: Bytes of the fixed arrays and working blocks before any library
    #: (:func:`rapomdp.planning.ar_memory.working_bytes`).
    working_bytes = staticmethod(working_bytes)

    # -- bounds --------------------------------------------------------------------------
    def lower_values(self, beliefs: np.ndarray) -> np.ndarray:
        """Lower bound (K, V) at beliefs (K, S) for every viewpoint."""
        B = np.atleast_2d(beliefs)
        dec = declare_value(B, self.lam, self.n_classes)
        out = np.repeat(dec[:, None], self.problem.n_viewpoints, axis=1)
        if len(self.slots):
            step = max(1, self.chunk // (len(self.slots) * self.problem.n_viewpoints))
            cost = self.cost[:, self.slots]
            for i in range(0, B.shape[0], step):
                s = B[i : i + step] @ self.betas.T  # (k, M)
                moves = (s[:, None, :] - cost[None]).max(axis=2)
                out[i : i + step] = np.maximum(out[i : i + step], moves)
        return out

    def _lower_at(self, B: np.ndarray, views: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lower bound at pairs (B[k], views[k]) and the chosen target slot (−1: declare)."""
        dec = declare_value(B, self.lam, self.n_classes)
        if not len(self.slots):
            return dec, np.full(B.shape[0], -1)
        s = B @ self.betas.T - self.cost[views][:, self.slots]  # (K, M)
        value, m = move_or_declare(s, dec)
        return value, np.where(m >= 0, self.slots[m], -1)

    def _sawtooth(self, beliefs: np.ndarray) -> np.ndarray:
        """Sawtooth part (K, V) of the upper bound (0 without points)."""
        n = self.up_points.shape[0]
        K, n_c = beliefs.shape
        out = np.zeros((K, self.problem.n_viewpoints))
        if n == 0:
            return out
        step = max(1, self.chunk // max(1, n * max(n_c, self.problem.n_viewpoints)))
        for i in range(0, K, step):
            phi = min_ratio(beliefs[i : i + step], self.up_inv, self.up_off)  # (k, N)
            out[i : i + step] = np.minimum(0.0, (phi[:, :, None] * self.up_values[None]).min(1))
        return out

    def upper_values(self, beliefs: np.ndarray) -> np.ndarray:
        """Upper bound (K, V) at beliefs (K, S) for every viewpoint."""
        B = np.atleast_2d(beliefs)
        out = self._sawtooth(B)
        dec = declare_value(B, self.lam, self.n_classes)
        out = np.minimum(out, np.maximum(dec[:, None], -self.min_cost[None]))
        if self.grid is not None:
            out = np.minimum(out, self.grid.evaluate(B))
        return out

    # -- children ------------------------------------------------------------------------
    def _child_lower(self, B: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Best plan at every child of B (K, S): probabilities (K, J, O), unnormalised values
        (K, J, O) and the alpha vectors used (K, J, O, S)."""
        u = self.moves.unnormalised(B)
        prob = u.sum(axis=3)
        marginal = class_marginal(u, self.n_classes)  # (K, J, O, C)
        kstar = marginal.argmax(axis=3)
        umax = np.take_along_axis(marginal, kstar[..., None], axis=3)[..., 0]
        value = -self.lam * (prob - umax)  # unnormalised_declare_value, u's sum and max reused
        n_c = B.shape[1]
        n_m = len(self.slots)
        choice = np.full(prob.shape, -1)
        if n_m:
            K, n_j, n_o = prob.shape
            cost = self.cost_tt[:, self.slots]  # (J, M)
            step = max(1, self.chunk // (K * n_j * n_o))
            for i in range(0, n_m, step):
                blk = slice(i, min(n_m, i + step))
                s = self.moves.dots(B, self.betas[blk])
                s -= prob[..., None] * cost[None, :, None, blk]
                m = s.argmax(axis=3)
                best = np.take_along_axis(s, m[..., None], axis=3)[..., 0]
                better = best > value
                value = np.where(better, best, value)
                choice = np.where(better, m + i, choice)
        alpha = declare_alphas(kstar, self.lam, n_c, self.n_classes)
        use = choice >= 0
        if use.any():
            jj = np.broadcast_to(np.arange(prob.shape[1])[None, :, None], prob.shape)[use]
            mm = choice[use]
            alpha[use] = self.betas[mm] - self.cost_tt[jj, self.slots[mm]][:, None]
        return prob, value, alpha

    def _child_upper(self, B: np.ndarray, prob: np.ndarray) -> np.ndarray:
        """Unnormalised upper bound prob · U(targets[a], child) at every child: (K, J, O)."""
        K, n_j, n_o = prob.shape
        # one step: declaring, or a move (≥ the cheapest) followed by at most 0
        step_cost = self.min_cost[self.targets][None, :, None]
        out = np.maximum(unnormalised_declare_value(self.moves.unnormalised(B), self.lam,
                                                    self.n_classes),
                         -prob * step_cost)
        n = self.up_points.shape[0]
        if n:
            vals = self.up_values[:, self.targets].T  # (J, N)
            step = max(1, self.chunk // (K * n_j * n_o))
            for i in range(0, n, step):
                blk = slice(i, min(n, i + step))
                ph = self.moves.phi(B, self.up_inv[blk], self.up_off[blk])  # (K, J, O, n)
                out = np.minimum(out, (ph * vals[None, :, None, blk]).min(axis=3))
        if self.grid is not None:
            u = self.moves.unnormalised(B)
            safe = np.where(prob > 0, prob, 1.0)
            ch = (u / safe[..., None]).reshape(-1, B.shape[1])
            views = np.broadcast_to(self.targets[None, :, None], prob.shape).ravel()
            g = self.grid.evaluate(ch, views).reshape(prob.shape)
            out = np.minimum(out, g * prob)
        return out

    # -- backups -------------------------------------------------------------------------
    def backup(
        self, B: np.ndarray, views: np.ndarray | None = None, upper: bool = True
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Back up the beliefs B (K, C): add the plan that improves most at (B[k], views[k])
        (at every viewpoint where it improves when ``views`` is None) and, if ``upper``, an
        upper point with values for every viewpoint. Returns the lower bound (K, V) after and
        the children's bounds (``prob``, ``low``, ``up`` unnormalised (K, J, O))."""
        prob, low_u, alpha = self._child_lower(B)
        betas = self.g * self.moves.backup(alpha)  # (K, J, C)
        q_low = np.einsum("kjc,kc->kj", betas, B)
        cand = q_low[:, None, :] - self.cost[None]  # (K, V, J)
        best_a = cand.argmax(axis=2)
        best = np.take_along_axis(cand, best_a[..., None], axis=2)[..., 0]
        old_low = self.lower_values(B)
        better = best > old_low + IMPROVEMENT_TOL
        if views is not None:
            mask = np.zeros_like(better)
            mask[np.arange(B.shape[0]), views] = True
            better &= mask
        if better.any():
            kk, vv = np.nonzero(better)
            pairs = np.unique(np.stack([kk, best_a[kk, vv]], axis=1), axis=0)
            self.betas = np.vstack([self.betas, betas[pairs[:, 0], pairs[:, 1]]])
            self.slots = np.concatenate([self.slots, pairs[:, 1]])
        info: dict[str, np.ndarray] = {"prob": prob, "low": low_u}
        if upper:
            up_u = self._child_upper(B, prob)
            q_up = self.g * up_u.sum(axis=2)  # (K, J)
            dec = declare_value(B, self.lam, self.n_classes)
            new_up = np.maximum(dec[:, None], (q_up[:, None, :] - self.cost[None]).max(axis=2))
            old_up = self.upper_values(B)
            up = np.minimum(old_up, new_up)
            improved = np.any(new_up < old_up - IMPROVEMENT_TOL, axis=1)
            if improved.any() and self.up_points.shape[0] < self.max_points:
                self._add_points(B[improved], up[improved])
            info.update(up=up_u, q_up=q_up)
        return np.maximum(old_low, best), info

    def _add_points(self, beliefs: np.ndarray, values: np.ndarray) -> None:
        """Append upper-bound points (k, C) with their values per viewpoint (k, V), at once."""
        support = beliefs > 0
        inverse = np.where(support, 1.0 / np.where(support, beliefs, 1.0), 0.0)
        self.up_points = np.vstack([self.up_points, beliefs])
        self.up_inv = np.vstack([self.up_inv, inverse])
        self.up_off = np.vstack([self.up_off, np.where(support, 0.0, np.inf)])
        self.up_values = np.vstack([self.up_values, values])

    # -- sampling ------------------------------------------------------------------------
    def _trajectory(self, eps: float, max_depth: int) -> None:
        """One upper-bound-guided trajectory from (v0, b0), then reverse-order backups."""
        v, b = self.problem.start_viewpoint, self.problem.start_belief
        path: list[tuple[int, np.ndarray]] = []
        for depth in range(max_depth):
            path.append((v, b))
            if self.clock() > self.deadline:
                break
            B = b[None]
            prob, low_u, _ = self._child_lower(B)
            up_u = self._child_upper(B, prob)
            q_up = self.g * up_u[0].sum(axis=1) - self.cost[v]  # (J,)
            dec = float(declare_value(b, self.lam, self.n_classes))
            up_here = min(float(self.upper_values(B)[0, v]), max(dec, float(q_up.max())))
            low_here = float(self.lower_values(B)[0, v])
            target = eps * self.g ** (-depth)
            if up_here - low_here <= target:
                break
            a = int(np.argmax(q_up))
            if q_up[a] <= dec:
                break
            excess = up_u[0, a] - low_u[0, a] - prob[0, a] * target / self.g
            o = int(np.argmax(excess))
            if excess[o] <= 0:
                break
            v, b = int(self.targets[a]), self.moves.Pj[a, o] * b / prob[0, a, o]
        for view, belief in reversed(path):
            if self.clock() > self.deadline:  # the bounds stay valid with fewer backups
                break
            self.backup(belief[None], np.array([view]), upper=True)
        self._visit(np.array([p[1] for p in path]), np.array([p[0] for p in path]))

    def _policy_batch(self, rng: np.random.Generator, n_runs: int, max_steps: int) -> None:
        """Episodes of the policy in hand (sampled classes and labels); back up the beliefs
        it reaches, deepest step first (lower bound only)."""
        pb = self.problem
        n_o = pb.n_classes
        cls = rng.choice(pb.n_states, size=n_runs, p=pb.start_belief)  # hidden states
        views = np.full(n_runs, pb.start_viewpoint)
        B = np.broadcast_to(pb.start_belief, (n_runs, pb.n_states)).copy()
        steps: list[np.ndarray] = []
        step_v: list[np.ndarray] = []
        all_b, all_v = [], []
        for _ in range(max_steps):
            _, slot = self._lower_at(B, views)
            go = slot >= 0
            if not go.any():
                break
            B, views, cls, slot = B[go], views[go], cls[go], slot[go]
            all_b.append(B)
            all_v.append(views)
            j = self.targets[slot]
            like = pb.observation_model[j, cls]  # (k, O)
            u = rng.random(j.size)
            labels = np.minimum((u[:, None] > np.cumsum(like, axis=1)).sum(axis=1), n_o - 1)
            B = update_beliefs(pb.observation_model, B, j, labels)
            views = j
            steps.append(B)
            step_v.append(views)
        for Bs, vs in zip(reversed(steps), reversed(step_v), strict=True):
            key = np.concatenate([np.round(Bs, BELIEF_DECIMALS), vs[:, None]], axis=1)
            _, first = np.unique(key, axis=0, return_index=True)
            Bs, vs = Bs[first], vs[first]
            # a belief's children (J, O, C) and their dot products with the library
            per = len(self.targets) * Bs.shape[1] * (1 + len(self.slots) + Bs.shape[1])
            step = max(1, self.chunk // per)
            for i in range(0, Bs.shape[0], step):
                if self.clock() > self.deadline:
                    return
                self.backup(Bs[i : i + step], vs[i : i + step], upper=False)
        if all_b:
            self._visit(np.vstack(all_b), np.concatenate(all_v))

    def _visit(self, B: np.ndarray, views: np.ndarray) -> None:
        self.visited_b.append(np.atleast_2d(B))
        self.visited_v.append(np.atleast_1d(views))

    def prune(self, keep_pairs: int = KEEP_PAIRS) -> None:
        """Drop library vectors best at no visited (belief, viewpoint) pair."""
        B = np.vstack(self.visited_b)[-keep_pairs:]
        views = np.concatenate(self.visited_v)[-keep_pairs:]
        key = np.concatenate([np.round(B, BELIEF_DECIMALS), views[:, None]], axis=1)
        _, first = np.unique(key, axis=0, return_index=True)
        B, views = B[first], views[first]
        self.visited_b, self.visited_v = [B], [views]
        n_m = len(self.slots)
        if not n_m:
            return
        used = np.zeros(n_m, dtype=bool)
        step = max(1, self.chunk // n_m)
        for i in range(0, B.shape[0], step):
            blk, vb = B[i : i + step], views[i : i + step]
            s = blk @ self.betas.T - self.cost[vb][:, self.slots]
            _, m = move_or_declare(s, declare_value(blk, self.lam, self.n_classes))
            used[m[m >= 0]] = True
        self.betas, self.slots = self.betas[used], self.slots[used]

    # -- the grid ------------------------------------------------------------------------
    def _build_grid(self, until: float) -> None:
        """Grid upper bounds of growing resolution, up to the one the memory plan allows,
        while the time extrapolated from the previous one fits before ``until``."""
        pb = self.problem
        n_c, n_j = pb.n_states, len(self.targets)
        last_cost, last_entries = 0.0, 0
        for res in grid_resolutions(self.grid_option):
            if res > self.max_resolution:
                break
            entries = grid_entries(res, n_c, n_j, pb.n_classes)
            now = self.clock()
            if last_entries and now + 1.5 * last_cost * entries / last_entries > until:
                break
            if now > until:
                break
            grid = grid_upper_bound(
                pb.observation_model, self.cost, self.targets, self.lam, self.g, res,
                deadline=until, clock=self.clock, tol=1e-5, initial=self.grid,
            )
            if grid.sweeps == 0:
                break
            self.grid = grid
            last_cost, last_entries = self.clock() - now, entries

    def policy(self) -> ActiveRecognitionPolicy:
        """The lower-bound policy, with the upper bound attached."""
        full = np.full((self.problem.n_viewpoints, self.problem.n_viewpoints), np.inf)
        full[:, self.targets] = self.cost
        return ActiveRecognitionPolicy(
            self.betas.copy(),
            self.targets[self.slots].copy(),
            full,
            self.lam,
            self.g,
            self.up_points.copy(),
            self.up_values.copy(),
            self.n_classes,
        )

    def solve(
        self,
        precision: float = 1e-3,
        timeout: float = 30.0,
        callback: ProgressCallback | None = None,
        report_every: float = 0.5,
        max_depth: int = 60,
        gap_fraction: float = 0.5,
        max_iterations: int | None = None,
        policy_trajectories: bool = True,
        seed: int = 0,
        checkpoints: tuple[float, ...] = (),
        clock: str = "process",
        grid_share: float = 0.3,
        policy_runs: int = 16,
    ) -> SolveResult[ActiveRecognitionPolicy]:
        """Improve both bounds at (v0, b0) until their gap ≤ ``precision`` or ``timeout`` s
        of ``clock`` ("process": CPU time, or "wall").

        ``checkpoints`` (seconds) force a history entry as soon as each is passed. Up to
        ``grid_share`` of the time goes to the grid upper bound (where affordable).

        Args:
            precision: The gap upper − lower at the start at which it stops (value units:
                metres of movement energy, as λ).
            timeout: Seconds of ``clock``.
            callback: Called with each history entry.
            report_every: Seconds between history entries.
            max_depth: The longest sampled trajectory (steps).
            gap_fraction: A trajectory's target gap, as a share of the current one.
            max_iterations: Stop after this many sampling rounds (None: no limit).
            policy_trajectories: Alternate bound-guided trajectories with batches of episodes
                of the policy in hand.
            seed: Seed of the sampled classes and labels.
            checkpoints: Seconds at which a history entry is forced.
            clock: ``"process"`` (CPU time of this process) or ``"wall"``.
            grid_share: The share of ``timeout`` the grid upper bound may take.
            policy_runs: Episodes per policy batch.

        Returns:
            The lower-bound policy, the final bounds at the start, the seconds, the sampling
            rounds, whether the gap closed, the history and the note on the bounds used.
        """
        check_budget(precision, timeout)
        self.clock = CLOCKS[clock]
        start = self.clock()
        self.deadline = start + timeout
        v0, b0 = self.problem.start_viewpoint, self.problem.start_belief
        rng = np.random.default_rng(seed)
        history: list[Progress] = []
        it, next_prune, last, pruned, full = 0, FIRST_PRUNE, -np.inf, 0, False
        pending = sorted(checkpoints)
        self._build_grid(start + grid_share * timeout)
        while True:
            now = self.clock()
            snap = Progress(
                now - start,
                float(self.lower_values(b0[None])[0, v0]),
                float(self.upper_values(b0[None])[0, v0]),
                len(self.slots),
                self.up_points.shape[0],
                it,
            )
            converged = snap.gap <= precision
            done = converged or full or now > self.deadline or (
                max_iterations is not None and it >= max_iterations
            )
            hit = bool(pending) and snap.elapsed >= pending[0]
            while pending and snap.elapsed >= pending[0]:
                pending.pop(0)
            if done or hit or now - last >= report_every:
                history.append(snap)
                last = now
                if callback is not None:
                    callback(snap)
            if done:
                break
            eps = max(precision, gap_fraction * snap.gap)
            if policy_trajectories and it % 2 == 1:
                self._policy_batch(rng, policy_runs, max_depth)
            else:
                self._trajectory(eps, max_depth)
            it += 1
            if it >= next_prune or len(self.slots) > LIBRARY_GROWTH * pruned + LIBRARY_SLACK:
                self.prune()
                next_prune = int(it * PRUNE_GROWTH) + PRUNE_STEP
                pruned = len(self.slots)
                if pruned > self.max_vectors:
                    self.notes.append(
                        f"stopped: {pruned} lower-bound vectors fill the memory cap's share")
                    full = True
        # the policy file's sawtooth carries the reported upper bound at the start
        up0 = self.upper_values(b0[None])[0]
        if np.any(up0 < self._sawtooth(b0[None])[0] - EQUAL_TOL):
            self._add_points(b0[None], np.asarray(up0)[None])
        self.prune()
        if self.up_points.shape[0] >= self.max_points:
            self.notes.append(f"upper-bound points capped at {self.max_points} by memory")
        if self.grid is not None:
            self.notes.append(f"grid reached resolution {self.grid.grid.n}")
        final = history[-1]
        return SolveResult(
            self.policy(), final.lower, final.upper, final.elapsed, it, converged, history,
            note=self.note,
        )

    @property
    def note(self) -> str:
        """One line: which bounds the memory cap and the time budget left in use."""
        return "; ".join(self.notes)


def solve_active_recognition(
    problem: ActiveRecognitionProblem,
    precision: float = 1e-3,
    timeout: float = 30.0,
    callback: ProgressCallback | None = None,
    *,
    chunk: int = 2_000_000,
    grid: bool | int = True,
    grid_entries: int = 12_000_000,
    memory_gb: float = DEFAULT_MEMORY_GB,
    **options: Any,
) -> SolveResult[ActiveRecognitionPolicy]:
    """Solve the MOMDP with :class:`ActiveRecognitionSolver`; ``result.policy`` is an
    :class:`~rapomdp.planning.policy.ActiveRecognitionPolicy`. ``chunk``, ``grid`` (False: no
    grid bound; an int: that resolution), ``grid_entries`` and ``memory_gb`` (the cap every
    structure is sized against, default 4) go to the constructor, ``options`` to
    :meth:`ActiveRecognitionSolver.solve` (``clock``, ``checkpoints``, ``max_iterations``, …).
    ``result.note`` says which bounds the cap and the budget left in use.

    The planner of the RA-POMDP: from the start viewpoint and belief, where to move next or
    which class to declare, trading movement energy against the cost λ of a wrong
    declaration (paper Eqs. 1-5).

    Args:
        problem: The MOMDP (:func:`~rapomdp.planning.momdp.build_active_recognition_problem`).
        precision: The gap between the bounds at the start at which it stops.
        timeout: Seconds of process CPU time (``clock="wall"``: wall time).
        callback: Called with each :class:`~rapomdp.planning.sarsop.Progress` snapshot.
        chunk: Entries of one working block.
        grid: The grid upper bound: True (the finest that fits), False (none) or a resolution.
        grid_entries: The most grid entries the time budget allows.
        memory_gb: The memory cap in GB.
        **options: More settings of :meth:`ActiveRecognitionSolver.solve`.

    Returns:
        The policy, the lower and upper bounds on the optimal value at the start (a negative
        expected cost, in the units of the energy and λ), the seconds, the rounds, whether the
        gap closed, the history and a note.

    Raises:
        MemoryCapError: The problem does not fit ``memory_gb``.
        ValueError: ``precision`` or ``timeout`` is not a positive finite number.

    Example:
        Two viewpoints: one informative, the start barely so. Moving (1 m) and then declaring
        is worth −1 + 0.95 · (−8 · 0.15) = −2.14, better than declaring now (−4):

        >>> import numpy as np
        >>> from rapomdp.planning import build_active_recognition_problem
        >>> P = np.array([[[0.9, 0.1], [0.2, 0.8]],   # viewpoint 0: informative
        ...               [[0.6, 0.4], [0.4, 0.6]]])  # viewpoint 1: barely
        >>> E = np.array([[0.0, 1.0], [1.0, 0.0]])     # moving costs 1 m
        >>> problem = build_active_recognition_problem(P, E, lambda_=8.0, start_viewpoint=1)
        >>> result = solve_active_recognition(problem, precision=1e-3)
        >>> result.converged, round(result.lower, 2), round(result.upper, 2)
        (True, -2.14, -2.14)
        >>> result.policy.act(1, problem.start_belief)
        ARAction(kind='move', target=0)
        >>> result.policy.act(0, np.array([0.9, 0.1]))
        ARAction(kind='declare', target=0)
    """
    solver = ActiveRecognitionSolver(problem, chunk, grid, grid_entries, memory_gb)
    return solver.solve(precision, timeout, callback, **options)
