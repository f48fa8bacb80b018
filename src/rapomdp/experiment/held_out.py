"""The held-out closed loop: each POMDP method run on objects its observation model never saw.

For every volume group g (the g-th volume model of every class), a method's model is the one
fitted without g (as the observe or vptree stage fitted it for its held-out walks), tempered by
the belief's own t, solved at λ and run from seeded starts on each of g's models, its views
the labels the classifier gave that model at X_rho (recorded by the stages: an episode is
exact). Where these episodes stop is where the method itself stops on unseen objects, so its
declared confidence is fitted there
(:func:`~rapomdp.recognition.belief.stops_declared_confidence`). Only volume models and their
recorded labels are read, never the test models.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from rapomdp.awareness.choices import RecordedObservation
from rapomdp.belief import safe_log, temper
from rapomdp.config import Config
from rapomdp.context import RunContext
from rapomdp.data.splits import class_seed
from rapomdp.experiment.episode import Motion, Policy, run_episode
from rapomdp.experiment.learned import LearnedPolicy, load_learned_policy
from rapomdp.experiment.methods import POMDPPolicy, RandomWalkPolicy, StaticPolicy
from rapomdp.experiment.metrics import cluster_bootstrap_difference, paired_cluster_sums
from rapomdp.experiment.sections import LEARNED
from rapomdp.io import load_npz, read_json, write_json_atomic
from rapomdp.parallel import run_tasks
from rapomdp.planning.artefacts import policy_file
from rapomdp.planning.policy import ActiveRecognitionPolicy
from rapomdp.recognition.artefacts import VPTREE_OBSERVATION_FILE
from rapomdp.recognition.belief import DeclaredConfidence, stops_declared_confidence
from rapomdp.recognition.vptree_stage import vptree_folds
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import StageError, StageInputs

HELD_OUT_STARTS = 4
"""Seeded reachable starts per held-out model (each group's models × starts are the stops)."""

HELD_OUT_DIR = "held_out"
"""The evaluate stage's folder of the held-out closed loop (its solves and record)."""
DECLARED_FIT_FILE = "declared_fit.json"
"""The record of the closed-loop fit in :data:`HELD_OUT_DIR`."""


class LabelScene:
    """A held-out model's view at x is the index x (its label is looked up by the recogniser)."""

    def look(self, viewpoint: int, rng: np.random.Generator) -> np.ndarray:
        return np.full((1, 1), float(viewpoint))


class LabelRecogniser:
    """The classifier's recorded label at each X_rho viewpoint of one model, one-hot."""

    def __init__(self, labels: np.ndarray, classes: int) -> None:
        self.labels, self.classes = labels, classes

    def predict(self, depth_images: np.ndarray) -> np.ndarray:
        return np.eye(self.classes)[self.labels[depth_images[:, 0, 0].astype(int)]]


@dataclass(frozen=True)
class HeldOutFold:
    """One method's held-out group: its models' true classes ``labels`` (M,) and recorded
    labels ``predicted`` (M, V), and the method's ``model`` (V, C, C) fitted without them
    (the planner's and the belief's)."""

    group: int
    labels: np.ndarray
    predicted: np.ndarray
    model: np.ndarray


def held_out_folds(config: Config, inputs: StageInputs, methods: Sequence[str]
                   ) -> dict[str, list[HeldOutFold]]:
    """Each POMDP method's held-out groups (``vptree``: the vptree stage's labels of the
    volume models; the others: the observe stage's refitted folds, ``ra`` its chosen
    variant). Empty lists where there are fewer than two groups to hold out
    (:func:`closed_loop_skipped`)."""
    out: dict[str, list[HeldOutFold]] = {}
    cnn = [m for m in methods if m != "vptree"]
    if cnn:
        recorded = RecordedObservation.load(inputs.observe)
        folds = recorded.belief_folds(config.observe)
        temperatures = recorded.calibration["temperatures"]
        evidence = recorded.evidence
        for name in cnn:
            out[name] = []
            if len(folds) < 2:
                continue
            for held, models in folds:
                planner = temper(models[name].probabilities, float(temperatures[name]))
                out[name].append(HeldOutFold(int(evidence.groups[held][0]),
                                             evidence.labels[held], evidence.predicted[held],
                                             planner))
    if "vptree" in methods:
        vptree = load_npz(inputs.vptree / VPTREE_OBSERVATION_FILE)
        if "volume_predictions" not in vptree:
            raise StageError("the held-out closed loop: the vptree stage predates "
                             "the saved volume labels: rapomdp run -w W --redo vptree")
        labels, predicted = vptree["volume_labels"], vptree["volume_predictions"]
        groups, t = vptree["volume_groups"], float(vptree["temperature"])
        folds_v = vptree_folds(labels, predicted, groups, len(vptree["classes"]),
                               config.vptree.pseudo_count)
        tempered = [(held, temper(m, t)) for held, m in folds_v]
        out["vptree"] = [] if len(folds_v) < 2 else [
            HeldOutFold(int(groups[held][0]), labels[held], predicted[held], m)
            for held, m in tempered]
    return out


def closed_loop_skipped(config: Config, name: str) -> str:
    """Why a POMDP method has no held-out closed loop (it keeps the walks' a)."""
    return ("fewer than two held-out groups of volume models the trained classifier labelled "
            "(dataset.split.volume)")


class HeldOutStops(NamedTuple):
    """One method's episodes on held-out models: the final log beliefs (episodes, C), the true
    class, whether the declaration was right, the movement energy (m), the images taken and
    the start viewpoint of each."""

    log_beliefs: np.ndarray
    truth: np.ndarray
    correct: np.ndarray
    energy: np.ndarray
    images: np.ndarray
    starts: np.ndarray


def held_out_stops(config: Config, policy: Policy, fold: HeldOutFold, motion: Motion,
                   starts: int = HELD_OUT_STARTS) -> HeldOutStops:
    """Each episode of ``policy`` from ``starts`` seeded reachable starts on each held-out model
    of ``fold`` (the starts depend on the group and model only, so every method starts from
    the same ones)."""
    classes = fold.model.shape[2]
    reachable = np.flatnonzero(motion.reachable)
    finals, truth, right, energy, images, first = [], [], [], [], [], []
    for r in range(len(fold.labels)):
        rng = class_seed(config.seed, f"held-out/{fold.group}/{r}")
        for s in rng.choice(reachable, min(starts, reachable.size), replace=False):
            episode = run_episode(LabelScene(), LabelRecogniser(fold.predicted[r], classes),
                                  policy, motion, int(s), config.evaluate.max_moves, rng)
            finals.append(safe_log(episode.beliefs[-1]))
            truth.append(int(fold.labels[r]))
            right.append(episode.declared == int(fold.labels[r]))
            energy.append(float(episode.move_energy.sum()))
            images.append(len(episode.viewpoints))
            first.append(int(s))
    return HeldOutStops(np.array(finals), np.array(truth, dtype=np.int64),
                        np.array(right, dtype=bool), np.array(energy), np.array(images),
                        np.array(first, dtype=np.int64))


def load_declared_fit(evaluate_dir: Path) -> dict[str, Any] | None:
    """An evaluate stage's record of its held-out closed-loop fit (``held_out/
    declared_fit.json``), None where it fitted none (one held-out group, or a stage from
    before the fit)."""
    path = Path(evaluate_dir) / HELD_OUT_DIR / DECLARED_FIT_FILE
    return read_json(path) if path.is_file() else None


@dataclass(frozen=True)
class ClosedLoopFit:
    """One method's held-out closed loop (``run``, not recorded) and its ``declared``
    confidence fitted at the stops; the loop's accuracy, mean energy (m), episodes and stops
    read from the run."""

    declared: DeclaredConfidence
    run: HeldOutRun

    @property
    def accuracy(self) -> float:
        return self.run.accuracy

    @property
    def energy(self) -> float:
        return self.run.energy_m

    @property
    def episodes(self) -> int:
        return self.run.episodes

    @property
    def log_beliefs(self) -> np.ndarray:
        return self.run.stops.log_beliefs

    @property
    def truth(self) -> np.ndarray:
        return self.run.stops.truth

    @property
    def images(self) -> np.ndarray:
        return self.run.stops.images

    @property
    def groups(self) -> np.ndarray:
        return self.run.groups

    def to_dict(self) -> dict[str, object]:
        return {"declared_confidence": self.declared.to_dict(), "accuracy": self.accuracy,
                "energy": self.energy, "episodes": self.episodes}


def _held_out_task(config_json: str, inputs: StageInputs, name: str, fold: HeldOutFold,
                   plans: str | None) -> HeldOutStops:
    """A worker's task: one method's episodes on one held-out group (:func:`held_out_stops`);
    ``plans``: the POMDP's policy file, None for Static, Random and the learned baseline."""
    config = Config.model_validate_json(config_json)
    motion = Motion.from_robot(load_robot(inputs.robot))
    policy: Policy
    if name == "static":  # the start view's label, declared
        policy = StaticPolicy("static")
    elif name == "random":  # its walk at Table 1's threshold
        walk = config.evaluate.random
        policy = RandomWalkPolicy(fold.model, motion.distance_m, motion.reachable,
                                  walk.neighbours, walk.belief_threshold, walk.max_moves, name)
    elif plans is None:
        network, spec = load_learned_policy(inputs.learn, config.solve.wrong_declaration_cost_m)
        policy = LearnedPolicy(network, spec, fold.model, motion.reachable, name)
    else:
        policy = POMDPPolicy.configured(config.evaluate, ActiveRecognitionPolicy.load(plans),
                                        fold.model, name, motion.reachable)
    return held_out_stops(config, policy, fold, motion)


NOT_POMDP = ("static", "random", LEARNED)
"""The methods that are no POMDP policies (solved per λ): Static, Random, and the learned
baseline (trained per λ by the learn stage)."""


@dataclass(frozen=True)
class HeldOutRun:
    """One method's held-out closed loop: its ``stops`` and each episode's held-out volume
    ``groups``."""

    stops: HeldOutStops
    groups: np.ndarray

    @property
    def accuracy(self) -> float:
        return float(self.stops.correct.mean())

    @property
    def energy_m(self) -> float:
        return float(self.stops.energy.mean())

    @property
    def episodes(self) -> int:
        return int(self.stops.truth.size)

    def objects(self) -> np.ndarray:
        """Each episode's held-out object, ``group/class`` (group g holds the g-th volume model
        of every class, so the pair names one model whichever stage labelled it)."""
        return np.char.add(np.char.add(self.groups.astype(str), "/"),
                           self.stops.truth.astype(str))

    def pairs(self) -> np.ndarray:
        """Each episode's (object, start) key, ``group/class#start``: what pairs two methods."""
        return np.char.add(np.char.add(self.objects(), "#"), self.stops.starts.astype(str))


def held_out_runs(config: Config, inputs: StageInputs, methods: Sequence[str],
                  context: RunContext = RunContext()
                  ) -> tuple[dict[str, HeldOutRun], dict[str, str]]:
    """Every method of ``methods`` run on each held-out volume group.

    The belief (and a POMDP's lookahead) by its observation model fitted without the group, a
    POMDP by the solve stage's plan; the learned baseline by the learn stage's policy at Table
    1's λ; Random walking at Table 1's threshold on its observation model's folds; Static
    declaring its start view's label (on RA-POMDP's folds).

    Args:
        config: the workspace's configuration.
        inputs: the evaluate stage's input folders.
        methods: the method keys to run (of ``evaluate.methods``).
        context: the run's workers and progress.

    Returns:
        Each run method's :class:`HeldOutRun`, by key, and for each method without held-out
        folds, why (:func:`closed_loop_skipped`).
    """
    model_of = {name: name for name in methods}
    if "random" in methods:
        model_of["random"] = config.evaluate.random.observation_model
    if LEARNED in methods:  # its belief's observation model
        _, spec = load_learned_policy(inputs.learn, config.solve.wrong_declaration_cost_m)
        model_of[LEARNED] = spec.observation_model
    if "static" in methods:  # it reads labels only: RA-POMDP's folds hold them
        model_of["static"] = "ra"
    by_model = held_out_folds(config, inputs, sorted(set(model_of.values())))
    all_folds = {name: by_model[model] for name, model in model_of.items()}
    folds = {name: f for name, f in all_folds.items() if f}
    skipped = {name: closed_loop_skipped(config, model_of[name])
               for name in all_folds if name not in folds}
    if not folds:
        return {}, skipped
    pairs = [(name, fold) for name, fs in folds.items() for fold in fs]
    config_json = config.model_dump_json()
    tasks = []
    for name, fold in pairs:
        plans = None  # Static, Random; the learned baseline: the learn stage's policy
        if name not in NOT_POMDP:
            path = inputs.solve / policy_file(name)
            if not path.is_file():
                raise StageError(f"method '{name}' needs {path.name} from the solve stage for "
                                 f"its held-out closed loop: add '{name}' to solve.models")
            plans = str(path)
        tasks.append((config_json, inputs, name, fold, plans))
    stops = run_tasks(_held_out_task, tasks, context.worker_count,
                      "evaluate: held-out closed loop", context.progress, context.scheduler,
                      unit="episodes", sizes=[len(fold.labels) * HELD_OUT_STARTS
                                              for _, fold in pairs], pool=context.pool)
    parts: dict[str, list[tuple[HeldOutStops, np.ndarray]]] = {}
    for (name, fold), part in zip(pairs, stops, strict=True):
        parts.setdefault(name, []).append((part, np.full(part.truth.size, fold.group)))
    runs = {name: HeldOutRun(HeldOutStops(*(np.concatenate(a) for a in
                                             zip(*(p for p, _ in rows), strict=True))),
                             np.concatenate([g for _, g in rows]))
            for name, rows in parts.items()}
    return runs, skipped


def closed_loop_declared(config: Config, inputs: StageInputs, methods: Sequence[str],
                         out: Path, context: RunContext = RunContext(),
                         runs: tuple[dict[str, HeldOutRun], dict[str, str]] | None = None
                         ) -> dict[str, ClosedLoopFit]:
    """Fit each method's declared confidence on its held-out closed loop and record it.

    Methods without held-out folds are left out (they keep the walks' a; the record says
    why).

    Args:
        config: the workspace's configuration.
        inputs: the evaluate stage's input folders.
        methods: the method keys to fit (``evaluate.methods`` less Static and Random).
        out: the folder ``declared_fit.json`` is written to (:data:`HELD_OUT_DIR`).
        context: the run's workers and progress.
        runs: :func:`held_out_runs`'s result for at least ``methods``, or None to run them.

    Returns:
        Each fitted method's :class:`ClosedLoopFit`, by key.
    """
    if runs is None:
        runs = held_out_runs(config, inputs, methods, context)
    ran, skipped = runs
    if not any(name in ran for name in methods):
        return {}
    fits: dict[str, ClosedLoopFit] = {}
    for name in methods:
        if name not in ran:
            continue
        stops = ran[name].stops
        declared = stops_declared_confidence(stops.log_beliefs, stops.truth, ran[name].groups)
        fits[name] = ClosedLoopFit(declared, ran[name])
    write_json_atomic(out / DECLARED_FIT_FILE, {
        "lambda_m": config.solve.wrong_declaration_cost_m,
        "starts_per_model": HELD_OUT_STARTS,
        "plans": "solve stage",
        "form": "scalar",
        "methods": {name: fit.to_dict() for name, fit in fits.items()},
        "walks_kept": {name: why for name, why in skipped.items() if name in methods}})
    return fits


COMPARISON_FILE = "comparison.json"
"""The record of :func:`held_out_comparison` in :data:`HELD_OUT_DIR`."""
NOT_HELD_OUT = {LEARNED: "the learn stage trained it on these objects' recorded labels, so its "
                         "episodes here are not held out"}
"""Methods whose held-out closed loop is not held out for them, left out of the comparison."""


def held_out_comparison(runs: Mapping[str, HeldOutRun], reference: str = "ra",
                        resamples: int = 10_000, seed: int = 0,
                        skipped: Mapping[str, str] | None = None) -> dict[str, Any]:
    """Every method's held-out accuracy and mean energy and, where it ran from the same
    (object, start) pairs as ``reference``, its paired accuracy difference to it with a 95 %
    cluster-bootstrap interval that resamples held-out objects: what objects the classifier
    and the observation models never saw say about the methods on this dataset, before any
    test model is read; each paired method's per-object sums and pair counts too (what a study
    pools over seeds). ``order``: the methods as run. A method whose pairs differ is listed
    under ``unpaired``; ``skipped``: the methods without held-out folds, and why
    (:func:`held_out_runs`); ``not_held_out``: the methods of :data:`NOT_HELD_OUT` among
    ``runs``, left out, and why."""
    left_out = {name: why for name, why in NOT_HELD_OUT.items() if name in runs}
    runs = {name: run for name, run in runs.items() if name not in left_out}
    record: dict[str, Any] = {
        "reference": reference, "order": list(runs),
        "methods": {name: {"accuracy": run.accuracy, "energy_m": run.energy_m,
                           "episodes": run.episodes, "objects": int(np.unique(
                               run.objects()).size)} for name, run in runs.items()},
        "paired": {}, "unpaired": [], "skipped": dict(skipped or {}),
        "not_held_out": left_out}
    if reference not in runs:
        return record
    base = runs[reference]
    for name, run in runs.items():
        if name == reference:
            continue
        try:
            objects, sums, sizes = paired_cluster_sums(run.pairs(), run.stops.correct,
                                                       run.objects(), base.pairs(),
                                                       base.stops.correct)
        except ValueError:
            record["unpaired"].append(name)
            continue
        estimate, low, high = cluster_bootstrap_difference(sums, sizes, resamples, seed)
        record["paired"][name] = {"difference": estimate, "low": low, "high": high,
                                  "pairs": int(sizes.sum()), "objects": int(objects.size),
                                  "per_object": {"objects": objects.tolist(),
                                                 "sums": sums.tolist(),
                                                 "pairs": sizes.astype(int).tolist()}}
    return record


def load_held_out_comparison(evaluate_dir: Path) -> dict[str, Any] | None:
    """An evaluate stage's :func:`held_out_comparison` record, None where it has none (fewer
    than two held-out groups, or a stage from before it)."""
    path = Path(evaluate_dir) / HELD_OUT_DIR / COMPARISON_FILE
    return read_json(path) if path.is_file() else None
