"""The size-prior rule's verdict (``results/size_prior_rule.md``) from held-out closed loops
run with and without ``--size-prior`` (``held_out_closed_loop.py --save``), one pair a seed.

    python benchmarks/size_prior_summary.py --with S0.npz S1.npz S2.npz \\
        --without B0.npz B1.npz B2.npz [--keys ra@8 classifier@8 random@0] [--rule]
        [--matched H0.npz H1.npz H2.npz]

``--matched``: runs with the size prior at larger λ (the rule's second question): per method,
the largest λ at which its pooled energy with the prior is at most its energy without it at
λ = 8, and the paired difference there.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from held_out_paired import describe, pooled_difference  # noqa: E402

from rapomdp.io import load_npz  # noqa: E402

RULE_GAIN = 0.03
"""RA-POMDP's pooled held-out gain the rule asks for (its interval above 0 too)."""


def matched(loaded: list[tuple[dict[str, np.ndarray], dict[str, np.ndarray]]],
            higher: list[dict[str, np.ndarray]]) -> None:
    """Each POMDP method with the prior at the largest λ within its uniform λ = 8 energy."""
    if len(higher) != len(loaded):
        raise SystemExit("give one --matched run a seed")
    for method in ("ra", "classifier"):
        base = [b[f"{method}@8"] for _, b in loaded]
        budget = float(np.concatenate(base)[:, 1].mean())
        runs = {8.0: [a[f"{method}@8"] for a, _ in loaded]}
        for key in sorted(higher[0]):
            name, lam = key.split("@")
            if name == method:
                runs[float(lam)] = [h[key] for h in higher]
        energy = {lam: float(np.concatenate(r)[:, 1].mean()) for lam, r in runs.items()}
        within = [lam for lam in sorted(runs) if energy[lam] <= budget]
        print(f"{method}: uniform λ = 8 spends {budget:.3f} m; with the prior " +
              ", ".join(f"λ = {lam:g} {energy[lam]:.3f} m" for lam in sorted(runs)))
        if not within:
            print("  no λ with the prior within that energy")
            continue
        best = max(within)
        print("  " + describe(f"{method}, prior at λ = {best:g} vs uniform at 8",
                              list(zip(runs[best], base, strict=True)),
                              ("size prior", "uniform")))
        estimate, low, _ = pooled_difference(list(zip(runs[best], base, strict=True)))
        met = estimate >= RULE_GAIN and low > 0
        print(f"  second question: {'a lead at matched energy' if met else 'not a lead'}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--with", dest="with_", type=Path, nargs="+", required=True)
    parser.add_argument("--without", type=Path, nargs="+", required=True)
    parser.add_argument("--keys", nargs="+", default=["ra@8", "classifier@8", "random@0"])
    parser.add_argument("--matched", type=Path, nargs="+", default=None,
                        help="runs with the size prior at larger λ, one a seed")
    parser.add_argument("--rule", action="store_true",
                        help="print the verdict (the rule is read on the real-CAD runs)")
    args = parser.parse_args()
    if len(args.with_) != len(args.without):
        raise SystemExit("give one run with and one without the size prior a seed")
    loaded = [(load_npz(a), load_npz(b)) for a, b in zip(args.with_, args.without, strict=True)]
    for key in args.keys:
        if any(key not in a or key not in b for a, b in loaded):
            raise SystemExit(f"{key}: not in every run")
        print(describe(key, [(a[key], b[key]) for a, b in loaded], ("size prior", "uniform")))
    if args.matched is not None:
        matched(loaded, [load_npz(p) for p in args.matched])
    if args.rule:
        estimate, low, _ = pooled_difference([(a["ra@8"], b["ra@8"]) for a, b in loaded])
        met = estimate >= RULE_GAIN and low > 0
        print(f"verdict: RA-POMDP {estimate:+.3f}, interval low {low:+.3f}: "
              + ("build the size prior as a pipeline option next" if met
                 else "not recommended by the rule"))


if __name__ == "__main__":
    main()
