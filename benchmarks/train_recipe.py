"""The classifier's training recipe compared on held-out objects only: each variant (a set of
``train.*`` overrides) retrains the classifier of finished workspaces on hard-linked copies
(``rapomdp run --until classifier_eval``) and is scored by what a recipe choice may read:

* training and validation accuracy of the final epoch (validation: held-out *views* of the
  training models, ``train.validation_fraction``), and the best validation epoch;
* volume accuracy: the classifier's single-view accuracy over X_rho on the *volume* models,
  objects it never trained on (the observe stage's held-out evidence); the test models'
  outputs are never read;
* the train stage's wall seconds.

    OMP_NUM_THREADS=1 python benchmarks/train_recipe.py -w W1 [W2 ...] \\
        --variant current: --variant wide:train.width=0.5 ...

A variant is ``LABEL:KEY=VALUE,KEY=VALUE`` (no overrides: the workspace's own recipe, retrained
with this tree's code so every row is timed in the same session). The first row of each
workspace, ``(as found)``, is its classifier's volume accuracy as it is, and every variant's
Δ is against it. With ``--ensemble`` the mean of all the rows' probabilities is scored too
(accuracy and single-view confidence − accuracy). Run it from the folder a dataset's
relative ``path`` is relative to.
Measured: ``benchmarks/results/train_recipe.txt``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from stage_speed import workspace_copies  # noqa: E402
from tree_run import tree_env  # noqa: E402

from rapomdp.data.dataset import load_dataset  # noqa: E402
from rapomdp.io import save_npz  # noqa: E402
from rapomdp.recognition.artefacts import load_volume_probabilities  # noqa: E402

SRC = Path(__file__).resolve().parents[1] / "src"


def parse_variant(text: str) -> tuple[str, list[str]]:
    """``LABEL:K=V,K=V`` as the label and its overrides."""
    label, _, overrides = text.partition(":")
    if not label:
        raise argparse.ArgumentTypeError(f"variant '{text}' has no label (LABEL:K=V,...)")
    return label, [o for o in overrides.split(",") if o]


def volume_outputs(workspace: Path) -> tuple[np.ndarray, np.ndarray]:
    """The classifier's probabilities (N, C) at X_rho of every volume model's view, and the
    true classes (N,) (never the test models)."""
    dataset = load_dataset(workspace / "dataset")
    outputs = load_volume_probabilities(workspace / "classifier_eval")
    models = dataset.with_role("volume")
    probabilities = np.concatenate([outputs.of(m) for m in models])
    labels = np.concatenate([np.full(len(outputs.of(m)), dataset.label(m)) for m in models])
    return probabilities, labels


def volume_accuracy(workspace: Path) -> float:
    """Single-view accuracy over X_rho on the volume models (never the test models)."""
    probabilities, labels = volume_outputs(workspace)
    return float((probabilities.argmax(axis=1) == labels).mean())


def single_view_figures(probabilities: np.ndarray, labels: np.ndarray) -> str:
    """Accuracy and confidence − accuracy of single views (the mean top probability)."""
    accuracy = float((probabilities.argmax(axis=1) == labels).mean())
    return (f"accuracy {accuracy:.3f}, confidence − accuracy "
            f"{float(probabilities.max(axis=1).mean()) - accuracy:+.3f}")


def score(workspace: Path, overrides: list[str], threads: int) -> dict[str, float]:
    """Retrain in ``workspace`` (a copy) with ``overrides`` and read the held-out figures."""
    subprocess.run([sys.executable, "-c", "from rapomdp.cli import main; main()", "run",
                    "-w", str(workspace), "--threads", str(threads), "--redo", "train",
                    "--until", "classifier_eval", *overrides],
                   env=tree_env(SRC), check=True, stdout=subprocess.DEVNULL)
    training = json.loads((workspace / "train" / "classifier.json").read_text())["training"]
    history = np.genfromtxt(workspace / "train" / "history.csv", delimiter=",", names=True)
    return {"train": training["final_train_accuracy"],
            "validation": training["final_validation_accuracy"],
            "best_validation": float(np.max(history["val_accuracy"])),
            "best_epoch": int(history["epoch"][np.argmax(history["val_accuracy"])]),
            "volume": volume_accuracy(workspace), "seconds": training["wall_s"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    parser.add_argument("--variant", type=parse_variant, action="append", required=True,
                        help="LABEL:KEY=VALUE,... (repeatable); Δ volume is against the "
                        "workspace's classifier as found")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--ensemble", action="store_true",
                        help="also score the mean of every row's probabilities (the "
                        "classifier as found and each variant's) on the volume models")
    parser.add_argument("--save-ensemble", type=Path, default=None, metavar="DIR",
                        help="with --ensemble: write the ensemble's labels of the volume "
                        "models to DIR/<configuration>-<seed>.npz")
    args = parser.parse_args()
    print(f"# python benchmarks/train_recipe.py {' '.join(sys.argv[1:])}")
    print(f"{'workspace':<40} {'variant':<16} {'train':>6} {'val':>6} {'best val':>8} "
          f"{'@ep':>4} {'volume':>7} {'Δ volume':>9} {'train s':>8}")
    for workspace in args.workspace:
        labels = [label for label, _ in args.variant]
        reference = volume_accuracy(workspace)
        print(f"{str(workspace)[-40:]:<40} {'(as found)':<16} {'':>6} {'':>6} {'':>8} "
              f"{'':>4} {reference:7.3f}", flush=True)
        members = [volume_outputs(workspace)]
        with workspace_copies(workspace, labels) as copies:
            for label, overrides in args.variant:
                s = score(copies[label], overrides, args.threads)
                print(f"{str(workspace)[-40:]:<40} {label:<16} {s['train']:6.3f} "
                      f"{s['validation']:6.3f} {s['best_validation']:8.3f} "
                      f"{s['best_epoch']:4d} {s['volume']:7.3f} "
                      f"{s['volume'] - reference:+9.3f} {s['seconds']:8.1f}", flush=True)
                members.append(volume_outputs(copies[label]))
        if args.ensemble:
            truth = members[0][1]
            for i, (p, _) in enumerate(members):
                name = "(as found)" if i == 0 else labels[i - 1]
                print(f"  {name}: {single_view_figures(p, truth)}")
            mean = np.mean([p for p, _ in members], axis=0)
            print(f"  ensemble of the {len(members)} (mean of their probabilities): "
                  f"{single_view_figures(mean, truth)}", flush=True)
            if args.save_ensemble is not None:
                # the ensemble's labels of each volume model at X_rho, for
                # held_out_closed_loop.py --volume-labels
                dataset = load_dataset(workspace / "dataset")
                files = [m.file for m in dataset.with_role("volume")]
                labels_vc = mean.argmax(axis=1).reshape(len(files), -1)
                args.save_ensemble.mkdir(parents=True, exist_ok=True)
                save_npz(args.save_ensemble / f"{workspace.parent.name}-{workspace.name}.npz",
                         files=np.array(files), predicted=labels_vc)


if __name__ == "__main__":
    main()
