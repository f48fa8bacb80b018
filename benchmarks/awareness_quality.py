"""The self-awareness figures of a finished workspace: what the cross-fitting cost against the
classifier's training (same run, so the ratio is fair on a loaded machine), the held-out
validation that chose RA-POMDP's model, the quality table on the test models, the fitted
temperatures and level shifts, and the held-out belief calibration (naive against tempered).

    python benchmarks/awareness_quality.py W [W2 ...]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from rapomdp.awareness.evidence import Evidence, fit_observation_models, validation_quality
from rapomdp.config import load_config
from rapomdp.io import load_npz, read_json


def transfer(root: Path) -> list[dict[str, float | str]]:
    """Models fitted on the cross-fitted folds only, scored on the volume models under the
    trained classifier: does what the fold classifiers show transfer to the classifier the
    planner uses (on objects neither trained on)?"""
    data = load_npz(root / "observe" / "observation_models.npz")
    config_path = root / "config.yaml"
    cfg = load_config(config_path if config_path.exists() else None).observe
    evidence = Evidence(data["evidence_labels"], data["evidence_predictions"],
                        data["evidence_groups"])
    folds = evidence.subset(evidence.groups > 0)
    scores = {"mean": data["scores"], "area": data["area_scores"]}
    models = fit_observation_models(folds, scores, [str(c) for c in data["classes"]], cfg,
                                    data["directions"])
    return validation_quality(evidence, [(evidence.groups == 0, models)])


def main(workspaces: list[str]) -> None:
    for root in map(Path, workspaces):
        manifest = read_json(root / "manifest.json")["stages"]
        train_s, crossfit_s = manifest["train"]["seconds"], manifest["crossfit"]["seconds"]
        total_s = sum(stage["seconds"] for stage in manifest.values())
        crossfit = read_json(root / "crossfit" / "crossfit.json")
        calibration = read_json(root / "observe" / "calibration.json")
        print(f"\n== {root}")
        print(f"stages: {total_s:.0f} s in all; train {train_s:.1f} s; crossfit {crossfit_s:.1f} s "
              f"({crossfit['folds']} folds x {crossfit['epochs']} epochs, "
              f"{crossfit_s / train_s:.2f}x the training); held-out accuracy of the fold "
              f"classifiers {crossfit['held_out_accuracy']:.3f}, of the classifier on its "
              f"volume models {calibration['volume_accuracy']:.3f}")
        print(f"RA-POMDP's model (observe.ra_model {calibration['ra_model_configured']}): "
              f"ra_{calibration['ra_model']}; evidence {calibration['evidence']}, "
              f"{calibration['pairs']} (model, viewpoint) pairs")
        if (root / "observe" / "validation.md").exists():
            print("\nheld-out validation (leave-one-group-out):")
            print((root / "observe" / "validation.md").read_text())
        if (np.asarray(load_npz(root / "observe" / "observation_models.npz")[
                "evidence_groups"]) > 0).any():
            print("transfer: fitted on the cross-fitted folds only, scored on the volume "
                  "models under the trained classifier:")
            print("| model | log-likelihood | Brier | AUC | mean P(correct) | accuracy |")
            print("|---|---|---|---|---|---|")
            for r in transfer(root):
                print(f"| {r['model']} | {r['log_likelihood']:.3f} | {r['brier']:.3f} | "
                      f"{r['auc']:.3f} | {r['mean_p_correct']:.3f} | {r['accuracy']:.3f} |")
            print()
        print("quality on the test models (single view):")
        print((root / "observe" / "quality.md").read_text())
        print("| model | level shift | temperature | held-out ECE first view naive -> tempered "
              "| last view naive -> tempered | held-out belief/accuracy last view |")
        print("|---|---|---|---|---|---|")
        held = calibration.get("held_out_belief", {})
        for name, t in calibration["temperatures"].items():
            h = held.get(name)
            shift = calibration.get("level_shifts", {}).get(name, 0.0)
            if h is None:
                print(f"| {name} | {shift:.2f} | {t:.3f} | - | - | - |")
                continue
            print(f"| {name} | {shift:.2f} | {t:.3f} | {h['ece_first_naive']:.3f} -> "
                  f"{h['ece_first_tempered']:.3f} | {h['ece_last_naive']:.3f} -> "
                  f"{h['ece_last_tempered']:.3f} | {h['belief_last_tempered']:.3f} / "
                  f"{h['accuracy_last']:.3f} |")


if __name__ == "__main__":
    main(sys.argv[1:])
