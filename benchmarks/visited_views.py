"""Where does each method look after its first view, and are those views any good?

For every workspace, each method's *later* views (every view after an episode's first) on the
test models: their single-view accuracy on the episode's own object against that object's
average over all of X_rho (below 0: the method moves to views worse than the object's average,
e.g. the neighbours of a wrong start, whose labels repeat it); the held-out per-viewpoint
accuracy of those views (the volume models' accuracy at that viewpoint, pooled over classes:
what held-out evidence says of the views chosen); how concentrated the views are (the share of
the five most visited); and, per observation model, how much its rows vary over viewpoints
(the standard deviation over viewpoints of each row's mutual information I(o; c | x) under a
uniform prior: 0 for a model that thinks every view is worth the same); and whether the
per-viewpoint accuracy pooled over classes carries between held-out objects at all: for each
volume group, the correlation over viewpoints of its objects' accuracy with the other groups'
(smoothed by a Gaussian of ``--bandwidth-deg`` over the angle between viewpoints), averaged
over the groups. Where the views are: the mean elevation of each method's later views (90° is
straight down on the object) and, per workspace, the held-out accuracy in elevation bands of
``--band-deg`` pooled over classes, per volume group, with the count of groups whose top band is
their worst, and the mean movement energy from every reachable viewpoint to the reachable
viewpoints of each band (the top of a hemisphere is its hub: near everything), and what the
chosen RA model believes of each band held out: its mean P(correct) there, each volume group
scored by the models fitted without it, beside that band's held-out accuracy.

A diagnostic: it reads the test models' episodes and labels, so nothing here may drive a
choice.

    python benchmarks/visited_views.py -w W [W ...] [--methods random classifier ra]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from rapomdp.awareness.choices import RecordedObservation
from rapomdp.awareness.evidence import observed_probabilities, recorded_evidence
from rapomdp.awareness.variants import leave_one_group_out
from rapomdp.experiment.episode import Motion
from rapomdp.experiment.episode_table import EPISODES_FILE, EpisodeTable
from rapomdp.geometry.viewsphere import azimuth_zenith, geodesic_distance_matrix
from rapomdp.io import load_npz
from rapomdp.recognition.artefacts import load_xrho_probabilities
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import Workspace

TOP_VIEWS = 5


def held_out_view_accuracy_transfer(correct: np.ndarray, groups: np.ndarray,
                                    directions: np.ndarray, bandwidth_deg: float) -> float:
    """Mean over volume groups of the correlation, over viewpoints, between a group's accuracy
    and the other groups' accuracy smoothed over neighbouring viewpoints; ``correct`` (M, V)."""
    angle = np.degrees(geodesic_distance_matrix(directions, radius_m=1.0))
    kernel = np.exp(-0.5 * (angle / bandwidth_deg) ** 2)
    kernel /= kernel.sum(axis=1, keepdims=True)
    names = np.unique(groups)
    if names.size < 2:
        return float("nan")
    return float(np.mean([
        np.corrcoef(kernel @ correct[groups != g].mean(axis=0),
                    correct[groups == g].mean(axis=0))[0, 1] for g in names]))


def elevation_band(elevation_deg: np.ndarray, band_deg: float) -> np.ndarray:
    """Each viewpoint's elevation band (V,): 0 for [0, band_deg), the last one ending at 90°."""
    return np.minimum((elevation_deg // band_deg).astype(np.int64),
                      int(np.ceil(90 / band_deg)) - 1)


def band_accuracy(correct: np.ndarray, groups: np.ndarray, elevation_deg: np.ndarray,
                  band_deg: float) -> np.ndarray:
    """Accuracy (G, B) of each volume group's objects in each elevation band of ``band_deg``
    (from 0° to 90°), pooled over classes; ``correct`` (M, V)."""
    band = elevation_band(elevation_deg, band_deg)
    count = np.bincount(band, minlength=band.max() + 1)
    return np.stack([np.bincount(band, weights=correct[groups == g].mean(axis=0),
                                 minlength=count.size) / np.maximum(count, 1)
                     for g in np.unique(groups)])


def band_energy(energy: np.ndarray, reachable: np.ndarray, elevation_deg: np.ndarray,
                band_deg: float) -> np.ndarray:
    """Mean movement energy (B,) from every reachable viewpoint to the other reachable
    viewpoints of each elevation band (NaN for a band with none)."""
    band = elevation_band(elevation_deg, band_deg)
    moves = reachable[:, None] & reachable[None, :] & ~np.eye(reachable.size, dtype=bool)
    total = np.bincount(band, weights=np.where(moves, energy, 0.0).sum(axis=0),
                        minlength=band.max() + 1)
    count = np.bincount(band, weights=moves.sum(axis=0), minlength=band.max() + 1)
    return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def held_out_band_belief(root: Path, elevation_deg: np.ndarray, band_deg: float
                         ) -> tuple[str, np.ndarray]:
    """The chosen RA model's name and its mean held-out P(correct) (B,) per elevation band: each
    volume group scored by the models fitted on the other groups, as the observe stage fits
    them."""
    recorded = RecordedObservation.load(root / "observe")
    evidence = recorded.evidence
    folds = leave_one_group_out(evidence, recorded.scores, recorded.classes,
                                Workspace(root).config().observe,
                                recorded.arrays["directions"], recorded.transfer_kernel)
    p_correct = np.full(evidence.predicted.shape, np.nan)
    for held, models in folds:
        part = evidence.subset(held)
        p_correct[held] = observed_probabilities(models[recorded.variant].probabilities,
                                                 part.labels, part.predicted)[1]
    band = elevation_band(elevation_deg, band_deg)
    per_view = np.nanmean(p_correct, axis=0)
    count = np.bincount(band, minlength=band.max() + 1)
    return recorded.variant, np.bincount(band, weights=per_view,
                                         minlength=count.size) / np.maximum(count, 1)


def viewpoint_information(model: np.ndarray) -> np.ndarray:
    """I(o; c | x) per viewpoint (V,) of a model P(o | c, x) (V, C, O), uniform prior on c."""
    rows = model / model.sum(axis=2, keepdims=True)
    marginal = rows.mean(axis=1, keepdims=True)
    ratio = np.log(np.maximum(rows, 1e-300)) - np.log(np.maximum(marginal, 1e-300))
    return (rows * ratio).sum(axis=2).mean(axis=1)


def later_views(table: EpisodeTable, method: str) -> tuple[np.ndarray, np.ndarray]:
    """The episode index and viewpoint of every view after the first of ``method``'s episodes."""
    episodes = np.flatnonzero(table.method == method)
    starts, ends = table.offsets[episodes] + 1, table.offsets[episodes + 1]
    lengths = np.maximum(ends - starts, 0)
    owner = np.repeat(episodes, lengths)
    # each step's index: its episode's first later step plus its rank within the episode
    rank = np.arange(lengths.sum()) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    return owner, table.step_viewpoints[np.repeat(starts, lengths) + rank]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, nargs="+", required=True)
    parser.add_argument("--methods", nargs="+", default=["random", "vptree", "classifier", "ra"])
    parser.add_argument("--models", nargs="+", default=["ra", "classifier"],
                        help="observation models whose viewpoint information is printed")
    parser.add_argument("--bandwidth-deg", type=float, default=20.0,
                        help="smoothing of the held-out groups' per-viewpoint accuracy")
    parser.add_argument("--band-deg", type=float, default=15.0,
                        help="width of the elevation bands of the held-out accuracy")
    args = parser.parse_args()
    print("later views: views after an episode's first; own: their accuracy on the episode's "
          "object minus that object's mean over X_rho; held-out: the volume models' accuracy "
          f"at those viewpoints; top {TOP_VIEWS}: share of the most visited; elev.: their mean "
          "elevation (degrees)")
    print(f"{'workspace':40s} {'method':10s} {'views':>6s} {'accuracy':>8s} {'own':>7s} "
          f"{'held-out':>8s} {'top ' + str(TOP_VIEWS):>6s} {'elev.':>6s}")
    top_worst, cells = 0, 0
    for root in args.workspace:
        table = EpisodeTable.load(root / "evaluate" / EPISODES_FILE)
        probabilities = load_xrho_probabilities(root / "classifier_eval")
        observe = load_npz(root / "observe" / "observation_models.npz")
        evidence = recorded_evidence(observe)
        held_out_accuracy = evidence.correct.mean(axis=0)  # (V,)
        elevation = 90.0 - np.degrees(azimuth_zenith(observe["directions"])[1])
        files = sorted(set(str(f) for f in table.model))
        predicted = np.stack([probabilities.by_file[f].argmax(axis=1) for f in files])  # (M, V)
        index = {f: i for i, f in enumerate(files)}
        episode_object = np.array([index[str(f)] for f in table.model])
        right_at = predicted[episode_object] == table.class_index[:, None]  # (E, V)
        for method in args.methods:
            owner, views = later_views(table, method)
            if views.size == 0:
                print(f"{str(root):40s} {method:10s} {0:6d}")
                continue
            right = right_at[owner, views]
            own = right.mean() - right_at[owner].mean(axis=1).mean()
            counts = np.bincount(views, minlength=held_out_accuracy.size)
            top = np.sort(counts)[::-1][:TOP_VIEWS].sum() / counts.sum()
            print(f"{str(root):40s} {method:10s} {views.size:6d} {right.mean():8.3f} "
                  f"{own:+7.3f} {held_out_accuracy[views].mean():8.3f} {top:6.2f} "
                  f"{elevation[views].mean():6.1f}")
        info = {name: viewpoint_information(observe[name]) for name in args.models
                if name in observe}
        transfer = held_out_view_accuracy_transfer(
            evidence.correct.astype(np.float64), evidence.groups, observe["directions"],
            args.bandwidth_deg)
        print(f"{str(root):40s} viewpoint information, sd over viewpoints: " + ", ".join(
            f"{name} {values.std():.4f}" for name, values in info.items())
            + f"; held-out per-viewpoint accuracy, group against the others: r = {transfer:+.2f}")
        bands = band_accuracy(evidence.correct.astype(np.float64), evidence.groups, elevation,
                              args.band_deg)
        top_worst += int((bands.argmin(axis=1) == bands.shape[1] - 1).sum())
        cells += bands.shape[0]
        print(f"{str(root):40s} held-out accuracy per {args.band_deg:g}° elevation band "
              "(low to high), per volume group: "
              + "; ".join(" ".join(f"{a:.2f}" for a in row) for row in bands))
        motion = Motion.from_robot(load_robot(root / "robot"))
        to_band = band_energy(motion.energy, motion.reachable, elevation, args.band_deg)
        print(f"{str(root):40s} mean energy (m) from the reachable viewpoints to each band: "
              + " ".join(f"{e:.3f}" for e in to_band))
        variant, believed = held_out_band_belief(root, elevation, args.band_deg)
        actual = band_accuracy(evidence.correct.astype(np.float64),
                               np.zeros(len(evidence.labels), dtype=np.int64), elevation,
                               args.band_deg)[0]
        print(f"{str(root):40s} {variant} held out, P(correct) / accuracy per band: "
              + " ".join(f"{p:.2f}/{a:.2f}" for p, a in zip(believed, actual, strict=True)))
    print(f"the top elevation band is a volume group's worst in {top_worst} of {cells}")


if __name__ == "__main__":
    main()
