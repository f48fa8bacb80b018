"""Which held-out evidence predicts the trained classifier on unseen objects: leave one volume
model out, fit every observation model on the other volume models (``volume``) or on those plus
the cross-fitted training models, level-shifted as the observe stage does (``both``), and score
the left-out one. Needs a workspace whose observe stage ran with ``observe.evidence=both``;
never reads the test models.

    python benchmarks/held_out_evidence.py --workspace W
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rapomdp.awareness.evidence import (
    RecordedObservation,
    fit_level,
    fit_observation_models,
    observed_probabilities,
    shift_level,
)
from rapomdp.awareness.quality import quality_from_probabilities
from rapomdp.workspace import Workspace


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, required=True)
    args = parser.parse_args()
    ws = Workspace(args.workspace)
    config = ws.config()
    recorded = RecordedObservation.load(ws.require("observe"))
    observe, evidence, scores = recorded.arrays, recorded.evidence, recorded.scores
    if evidence.volume_mask.all():
        raise SystemExit(f"{args.workspace}: no cross-fitted rows; run observe with "
                         "observe.evidence=both")
    classes, kernel = recorded.classes, recorded.transfer_kernel
    pooled: dict[tuple[str, str], list[list[np.ndarray]]] = {}
    for g in np.unique(evidence.groups[evidence.volume_mask]):
        held = evidence.groups == g
        part = evidence.subset(held)
        for kind in ("volume", "both"):
            rest = evidence.subset(~held & (evidence.volume_mask if kind == "volume" else True))
            fitted = fit_observation_models(rest, scores, classes, config.observe,
                                            observe["directions"], kernel)
            volume = rest.subset(rest.volume_mask)
            for name, model in fitted.items():
                p = model.probabilities
                if kind == "both":
                    p = shift_level(p, fit_level(p, volume.labels, volume.predicted))
                o, pc = observed_probabilities(p, part.labels, part.predicted)
                cell = pooled.setdefault((name, kind), [[], [], []])
                cell[0].append(o.ravel())
                cell[1].append(pc.ravel())
                cell[2].append(part.correct.ravel())
    print(f"leave one volume model out: {int(evidence.volume_mask.sum())} volume rows, "
          f"{int((~evidence.volume_mask).sum())} cross-fitted rows, {len(classes)} classes")
    print("| model | volume: log-likelihood / AUC | both: log-likelihood / AUC |")
    print("|---|---|---|")
    for name in dict.fromkeys(n for n, _ in pooled):
        cells = []
        for kind in ("volume", "both"):
            q = quality_from_probabilities(*(np.concatenate(x) for x in pooled[(name, kind)]))
            cells.append(f"{q['log_likelihood']:.3f} / {q['auc']:.3f}")
        print(f"| {name} | {cells[0]} | {cells[1]} |")


if __name__ == "__main__":
    main()
