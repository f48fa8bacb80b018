"""A tried speed-up of the one-step lookahead that did not pay: screen every move in float32
(one product of an augmented child vector [u, P(o)·E] with each plan's [β, −one-hot of its
first target's group], whose rounding error is bounded), then value exactly, in float64, only
the moves that can be the best or beat declaring. It returns the same actions as the exact
lookahead it was measured against (``lookahead_speed.reference_lookahead_act``, the
implementation of the time; checked here on every case); the figure is the CPU time per action
of both, on beliefs after one to four random labels, one core. The screen ``lookahead_act``
adopted later avoids what cost this one its gain: see ``lookahead_speed.py``.

    OMP_NUM_THREADS=1 python benchmarks/lookahead_screening.py --workspace W [--repeats 200]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from lookahead_speed import (  # benchmarks/, the script's own folder
    recorded_cases,
    reference_lookahead_act,
)

from rapomdp.planning.policy import ActiveRecognitionPolicy, ARAction
from rapomdp.planning.rules import (
    TIE_TOL,
    declare_value,
    move_or_declare,
    unnormalised_declare_value,
)


def screened_lookahead(policy: ActiveRecognitionPolicy, plans32: np.ndarray,
                       group_energy32: np.ndarray, scale: float, starts: np.ndarray,
                       betas: np.ndarray, first: np.ndarray, viewpoint: int, b: np.ndarray,
                       model: np.ndarray, allowed: np.ndarray,
                       forbidden: np.ndarray) -> ARAction:
    ok = allowed.copy()
    ok[viewpoint] = False
    ok &= ~forbidden
    targets = np.flatnonzero(ok)
    dec = float(declare_value(b, policy.lambda_))
    k = int(np.argmax(b))
    u = b[None, None, :] * np.swapaxes(model[targets], 1, 2)
    prob = u.sum(axis=2)
    child = unnormalised_declare_value(u, policy.lambda_)
    step = policy.move_energy[viewpoint, targets]
    augmented = np.empty(u.shape[:2] + (plans32.shape[1],), dtype=np.float32)
    augmented[..., : b.size] = u
    np.multiply(prob[..., None], group_energy32[targets][:, None, :],
                out=augmented[..., b.size:], casting="same_kind")
    rough_q = (policy.discount * np.maximum(child, (augmented @ plans32.T).max(axis=2))
               .sum(axis=1) - step)
    error = (2.0 * (plans32.shape[1] + 8) * 2.0**-24 * policy.discount * scale
             * prob.sum(axis=1) + 1e-9)
    keep = rough_q + error >= max(float((rough_q - error).max()), dec + TIE_TOL)
    if not keep.any():
        return ARAction("declare", k)
    targets, u, prob, child, step = targets[keep], u[keep], prob[keep], child[keep], step[keep]
    best = np.maximum.reduceat(u @ betas.T, starts, axis=2)
    best -= prob[..., None] * policy.move_energy[np.ix_(targets, first)][:, None]
    q = policy.discount * np.maximum(child, best.max(axis=2)).sum(axis=1) - step
    _, m = move_or_declare(q[None], np.asarray(dec)[None])
    return ARAction("move", int(targets[m[0]])) if m[0] >= 0 else ARAction("declare", k)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, required=True)
    parser.add_argument("--repeats", type=int, default=200)
    args = parser.parse_args()
    model, policy, reachable, cases = recorded_cases(args.workspace, args.repeats)
    n_c = model.shape[1]
    order = np.argsort(policy.targets, kind="stable")
    first, starts = np.unique(policy.targets[order], return_index=True)
    betas = np.ascontiguousarray(policy.betas[order])
    group = np.repeat(np.arange(starts.size), np.diff(np.append(starts, len(betas))))
    plans32 = np.concatenate([betas, -np.eye(starts.size)[group]], axis=1).astype(np.float32)
    finite = np.isfinite(policy.move_energy)
    penalty = policy.lambda_ + max(0.0, float(policy.betas.max())) + 1.0
    group_energy32 = np.where(finite, policy.move_energy, penalty)[:, first].astype(np.float32)
    scale = float(np.abs(policy.betas).max() + np.abs(policy.move_energy[finite]).max())
    same = sum(reference_lookahead_act(policy, v, b, model, reachable, vis)
               == screened_lookahead(policy, plans32, group_energy32, scale, starts, betas,
                                     first, v, b, model, reachable, vis)
               for v, b, vis in cases)
    seconds = {}
    for name in ("reference", "screened"):
        start = time.process_time()
        for v, b, vis in cases:
            if name == "reference":
                reference_lookahead_act(policy, v, b, model, reachable, vis)
            else:
                screened_lookahead(policy, plans32, group_energy32, scale, starts, betas, first,
                                   v, b, model, reachable, vis)
        seconds[name] = (time.process_time() - start) / len(cases)
    print(f"{policy.betas.shape[0]} plans, {int(reachable.sum())} reachable viewpoints, "
          f"{n_c} classes, {len(cases)} beliefs: the same action {same}/{len(cases)}; CPU per "
          f"action reference lookahead {1e3 * seconds['reference']:.2f} ms, screened "
          f"{1e3 * seconds['screened']:.2f} ms "
          f"({seconds['reference'] / seconds['screened']:.2f}x)")


if __name__ == "__main__":
    main()
