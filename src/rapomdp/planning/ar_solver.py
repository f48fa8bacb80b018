"""SARSOP-style solver for the active-recognition MOMDP, exploiting its structure.

Because the class never changes and the viewpoint is observed, a belief is (v, b) with b on the
|C|-simplex, and the value function is one convex function of b per viewpoint. Two facts make
it cheap:

* Moving to j costs E[v, j] whatever the class, so the value of "move to j, then act" is
  β·b − E[v, j] with β independent of the viewpoint v we leave. One lower-bound backup at b
  therefore yields plans for *every* viewpoint at once: the solver keeps one library of
  vectors β_m (each tagged with its target j_m) and the set for viewpoint v is
  {β_m − E[v, j_m]} plus the declare vectors −λ(1 − e_k). Likewise one upper-bound backup at b
  gives an upper value for every viewpoint: the points are beliefs b_i with a value per
  viewpoint U_i[v].
* With the class known the best is to declare it at once for 0 (moves cost ≥ 0), so the
  upper bound is 0 at every corner of the simplex; sawtooth interpolation from the corners and
  the points gives U(v, b) = min(0, min_i φ_i(b) U_i[v]), φ_i(b) = min_c b(c)/b_i(c). (The
  generic FIB degenerates to 0 here; these corners are exact.)

Sampling, backups and pruning follow :mod:`rapomdp.planning.sarsop`: trajectories from
(v0, b0) alternately guided by the upper bound with the largest weighted excess gap, and by
the policy in hand with sampled observations; reverse-order backups; library vectors that are
best nowhere among the sampled beliefs are pruned.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from rapomdp.planning.momdp import ActiveRecognitionProblem
from rapomdp.planning.policy import ActiveRecognitionPolicy
from rapomdp.planning.sarsop import Progress, ProgressCallback, SolveResult


@dataclass
class _Expansion:
    """Everything one backup at belief b needs and produces."""

    prob: np.ndarray  # (J, Zo) p(o | b, move to target a)
    children: np.ndarray  # (J, Zo, C) normalised posteriors
    low_child: np.ndarray  # (J, Zo) lower bound at the child (at viewpoint targets[a])
    up_child: np.ndarray  # (J, Zo) upper bound at the child
    betas: np.ndarray  # (J, C) backed-up continuation vectors, one per target
    q_up: np.ndarray  # (J,) upper bound on the continuation value of each target


class ActiveRecognitionSolver:
    """Point-based solver with one shared library of continuation vectors over the simplex."""

    def __init__(self, problem: ActiveRecognitionProblem, chunk: int = 4_000_000) -> None:
        self.problem = problem
        self.targets = problem.targets  # (J,) viewpoint index of each move target
        self.cost = problem.move_cost()  # (V, J)
        self.cost_tt = self.cost[self.targets]  # (J, J): from a target to a target
        # Pj[a, o, c] = P(o | c, targets[a]): the layout the backups multiply with
        self.Pj = np.ascontiguousarray(
            problem.observation_model[self.targets].transpose(0, 2, 1)
        )
        self.lam = problem.lambda_
        self.g = problem.discount
        n_c = problem.n_classes
        self.betas = np.zeros((0, n_c))
        self.slots = np.zeros(0, dtype=np.int64)  # target slot (index into targets) of β
        self.up_points = np.zeros((0, n_c))
        self.up_inv = np.zeros((0, n_c))
        self.up_off = np.zeros((0, n_c))
        self.up_values = np.zeros((0, problem.n_viewpoints))
        self.sampled: list[np.ndarray] = [problem.start_belief]
        self.chunk = chunk

    # -- bounds --------------------------------------------------------------------------
    def lower_values(self, beliefs: np.ndarray) -> np.ndarray:
        """Lower bound (K, V) at beliefs (K, C) for every viewpoint."""
        B = np.atleast_2d(beliefs)
        dec = -self.lam * (1.0 - B.max(axis=1))
        out = np.repeat(dec[:, None], self.problem.n_viewpoints, axis=1)
        if len(self.slots):
            step = max(1, self.chunk // (len(self.slots) * self.problem.n_viewpoints))
            for i in range(0, B.shape[0], step):
                s = B[i : i + step] @ self.betas.T  # (k, M)
                moves = (s[:, None, :] - self.cost[:, self.slots][None]).max(axis=2)
                out[i : i + step] = np.maximum(out[i : i + step], moves)
        return out

    def _phi(self, beliefs: np.ndarray) -> np.ndarray:
        """φ_i(b) = min_c b(c)/b_i(c) over each point's support: (K, N)."""
        n = self.up_points.shape[0]
        K, n_c = beliefs.shape
        out = np.empty((K, n))
        step = max(1, self.chunk // max(1, n * n_c))
        for i in range(0, K, step):
            r = beliefs[i : i + step, None, :] * self.up_inv[None]
            r += self.up_off[None]
            out[i : i + step] = r.min(axis=2)
        return out

    def upper_values(self, beliefs: np.ndarray) -> np.ndarray:
        """Upper bound (K, V) at beliefs (K, C) for every viewpoint."""
        B = np.atleast_2d(beliefs)
        if self.up_points.shape[0] == 0:
            return np.zeros((B.shape[0], self.problem.n_viewpoints))
        phi = self._phi(B)  # (K, N)
        return np.minimum(0.0, (phi[:, :, None] * self.up_values[None]).min(axis=1))

    # -- one belief ----------------------------------------------------------------------
    def _lower_children(
        self, u: np.ndarray, prob: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Best plan at every child (unnormalised u (J, Zo, C)): its value (J, Zo) and the
        backed-up continuation vectors β_a = γ Σ_o P[a, o, :] ⊙ α_{a,o} (J, C)."""
        n_j, n_z, n_c = u.shape
        kstar = u.argmax(axis=2)  # best class to declare at each child
        dec = -self.lam * (prob - np.take_along_axis(u, kstar[..., None], axis=2)[..., 0])
        alpha = -self.lam * (1.0 - np.eye(n_c)[kstar])  # (J, Zo, C) declare vectors
        value = dec
        if len(self.slots):
            s = u @ self.betas.T  # (J, Zo, M)
            s -= prob[:, :, None] * self.cost_tt[:, self.slots][:, None, :]
            m = s.argmax(axis=2)
            best = np.take_along_axis(s, m[..., None], axis=2)[..., 0]
            use = best > dec
            if use.any():
                lib = self.betas[m] - self.cost_tt[np.arange(n_j)[:, None], self.slots[m]][
                    ..., None
                ]
                alpha = np.where(use[..., None], lib, alpha)
                value = np.where(use, best, dec)
        betas = self.g * np.einsum("aoc,aoc->ac", self.Pj, alpha)
        return value, betas

    def _expand(self, b: np.ndarray) -> _Expansion:
        u = b[None, None, :] * self.Pj  # (J, Zo, C) unnormalised children
        prob = u.sum(axis=2)
        safe = np.where(prob > 0, prob, 1.0)
        children = u / safe[..., None]
        low, betas = self._lower_children(u, prob)
        n_j, n_z, n_c = u.shape
        up = np.zeros((n_j, n_z))
        if self.up_points.shape[0]:
            phi = self._phi(children.reshape(n_j * n_z, n_c)).reshape(n_j, n_z, -1)
            vals = self.up_values[:, self.targets].T  # (J, N): each point's value at target a
            up = np.minimum(0.0, (phi * vals[:, None, :]).min(axis=2))
        q_up = self.g * (prob * up).sum(axis=1)
        return _Expansion(prob, children, low / safe, up, betas, q_up)

    def _backup(self, b: np.ndarray, ex: _Expansion) -> tuple[np.ndarray, np.ndarray]:
        """Add the improving plans and the upper point at b; returns (lower, upper) (V,)."""
        dec = -self.lam * (1.0 - b.max())
        old_low = self.lower_values(b[None])[0]
        cand = ex.betas @ b - self.cost  # (V, J)
        best_a = cand.argmax(axis=1)
        best = cand[np.arange(cand.shape[0]), best_a]
        better = best > old_low + 1e-10
        if better.any():
            new = np.unique(best_a[better])
            self.betas = np.vstack([self.betas, ex.betas[new]])
            self.slots = np.concatenate([self.slots, new])
        low = np.maximum(old_low, best)
        old_up = self.upper_values(b[None])[0]
        new_up = np.maximum(dec, (ex.q_up[None, :] - self.cost).max(axis=1))
        up = np.minimum(old_up, new_up)
        if np.any(new_up < old_up - 1e-10):
            self._add_point(b, up)
        return low, up

    def _add_point(self, b: np.ndarray, values: np.ndarray) -> None:
        support = b > 0
        self.up_points = np.vstack([self.up_points, b[None]])
        self.up_inv = np.vstack([self.up_inv, np.where(support, 1.0 / np.where(support, b, 1), 0)])
        self.up_off = np.vstack([self.up_off, np.where(support, 0.0, np.inf)[None]])
        self.up_values = np.vstack([self.up_values, values[None]])

    # -- the loop ------------------------------------------------------------------------
    def _trajectory(
        self,
        eps: float,
        max_depth: int,
        deadline: float,
        follow_lower: bool,
        rng: np.random.Generator,
    ) -> None:
        v, b = self.problem.start_viewpoint, self.problem.start_belief
        path: list[tuple[int, np.ndarray, _Expansion, int, int]] = []
        for depth in range(max_depth):
            ex = self._expand(b)
            low, up = self._backup(b, ex)
            target = eps * self.g ** (-depth)
            moves_low = ex.betas @ b - self.cost[v]
            moves_up = ex.q_up - self.cost[v]
            dec = -self.lam * (1.0 - b.max())
            if up[v] - low[v] <= target or time.perf_counter() > deadline:
                path.append((v, b, ex, -1, -1))
                break
            if follow_lower:
                a = int(np.argmax(moves_low))
                if moves_low[a] <= dec:
                    path.append((v, b, ex, -1, -1))
                    break
                pr = ex.prob[a]
                o = int(rng.choice(pr.size, p=pr / pr.sum()))
                path.append((v, b, ex, a, o))
                if ex.up_child[a, o] - ex.low_child[a, o] <= target / self.g:
                    break
            else:
                a = int(np.argmax(moves_up))
                if moves_up[a] <= dec:
                    path.append((v, b, ex, -1, -1))
                    break
                excess = ex.prob[a] * (ex.up_child[a] - ex.low_child[a] - target / self.g)
                o = int(np.argmax(excess))
                path.append((v, b, ex, a, o))
                if excess[o] <= 0:
                    break
            v, b = int(self.targets[a]), ex.children[a, o]
        # reverse-order backups; cached children upper values stay valid (the bound only
        # falls), only the child on the path is refreshed; the lower part is redone
        child_up: np.ndarray | None = None
        for _v, belief, ex, a, o in reversed(path):
            if a >= 0 and child_up is not None:
                ex.up_child[a, o] = min(ex.up_child[a, o], child_up[self.targets[a]])
                ex.q_up[a] = self.g * float(ex.prob[a] @ ex.up_child[a])
            u = belief[None, None, :] * self.Pj
            _, ex.betas = self._lower_children(u, ex.prob)
            _, child_up = self._backup(belief, ex)
        self.sampled.extend(item[1] for item in path)

    def prune(self) -> None:
        """Drop library vectors best at no (sampled belief, viewpoint) and redundant points."""
        B = np.unique(np.vstack(self.sampled), axis=0)
        self.sampled = list(B)
        n_m = len(self.slots)
        if n_m:
            used = np.zeros(n_m, dtype=bool)
            n_v = self.problem.n_viewpoints
            step = max(1, self.chunk // (n_m * n_v))
            cost = self.cost[:, self.slots]  # (V, M)
            for i in range(0, B.shape[0], step):
                blk = B[i : i + step]
                s = (blk @ self.betas.T)[:, None, :] - cost[None]  # (k, V, M)
                m = s.argmax(axis=2)
                best = np.take_along_axis(s, m[..., None], axis=2)[..., 0]
                dec = -self.lam * (1.0 - blk.max(axis=1))
                used[m[best > dec[:, None]]] = True
            self.betas, self.slots = self.betas[used], self.slots[used]
        n = self.up_points.shape[0]
        if n > 1:
            phi = self._phi(self.up_points)  # (N, N): φ_j(b_i)
            drop = np.zeros(n, dtype=bool)
            idx = np.arange(n)
            step = max(1, self.chunk // (n * self.problem.n_viewpoints))
            for i in range(0, n, step):
                rows = slice(i, min(n, i + step))
                bound = phi[rows, :, None] * self.up_values[None]  # (r, N, V)
                own = self.up_values[rows, None, :]
                later = (idx[None, :] > idx[rows, None])[..., None]
                dominated = np.where(later, bound <= own + 1e-12, bound < own - 1e-12).all(axis=2)
                dominated[np.arange(rows.stop - rows.start), idx[rows]] = False
                drop[rows] = dominated.any(axis=1)
            keep = ~drop
            self.up_points, self.up_inv = self.up_points[keep], self.up_inv[keep]
            self.up_off, self.up_values = self.up_off[keep], self.up_values[keep]

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
        )

    def solve(
        self,
        precision: float = 1e-3,
        timeout: float = 30.0,
        callback: ProgressCallback | None = None,
        report_every: float = 0.5,
        max_depth: int = 200,
        gap_fraction: float = 0.5,
        max_iterations: int | None = None,
        policy_trajectories: bool = True,
        seed: int = 0,
        checkpoints: tuple[float, ...] = (),
    ) -> SolveResult:
        """Improve both bounds at (v0, b0) until their gap ≤ ``precision`` or ``timeout`` s.

        ``checkpoints`` (seconds) force a history entry as soon as each is passed.
        """
        start = time.perf_counter()
        deadline = start + timeout
        v0, b0 = self.problem.start_viewpoint, self.problem.start_belief
        rng = np.random.default_rng(seed)
        history: list[Progress] = []
        it, next_prune, last, pruned_size = 0, 16, -np.inf, 0
        pending = sorted(checkpoints)
        while True:
            now = time.perf_counter()
            snap = Progress(
                now - start,
                float(self.lower_values(b0[None])[0, v0]),
                float(self.upper_values(b0[None])[0, v0]),
                len(self.slots),
                self.up_points.shape[0],
                it,
            )
            converged = snap.gap <= precision
            done = converged or now > deadline or (
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
            self._trajectory(eps, max_depth, deadline, policy_trajectories and it % 2 == 1, rng)
            it += 1
            if it >= next_prune or len(self.slots) > 2 * pruned_size + 256:
                self.prune()
                next_prune = int(it * 1.5) + 1
                pruned_size = len(self.slots)
        final = history[-1]
        return SolveResult(
            self.policy(), final.lower, final.upper, final.elapsed, it, converged, history
        )


def solve_active_recognition(
    problem: ActiveRecognitionProblem,
    precision: float = 1e-3,
    timeout: float = 30.0,
    callback: ProgressCallback | None = None,
    **options: object,
) -> SolveResult:
    """Solve the MOMDP with :class:`ActiveRecognitionSolver`; ``result.policy`` is an
    :class:`~rapomdp.planning.policy.ActiveRecognitionPolicy`."""
    solver = ActiveRecognitionSolver(problem)
    return solver.solve(precision, timeout, callback, **options)  # type: ignore[arg-type]
