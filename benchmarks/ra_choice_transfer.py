"""Does the held-out choice of the RA model transfer to the test models? For every workspace of
a study (or the workspaces named), the variant the observe stage chose on held-out objects
against the best RA variant on the test models (AUC and log-likelihood per observation, from
the stage's quality table), and the chosen model against the black box and the Classifier.

A diagnostic read after every choice was made: nothing here feeds a choice.

    python benchmarks/ra_choice_transfer.py -s runs/study     # every S/CONFIGURATION/seed-N
    python benchmarks/ra_choice_transfer.py -w W1 -w W2
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rapomdp.awareness.artefacts import load_quality, load_ra_choice

#: The RA variants the observe stage chooses among (quality rows ``ra_<variant>``).
RA_PREFIX = "ra_"


def workspace_row(workspace: Path) -> dict[str, object]:
    """The chosen variant's and the best variant's test AUC and log-likelihood."""
    observe = workspace / "observe"
    choice = load_ra_choice(observe)
    quality = {str(row["model"]): row for row in load_quality(observe)}
    variants = {name: row for name, row in quality.items() if name.startswith(RA_PREFIX)}
    chosen = variants[RA_PREFIX + choice.variant]
    best_auc = max(variants, key=lambda n: float(variants[n]["auc"]))
    best_ll = max(variants, key=lambda n: float(variants[n]["log_likelihood"]))
    return {
        "workspace": workspace,
        "chosen": choice.variant,
        "fallback": choice.rule == "too little evidence",
        "auc": float(chosen["auc"]),
        "auc_gap": float(variants[best_auc]["auc"]) - float(chosen["auc"]),
        "best_auc": best_auc.removeprefix(RA_PREFIX),
        "ll": float(chosen["log_likelihood"]),
        "ll_gap": float(variants[best_ll]["log_likelihood"]) - float(chosen["log_likelihood"]),
        "best_ll": best_ll.removeprefix(RA_PREFIX),
        "blackbox": (float(quality["blackbox"]["auc"]),
                     float(quality["blackbox"]["log_likelihood"])),
        "classifier": (float(quality["classifier"]["auc"]),
                       float(quality["classifier"]["log_likelihood"])),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", "-s", type=Path)
    parser.add_argument("--workspace", "-w", type=Path, action="append", default=[])
    args = parser.parse_args()
    workspaces = list(args.workspace)
    if args.study:
        found = args.study.glob("*/seed-*/observe/quality.csv")
        workspaces += sorted(p.parent.parent for p in found)
    if not workspaces:
        parser.error("no workspace with an observe stage: give --study or --workspace")
    print("chosen: the held-out choice; gap: best RA variant on the test models minus the "
          "chosen one (target <= 0.02); bb / cl: black box and Classifier (AUC, LL)")
    print(f"{'workspace':<34}{'chosen':<13}{'AUC':>7}{'gap':>7} {'best':<12}{'LL':>8}"
          f"{'gap':>7} {'best':<12}{'bb AUC':>8}{'bb LL':>8}{'cl AUC':>8}{'cl LL':>8}")
    for w in workspaces:
        r = workspace_row(w)
        name = "/".join(Path(str(r["workspace"])).parts[-2:])
        chosen = f"{r['chosen']}{'*' if r['fallback'] else ''}"
        bb, cl = r["blackbox"], r["classifier"]
        print(f"{name:<34}{chosen:<13}{r['auc']:>7.3f}{r['auc_gap']:>7.3f} {r['best_auc']:<12}"
              f"{r['ll']:>8.3f}{r['ll_gap']:>7.3f} {r['best_ll']:<12}{bb[0]:>8.3f}{bb[1]:>8.3f}"
              f"{cl[0]:>8.3f}{cl[1]:>8.3f}")
    print("*: too little held-out evidence, the robust default")


if __name__ == "__main__":
    main()
