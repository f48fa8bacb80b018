"""The declared confidence (``evaluate.declared_confidence``): held out, and on the test episodes.

For each workspace (seeds of one or more configurations; a workspace's configuration is its
parent folder's name, as a study lays them out) this prints:

1. *Held out* (what the observe and vptree stages recorded; never the test models): per model,
   the declared-confidence temperature a and, leave-one-group-out over the stopped held-out
   walks, the accuracy, the mean confidence and ECE of the belief and of the declared belief.
   Then, per configuration, the mean over its seeds and the adoption rule of
   ``benchmarks/results/declared_confidence_rule.md``: the ECE must fall for RA-POMDP's model
   and the Classifier model on every configuration.
2. *The test episodes* (a diagnostic read after the rule, never a choice): every method's
   confidence − accuracy and ECE as the belief and as declared, per seed and pooled over the
   seeds. The declared confidence changes no action, so the same episodes give both: the
   final belief is raised to its model's a (or, when the evaluate stage already reported
   declared beliefs, taken back to the belief by 1 / a).

    python benchmarks/declared_confidence.py -w W [W ...]
"""

from __future__ import annotations

import argparse
from collections import defaultdict
from pathlib import Path

import numpy as np

from rapomdp.experiment.episode_table import EPISODES_FILE, EpisodeTable
from rapomdp.io import read_json
from rapomdp.planning.stage import declared_temperatures, offered_observation_models
from rapomdp.recognition.belief import declared_belief, expected_calibration_error

RULE_MODELS = ("ra", "classifier")
#: The model whose belief each method reports (Random's: evaluate.random.observation_model).
METHOD_MODELS = {"ra": "ra", "classifier": "classifier", "vptree": "vptree"}


def held_out(workspace: Path) -> dict[str, dict[str, float]]:
    """Per model, the observe (and vptree) stage's held-out declared-confidence record."""
    records = dict(read_json(workspace / "observe" / "calibration.json")
                   .get("declared_confidence", {}))
    vptree = workspace / "vptree" / "vptree.json"
    if vptree.exists() and read_json(vptree).get("declared_confidence"):
        records["vptree"] = read_json(vptree)["declared_confidence"]
    if not records:
        raise SystemExit(f"{workspace}: no declared confidence recorded (redo its observe stage "
                         "with this version: rapomdp run -w W --until observe)")
    return records


def test_rows(workspace: Path) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per method: (correct, confidence as the belief, confidence as declared) of the
    evaluate stage's Table 1 episodes."""
    stage = read_json(workspace / "evaluate" / "stage.json")["config"]["evaluate"]
    reported_declared = stage.get("declared_confidence", "belief") == "calibrated"
    random_model = stage["random"]["observation_model"]
    offered, _ = offered_observation_models(workspace / "observe", workspace / "vptree")
    temperatures = declared_temperatures(workspace / "observe", offered, workspace / "vptree")
    table = EpisodeTable.load(workspace / "evaluate" / EPISODES_FILE)
    final = table.step_beliefs[table.offsets[1:] - 1]  # (E, C)
    rows = {}
    for method in table.methods:
        mine = table.method == method
        model = random_model if method == "random" else METHOD_MODELS.get(str(method))
        a = temperatures.get(model, 1.0) if model is not None else 1.0
        beliefs = final[mine]
        if reported_declared and a != 1.0:
            beliefs = declared_belief(beliefs, 1.0 / a)
        declared = declared_belief(beliefs, a)
        rows[str(method)] = (table.correct[mine], beliefs.max(axis=1), declared.max(axis=1))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    args = parser.parse_args()
    by_config: dict[str, list[Path]] = defaultdict(list)
    for w in args.workspace:
        by_config[w.parent.name].append(w)

    print("1) held out: stopped walks of the volume groups, leave-one-group-out "
          "(the observe and vptree stages' record)")
    print(f"{'workspace':44s} {'model':10s} {'a':>6s} {'acc':>6s} {'conf':>6s} {'ECE':>6s} "
          f"{'decl.':>6s} {'ECE':>6s}")
    means: dict[str, dict[str, np.ndarray]] = {}
    for config, workspaces in by_config.items():
        per_model: dict[str, list[list[float]]] = defaultdict(list)
        for w in workspaces:
            for model, r in held_out(w).items():
                if model.startswith("ra_"):
                    continue
                values = [r["temperature"], r["accuracy"], r["confidence"], r["ece"],
                          r["declared_confidence"], r["declared_ece"]]
                per_model[model].append(values)
                print(f"{str(w):44s} {model:10s} " + " ".join(f"{v:6.3f}" for v in values))
        means[config] = {m: np.mean(v, axis=0) for m, v in per_model.items()}
        for model, v in means[config].items():
            print(f"{config + ' (mean of ' + str(len(workspaces)) + ' seeds)':44s} "
                  f"{model:10s} " + " ".join(f"{x:6.3f}" for x in v))
    passed = all(means[c][m][5] < means[c][m][3] for c in means for m in RULE_MODELS)
    print("rule (ECE of the declared confidence below the belief's for "
          f"{' and '.join(RULE_MODELS)} on {', '.join(means)}): "
          f"{'met: adopt' if passed else 'not met: stays an option'}")

    print("\n2) the test episodes (diagnostic, not a choice): confidence - accuracy / ECE")
    print(f"{'configuration':24s} {'method':10s} {'seeds':>5s} {'accuracy':>8s} "
          f"{'belief: c-a':>11s} {'ECE':>6s} {'declared: c-a':>13s} {'ECE':>6s}   per seed "
          "c-a as declared")
    for config, workspaces in by_config.items():
        pooled: dict[str, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = defaultdict(list)
        for w in workspaces:
            for method, row in test_rows(w).items():
                pooled[method].append(row)
        for method, rows in pooled.items():
            right = np.concatenate([r[0] for r in rows])
            belief = np.concatenate([r[1] for r in rows])
            declared = np.concatenate([r[2] for r in rows])
            per_seed = " / ".join(f"{(r[2].mean() - r[0].mean()):+.3f}" for r in rows)
            print(f"{config:24s} {method:10s} {len(rows):5d} {right.mean():8.3f} "
                  f"{belief.mean() - right.mean():+11.3f} "
                  f"{expected_calibration_error(belief, right):6.3f} "
                  f"{declared.mean() - right.mean():+13.3f} "
                  f"{expected_calibration_error(declared, right):6.3f}   {per_seed}")


if __name__ == "__main__":
    main()
