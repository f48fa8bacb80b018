"""The self-awareness figures of a finished workspace: the stages' seconds, the held-out
validation of RA-POMDP's model and the other models, the quality table on the test models, the
fitted temperatures and the held-out belief calibration (naive against tempered).

    python benchmarks/awareness_quality.py W [W2 ...]
"""

from __future__ import annotations

import sys
from pathlib import Path

from rapomdp.io import read_json


def main(workspaces: list[str]) -> None:
    for root in map(Path, workspaces):
        manifest = read_json(root / "manifest.json")["stages"]
        train_s = manifest["train"]["seconds"]
        total_s = sum(stage["seconds"] for stage in manifest.values())
        calibration = read_json(root / "observe" / "calibration.json")
        print(f"\n== {root}")
        print(f"stages: {total_s:.0f} s in all; train {train_s:.1f} s; accuracy of the "
              f"classifier on its volume models {calibration['volume_accuracy']:.3f}")
        print(f"RA-POMDP's model (observe.ra_model {calibration['ra_model_configured']}): "
              f"ra_{calibration['ra_model']}; {calibration['pairs']} (volume model, viewpoint) "
              "pairs")
        if (root / "observe" / "validation.md").exists():
            print("\nheld-out validation (leave-one-group-out):")
            print((root / "observe" / "validation.md").read_text())
        print("quality on the test models (single view):")
        print((root / "observe" / "quality.md").read_text())
        print("| model | temperature | held-out ECE first view naive -> tempered "
              "| last view naive -> tempered | held-out belief/accuracy last view |")
        print("|---|---|---|---|---|")
        held = calibration.get("held_out_belief", {})
        for name, t in calibration["temperatures"].items():
            h = held.get(name)
            if h is None:
                print(f"| {name} | {t:.3f} | - | - | - |")
                continue
            print(f"| {name} | {t:.3f} | {h['ece_first_naive']:.3f} -> "
                  f"{h['ece_first_tempered']:.3f} | {h['ece_last_naive']:.3f} -> "
                  f"{h['ece_last_tempered']:.3f} | {h['belief_last_tempered']:.3f} / "
                  f"{h['accuracy_last']:.3f} |")


if __name__ == "__main__":
    main(sys.argv[1:])
