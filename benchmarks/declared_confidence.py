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

3. With ``--candidates``, the second round's candidates
   (``benchmarks/results/declared_confidence_rule_v2.md``), held out only: each workspace's
   observe stage is computed again (not written) and its walks fitted by the log loss of the
   true class (A, round one's) and by the confidence's cross-entropy (B), pooled over the
   thresholds and at Random's own threshold (C); then the rule.

    python benchmarks/declared_confidence.py -w W [W ...] [--candidates]
"""

from __future__ import annotations

import argparse
from collections import defaultdict
from pathlib import Path

import numpy as np

from rapomdp.awareness.artefacts import load_declared_confidence
from rapomdp.awareness.observe_stage import observe_inputs
from rapomdp.awareness.temperature import held_out_declared_confidence
from rapomdp.data.dataset import load_dataset
from rapomdp.data.splits import class_seed
from rapomdp.experiment.episode_table import EPISODES_FILE, EpisodeTable
from rapomdp.geometry.viewsphere import fibonacci_directions
from rapomdp.io import read_json
from rapomdp.pipeline import get_stage
from rapomdp.planning.stage import declared_temperatures, offered_observation_models
from rapomdp.recognition.belief import (
    TEMPERATURE_NEIGHBOURS,
    TEMPERATURE_WALKS_PER_ROW,
    DeclaredConfidence,
    declared_belief,
    expected_calibration_error,
)
from rapomdp.workspace import Workspace

RULE_MODELS = ("ra", "classifier")
#: The model whose belief each method reports (Random's: evaluate.random.observation_model).
METHOD_MODELS = {"ra": "ra", "classifier": "classifier", "vptree": "vptree"}


def held_out(workspace: Path) -> dict[str, dict[str, float]]:
    """Per model, the observe (and vptree) stage's held-out declared-confidence record."""
    records = load_declared_confidence(workspace / "observe", workspace / "vptree")
    if not records:
        raise SystemExit(f"{workspace}: no declared confidence recorded (redo its observe stage "
                         "with this version: rapomdp run -w W --until observe)")
    return records


def test_rows(workspace: Path) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per method: (correct, confidence as the belief, confidence as declared) of the
    evaluate stage's Table 1 episodes."""
    config = read_json(workspace / "evaluate" / "stage.json")["config"]
    stage = config["evaluate"]
    reported_declared = stage.get("declared_confidence", "belief") == "calibrated"
    random_model = stage["random"]["observation_model"]
    offered, _ = offered_observation_models(workspace / "observe", workspace / "vptree")
    temperatures = declared_temperatures(workspace / "observe", offered, workspace / "vptree")
    # Random reports with the a fitted at its own stop threshold (where the stage fitted one)
    random_a = declared_temperatures(workspace / "observe", {random_model: offered[random_model]},
                                     None, stage["random"]["belief_threshold"])[random_model]
    table = EpisodeTable.load(workspace / "evaluate" / EPISODES_FILE)
    final = table.step_beliefs[table.offsets[1:] - 1]  # (E, C)
    rows = {}
    for method in table.methods:
        mine = table.method == method
        model = METHOD_MODELS.get(str(method))  # Static and the learned baseline: a = 1
        a = (random_a if method == "random" else
             temperatures.get(model, 1.0) if model is not None else 1.0)
        beliefs = final[mine]
        if reported_declared and a != 1.0:
            beliefs = declared_belief(beliefs, 1.0 / a)
        declared = declared_belief(beliefs, a)
        rows[str(method)] = (table.correct[mine], beliefs.max(axis=1), declared.max(axis=1))
    return rows


def candidates(workspace: Path) -> dict[str, dict[str, DeclaredConfidence]]:
    """Per criterion, per model (RA-POMDP's and the Classifier), the declared confidence fitted
    on the observe stage's own held-out walks (the stage's seed)."""
    ws = Workspace(workspace)
    config = ws.config()
    inputs = ws.inputs(get_stage("observe"))
    result = observe_inputs(config, inputs, load_dataset(inputs.dataset), threads=1,
                            progress=False)
    directions = fibonacci_directions(config.viewpoints.count, hemisphere=True)
    out = {}
    for criterion in ("log_loss", "confidence"):
        fits = held_out_declared_confidence(
            result.evidence, result.belief_folds, result.temperatures, result.corrections,
            directions, TEMPERATURE_WALKS_PER_ROW, TEMPERATURE_NEIGHBOURS,
            class_seed(config.seed, "observe/declared"), criterion)
        out[criterion] = {"ra": fits[f"ra_{result.ra_variant}"],
                          "classifier": fits["classifier"]}
    return out


def run_candidates(by_config: dict[str, list[Path]], random_threshold: float) -> None:
    print("\n3) second round, held out (leave-one-group-out ECE at the stops; mean of seeds)")
    ece: dict[tuple[str, str, str], list[float]] = defaultdict(list)
    at_random: dict[tuple[str, str], list[tuple[float, float]]] = defaultdict(list)
    for config, workspaces in by_config.items():
        for w in workspaces:
            fits = candidates(w)
            for criterion, models in fits.items():
                for model, fit in models.items():
                    ece[config, criterion, model].append(fit.declared_ece)
                    k = fit.thresholds.index(random_threshold)
                    print(f"{str(w):44s} {criterion:10s} {model:10s} a {fit.temperature:.3f} "
                          f"ECE belief {fit.ece:.3f} declared {fit.declared_ece:.3f} | at "
                          f"{random_threshold:g}: a {fit.threshold_temperatures[k]:.3f} ECE "
                          f"belief {fit.threshold_ece[k]:.3f} pooled a "
                          f"{fit.threshold_declared_ece[k]:.3f} own a "
                          f"{fit.threshold_own_ece[k]:.3f}")
                    if model == "classifier":
                        at_random[config, criterion].append(
                            (fit.threshold_declared_ece[k], fit.threshold_own_ece[k]))
    means = {key: float(np.mean(v)) for key, v in ece.items()}
    for key, value in sorted(means.items()):
        print(f"  {key[0]:24s} {key[1]:10s} {key[2]:10s} held-out ECE {value:.3f}")
    b_wins = all(means[c, "confidence", m] < means[c, "log_loss", m]
                 for c in by_config for m in RULE_MODELS)
    kept = "confidence" if b_wins else "log_loss"
    print(f"rule 1 (B's ECE below A's for {' and '.join(RULE_MODELS)} on every set): "
          f"{'met: B' if b_wins else 'not met: A stays'}")
    own_wins = True
    for c in by_config:
        pooled, own = np.mean(at_random[c, kept], axis=0)
        own_wins &= bool(own < pooled)
        print(f"  {c:24s} {kept:10s} classifier at {random_threshold:g}: ECE pooled a "
              f"{pooled:.3f}, own a {own:.3f}")
    print(f"rule 2 (Random's own threshold's a, ECE below the pooled a's on every set): "
          f"{'met: C' if own_wins else 'not met: the pooled a'}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    parser.add_argument("--candidates", action="store_true",
                        help="the second round's candidates, held out (recomputes observe)")
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
    if args.candidates:
        thresholds = {Workspace(w).config().evaluate.random.belief_threshold
                      for w in args.workspace}
        if len(thresholds) != 1:
            raise SystemExit(f"the workspaces' Random thresholds differ: {sorted(thresholds)}")
        run_candidates(by_config, thresholds.pop())


if __name__ == "__main__":
    main()
