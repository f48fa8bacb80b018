"""The belief variants and the RA model's held-out choice, compared on held-out evidence only
(the volume models: objects the trained classifier never saw; never the test models).

For every belief variant (``observe.belief`` x ``observe.belief_correction``) the models are
fitted per volume group on the other groups, as the observe stage fits them (the nuisance's EM
included), the correction's temperature (or the similarity belief's view discount) is fitted on
the observe stage's held-out walks, and two things are measured:

* **walks**: the observe stage's held-out random walks (16 a model, 6 neighbouring views):
  the mean log loss of the belief in the true class over every step, and after steps 1, 3 and
  6 the accuracy, the confidence − accuracy and the ECE of the confidence;
* **closed loop**: RA-POMDP (solved at ``--lambda``, acting as ``evaluate.lookahead`` says)
  and Random (the ``evaluate.random`` walk with the Classifier model) from ``--starts`` seeded
  starts per held-out model on its recorded labels: accuracy, energy, confidence − accuracy,
  ECE, and each variant's paired accuracy difference against the first with a cluster-bootstrap
  interval over held-out models.

    python benchmarks/held_out_belief_models.py -w W [--variants naive:temperature
        nuisance:none similarity:fit similarity:mixed ...] [--lambda 8] [--starts 4]
        [--no-loop] [--save F]
    python benchmarks/held_out_belief_models.py --load A.npz B.npz   # the saved loops, paired
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from rapomdp.awareness.evidence import (
    MIXTURE_VARIANT,
    RecordedObservation,
    fit_observation_models,
    held_out_temperatures,
    held_out_view_discounts,
    view_similarity_kernel,
)
from rapomdp.awareness.nuisance import nuisance_belief_models
from rapomdp.awareness.observation import ObservationModel
from rapomdp.data.splits import class_seed
from rapomdp.experiment.episode import Motion, run_episode
from rapomdp.experiment.methods import POMDPPolicy, RandomWalkPolicy
from rapomdp.experiment.metrics import cluster_bootstrap_difference
from rapomdp.io import load_npz, save_npz
from rapomdp.planning.ar_solver import solve_active_recognition
from rapomdp.planning.momdp import build_active_recognition_problem
from rapomdp.planning.stage import start_viewpoint
from rapomdp.recognition.belief import (
    DISCOUNT_JUMP,
    TEMPERATURE_NEIGHBOURS,
    TEMPERATURE_WALK_LENGTH,
    TEMPERATURE_WALKS_PER_ROW,
    discounted_walk_log_beliefs,
    expected_calibration_error,
    fold_of_rows,
    held_out_groups,
    held_out_walks,
    temper,
    walk_log_beliefs,
)
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import Workspace

sys.path.insert(0, str(Path(__file__).parent))
from held_out_closed_loop import LabelRecogniser, LabelScene  # noqa: E402

STEPS = (1, 3, 6)


def belief_folds(recorded: RecordedObservation, config, belief: str, names: list[str],
                 masks: list[np.ndarray]) -> list[dict[str, ObservationModel]]:
    """Per held-out mask, the named models fitted on the other groups as the observe stage
    fits them for ``belief`` (naive: the single-view models; nuisance: the typed models)."""
    evidence, scores, classes = recorded.evidence, recorded.scores, recorded.classes
    directions = recorded.arrays["directions"]
    cfg = config.observe

    def fit(part, wanted=None):
        return {n: m.probabilities for n, m in fit_observation_models(
            part, scores, classes, cfg, directions, recorded.transfer_kernel,
            wanted).items()}

    if belief == "naive":
        return [{n: ObservationModel(p, classes) for n, p in fit(evidence.subset(~m),
                                                                  names).items()}
                for m in masks]
    _, per_fold = nuisance_belief_models(evidence, masks, fit, names,
                                         cfg.confusion_pseudo_count)
    return [{n: ObservationModel(nm.probabilities, classes, nm.prior) for n, nm in f.items()}
            for f in per_fold]


def walk_table(recorded, folds, temperatures, row_model, walks, walk_row, discounts, kernel):
    """Per model: the walk log loss and, after each of :data:`STEPS`, accuracy, confidence −
    accuracy and ECE (the beliefs with each model's temperature, or its view discount)."""
    evidence = recorded.evidence
    true = evidence.labels[walk_row]
    out = {}
    for name in folds[0]:
        models = [f[name].probabilities for f in folds]
        priors = ([f[name].prior for f in folds] if folds[0][name].prior is not None else None)
        if name in discounts:
            log_b = discounted_walk_log_beliefs(discounts[name], kernel, models, row_model,
                                                evidence.predicted, walks, walk_row, priors)
        else:
            log_b = walk_log_beliefs(temperatures[name], models, row_model,
                                     evidence.predicted, walks, walk_row, priors=priors)
        row = {"log_loss": float(-np.mean(log_b[np.arange(len(walks)), :, true]))}
        for step in STEPS:
            b = np.exp(log_b[:, step - 1])
            conf, right = b.max(axis=1), b.argmax(axis=1) == true
            row[f"acc{step}"] = float(right.mean())
            row[f"gap{step}"] = float(conf.mean() - right.mean())
            row[f"ece{step}"] = expected_calibration_error(conf, right)
        out[name] = row
    return out


def closed_loop(recorded, config, folds, masks, temperatures, motion, lam, starts, seconds,
                lookahead, discounts, kernel):
    """RA-POMDP and Random on every held-out model (its group's fold models): per method the
    episodes' (correct, energy, confidence, held-out model id)."""
    evidence = recorded.evidence
    classes = len(recorded.classes)
    cfg = config.evaluate
    start = start_viewpoint(motion.reachable)
    rows: dict[str, list[tuple[float, float, float, float]]] = {"ra": [], "random": []}
    for fold, (mask, models) in enumerate(zip(masks, folds, strict=True)):
        part = evidence.subset(mask)
        for method in rows:
            key = cfg.random.observation_model if method == "random" else "ra"
            model = temper(models[key].probabilities, temperatures[key])
            prior = models[key].prior
            # with a view discount: the updates from the single-view model, tempered per view
            extra = ({"discount": discounts[key], "similarity": kernel,
                      "first_view_model": models[key].probabilities}
                     if key in discounts else {})
            if method == "random":
                policy = RandomWalkPolicy(model, motion.distance_m, motion.reachable,
                                          cfg.random.neighbours, cfg.random.belief_threshold,
                                          cfg.random.max_moves, prior=prior, **extra)
            else:
                problem = build_active_recognition_problem(
                    model, motion.energy, motion.reachable, lam, config.solve.discount, start,
                    prior)
                solved = solve_active_recognition(problem, config.solve.precision, seconds,
                                                  max_iterations=config.solve.iterations)
                policy = POMDPPolicy(solved.policy, model, "ra", prior=prior,
                                     lookahead_over=motion.reachable if lookahead else None,
                                     **extra)
            for r in range(len(part.labels)):
                rng = class_seed(config.seed, f"held-out/{fold}/{r}")
                for s in rng.choice(np.flatnonzero(motion.reachable), starts, replace=False):
                    episode = run_episode(LabelScene(), LabelRecogniser(part.predicted[r],
                                                                        classes),
                                          policy, motion, int(s), cfg.max_moves, rng)
                    truth = int(part.labels[r])
                    rows[method].append((float(episode.declared == truth),
                                         float(episode.move_energy.sum()),
                                         float(episode.beliefs[-1].max()),
                                         float(fold * 10_000 + r)))
    return {m: np.array(v) for m, v in rows.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, default=None)
    parser.add_argument("--variants", nargs="+",
                        default=["naive:temperature", "naive:none", "nuisance:none",
                                 "nuisance:temperature"],
                        help="BELIEF:CORRECTION pairs (belief naive|nuisance|similarity, "
                             "correction none|temperature; similarity:fit fits its view "
                             "discount instead, on neighbour walks, similarity:mixed on walks "
                             "that also jump); the first is the paired reference")
    parser.add_argument("--lambda", dest="lam", type=float, default=8.0)
    parser.add_argument("--starts", type=int, default=4)
    parser.add_argument("--seconds", type=float, default=120.0, help="solver CPU budget each")
    parser.add_argument("--loop", action=argparse.BooleanOptionalAction, default=True,
                        help="run the held-out closed loop (--no-loop: the walks only)")
    parser.add_argument("--save", type=Path, default=None,
                        help="write the closed-loop episodes per variant and method (.npz)")
    parser.add_argument("--reference", default=None, metavar="FILE.npz:VARIANT",
                        help="pair against VARIANT's episodes saved by an earlier run (--save; "
                             "the same workspace's held-out models and starts) instead of the "
                             "first variant of this run")
    parser.add_argument("--load", type=Path, nargs="+", default=None,
                        help="print the closed-loop table of runs saved with --save (nothing "
                             "is fitted or run); the first variant loaded is the reference")
    args = parser.parse_args()
    if args.load is not None:
        loaded: dict[str, dict[str, np.ndarray]] = {}
        for path in args.load:
            for key, value in load_npz(path).items():
                spec, method = key.rsplit("@", 1)
                if spec in loaded and method in loaded[spec]:  # the same variant, another run
                    spec = f"{spec} ({path.stem})"
                loaded.setdefault(spec, {})[method] = value
        print_loops(loaded, next(iter(loaded)), dict.fromkeys(loaded, float("nan")))
        return
    if args.workspace is None:
        parser.error("--workspace is required (unless --load)")
    ws = Workspace(args.workspace)
    config = ws.config()
    recorded = RecordedObservation.load(ws.require("observe"))
    if recorded.variant == f"ra_{MIXTURE_VARIANT}":  # refits single variants by name
        raise SystemExit(f"{ws.root}: RA-POMDP's model is the mixture of RA variants "
                         "(observe.ra_model: mixture); this benchmark refits one "
                         "variant by name: run it on a workspace with ra_model auto "
                         "or a variant")
    evidence = recorded.evidence
    if not evidence.volume_mask.all():
        raise SystemExit(f"{args.workspace}: its evidence holds cross-fitted rows; this "
                         "benchmark refits volume-only models")
    directions = recorded.arrays["directions"]
    masks = held_out_groups(evidence.labels, evidence.groups)
    if len(masks) < 2:
        raise SystemExit(f"{args.workspace}: fewer than two held-out groups")
    row_model = fold_of_rows(masks, len(evidence.labels))
    walks, walk_row = held_out_walks(
        row_model, directions, class_seed(config.seed, "observe/temperature"),
        TEMPERATURE_WALK_LENGTH, TEMPERATURE_WALKS_PER_ROW, TEMPERATURE_NEIGHBOURS)
    motion = Motion.from_robot(load_robot(ws.require("robot")))
    kernel = view_similarity_kernel(recorded.scores["similarity"], directions,
                                    recorded.transfer_kernel)
    variant = recorded.variant
    names = list(dict.fromkeys([variant, config.evaluate.random.observation_model]))
    lookahead = config.evaluate.lookahead
    print(f"held-out belief variants on {len(masks)} volume groups of "
          f"{len(recorded.classes)} classes ({len(evidence.labels)} held-out objects); RA "
          f"model {variant}; walks: {len(walks)} of {walks.shape[1]} views; closed loop: "
          f"λ = {args.lam:g}, {args.starts} starts a model, POMDP acting by "
          f"{'a one-step lookahead' if lookahead else 'the solved plans'}")
    loops, walk_rows, seconds = {}, {}, {}
    for spec in args.variants:
        belief, correction = spec.split(":")
        began = time.perf_counter()
        folds = belief_folds(recorded, config, "naive" if belief == "similarity" else belief,
                             names, masks)
        paired = [(mask, f) for mask, f in zip(masks, folds, strict=True)]
        discounts: dict = {}
        if belief == "similarity":  # the observe stage's fit: discount and stand-in
            # similarity:mixed fits it on walks that also jump (observe.discount_walks)
            discounts, temperatures = held_out_view_discounts(
                evidence, paired, directions, kernel, TEMPERATURE_WALK_LENGTH,
                TEMPERATURE_WALKS_PER_ROW, TEMPERATURE_NEIGHBOURS,
                class_seed(config.seed, "observe/temperature"),
                DISCOUNT_JUMP if correction == "mixed" else 0.0)
        elif correction == "none":
            temperatures = dict.fromkeys(names, 1.0)
        else:
            temperatures, _ = held_out_temperatures(
                evidence, paired, directions, TEMPERATURE_WALK_LENGTH,
                TEMPERATURE_WALKS_PER_ROW, TEMPERATURE_NEIGHBOURS,
                class_seed(config.seed, "observe/temperature"))
        folds = [{("ra" if n == variant else n): m for n, m in f.items()} for f in folds]
        for table in (temperatures, discounts):
            if variant in table:
                table["ra"] = table[variant]
        walk_rows[spec] = walk_table(recorded, folds, temperatures, row_model, walks,
                                     walk_row, discounts, kernel)
        walk_rows[spec]["_t"] = {n: temperatures[n] for n in folds[0]}
        for name, d in discounts.items():
            if name in folds[0]:
                print(f"{spec}: {name} view discount scale {d.scale:.3f}, redundancy "
                      f"{d.redundancy:.3f}; the planner's stand-in t = {temperatures[name]:.3f}")
        if args.loop:
            loops[spec] = closed_loop(recorded, config, folds, masks, temperatures, motion,
                                      args.lam, args.starts, args.seconds, lookahead,
                                      discounts, kernel)
        seconds[spec] = time.perf_counter() - began
    print("\nwalks (belief in the true class, log loss over every step; acc / confidence − "
          "accuracy / ECE after steps " + ", ".join(map(str, STEPS)) + ")")
    print(f"{'variant':24s} {'model':12s} {'t':>5s} {'logloss':>7s} " + " ".join(
        f"{'acc' + str(s):>6s} {'c-a' + str(s):>6s} {'ece' + str(s):>6s}" for s in STEPS))
    for spec, table in walk_rows.items():
        for name, row in table.items():
            if name == "_t":
                continue
            print(f"{spec:24s} {name:12s} {table['_t'][name]:5.3f} {row['log_loss']:7.4f} "
                  + " ".join(f"{row[f'acc{s}']:6.3f} {row[f'gap{s}']:+6.3f} "
                             f"{row[f'ece{s}']:6.3f}" for s in STEPS))
    if not loops:
        return
    reference = args.variants[0]
    if args.reference is not None:
        path, reference = args.reference.rsplit(":", 1)
        saved = load_npz(Path(path))
        loops[f"{reference} (saved)"] = {m: saved[f"{reference}@{m}"] for m in ("ra", "random")}
        reference = f"{reference} (saved)"
        seconds[reference] = float("nan")
    print_loops(loops, reference, seconds)
    if args.save is not None:
        save_npz(args.save, **{f"{spec}@{method}": a for spec, rows in loops.items()
                               for method, a in rows.items() if not spec.endswith("(saved)")})


def print_loops(loops: dict[str, dict[str, np.ndarray]], reference: str,
                seconds: dict[str, float]) -> None:
    """The closed-loop table: per variant and method accuracy, energy, confidence − accuracy,
    ECE and the paired accuracy difference against ``reference``."""
    print(f"\nclosed loop on held-out models (paired: a variant's accuracy − {reference}'s "
          "over the same (held-out model, start) pairs, 95 % interval resampling held-out "
          "models)")
    print(f"{'variant':24s} {'method':8s} {'accuracy':>8s} {'energy':>7s} {'c-a':>7s} "
          f"{'ECE':>6s} {'paired':>28s} {'seconds':>8s}")
    for spec, rows in loops.items():
        for method, a in rows.items():
            paired = ""
            if spec != reference:
                b = loops[reference][method]
                if b.shape != a.shape or np.any(b[:, 3] != a[:, 3]):
                    raise SystemExit(f"{spec} and {reference}: not the same held-out episodes")
                models, cluster = np.unique(a[:, 3], return_inverse=True)
                est, low, high = cluster_bootstrap_difference(
                    np.bincount(cluster, weights=a[:, 0] - b[:, 0], minlength=models.size),
                    np.bincount(cluster, minlength=models.size).astype(np.float64))
                paired = f"{est:+.3f} [{low:+.3f}, {high:+.3f}]"
            print(f"{spec:24s} {method:8s} {a[:, 0].mean():8.3f} {a[:, 1].mean():7.3f} "
                  f"{a[:, 2].mean() - a[:, 0].mean():+7.3f} "
                  f"{expected_calibration_error(a[:, 2], a[:, 0]):6.3f} {paired:>28s} "
                  f"{seconds[spec]:8.1f}")


if __name__ == "__main__":
    main()
