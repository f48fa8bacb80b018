"""The closed loop on held-out evidence: every method's accuracy, energy and final belief on the
volume models (objects the trained classifier never saw), never on the test models.

For each volume group g (the g-th volume model of every class) the observation models are
fitted on the other groups as the observe stage fits them (same variant, same belief
correction and temperature, same ``ra_transfer`` kernel), each POMDP method is solved at each
λ, and the methods run from ``--starts`` seeded reachable starts per held-out model on its
labels at X_rho (noise off: the episode is exact). Random walks as `evaluate` configures it.
Prints one row per (method, λ) and the λ rule: the largest λ whose RA-POMDP episodes spend no
more energy than Random's. ``--models vptree`` runs the VP-tree baseline the same way on its own
labels of the volume models (saved by the vptree stage), each group's model counted on the
others with ``vptree.pseudo_count`` and tempered by the vptree stage's t (1 with
``--correction none``).

    python benchmarks/held_out_closed_loop.py --workspace W [--lambdas 2 8] [--starts 4]
        [--models ra classifier vptree] [--correction none|temperature|after_first]
        [--kernel POWER BANDWIDTH_DEG PRIOR] [--draws K] [--[no-]lookahead]
        [--lookahead-depth 1|2] [--lookahead-width N] [--save F]
        [--wrong-labels none|recorded] [--volume-labels F.npz] [--declared]
        [--fit-groups K] [--region-weight W] [--nested] [--class-shrinkage auto|W]

``--fit-groups K``: each held-out group's models are fitted on K of the other groups only (the
next K after it, cyclically) instead of all of them: how the held-out accuracy grows with the
evidence the models are counted on (the temperatures stay the recorded ones).

``--region-weight W``: RA-POMDP's model (``ra``) made region-aware, an experiment: each
held-out group's P(correct | c, x) moved on the logit scale by W times the other groups'
accuracy per viewpoint pooled over classes (centred, ``viewpoint_logit(pooled=True)``), the
wrong labels rescaled to keep their proportions; the temperature stays the recorded one.

``--nested``: each held-out group's knobs chosen without it: the RA variant, the
``ra_transfer`` kernel, every model's wrong-label shrinkage and belief temperature, made as
the observe stage makes them (``nested_choices.py``, which checks it repeats the stage) on the
other groups only, instead of the stage's choices on every group, the held-out one included.

``--class-shrinkage auto|W``: ``ra_class`` (RA-POMDP's model, which it must be) with its class
intercepts a_c moved to a_c + w (mean(a) − a_c) in every fold (``shrink_class_intercepts``);
``auto`` chooses w as ``observe.class_shrinkage: auto`` does; its wrong-label shrinkage is
chosen again and its temperature refitted on the shrunk folds, as the observe stage would
(benchmarks/results/class_shrinkage_closed_loop_rule.md). Without it, ``--wrong-labels
recorded`` shrinks ``ra_class`` as the observe stage chose (none before the option).

``--declared``: the declared confidence (``evaluate.declared_confidence``, docs/awareness.md
§4.8) at each method's held-out stops: confidence − accuracy and ECE of the belief, of the
belief raised to the a the stages fitted on held-out walks (Random's at its threshold; fitted
on every volume group, the held-out one included), and of the belief raised to the a fitted on
these episodes themselves, each group's by the other groups' episodes; and that a.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from rapomdp.awareness.evidence import (
    Evidence,
    RecordedObservation,
    TransferKernel,
    choose_class_shrinkage,
    choose_wrong_label_shrinkage,
    class_shrunk_folds,
    fit_observation_models,
    held_out_temperatures,
    leave_one_group_out,
    shift_level,
    shrink_class_intercepts,
    shrink_wrong_labels,
    shrunk_folds,
    viewpoint_logit,
)
from rapomdp.data.dataset import load_dataset
from rapomdp.data.splits import class_seed
from rapomdp.experiment.episode import Motion, run_episode
from rapomdp.experiment.held_out import LabelRecogniser, LabelScene
from rapomdp.experiment.methods import POMDPPolicy, RandomWalkPolicy
from rapomdp.io import load_npz, save_npz
from rapomdp.planning.ar_solver import solve_active_recognition
from rapomdp.planning.momdp import build_active_recognition_problem
from rapomdp.planning.stage import (
    declared_temperatures,
    offered_observation_models,
    start_viewpoint,
)
from rapomdp.recognition.artefacts import VPTREE_OBSERVATION_FILE, load_volume_probabilities
from rapomdp.recognition.belief import (
    TEMPERATURE_NEIGHBOURS,
    TEMPERATURE_WALK_LENGTH,
    TEMPERATURE_WALKS_PER_ROW,
    declared_log_beliefs,
    expected_calibration_error,
    stops_declared_confidence,
    temper,
)
from rapomdp.recognition.evaluation import viewpoint_confusion
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import Workspace

sys.path.insert(0, str(Path(__file__).parent))
from nested_choices import ObserveChoices, nested_choices  # noqa: E402
from size_prior import workspace_size_model  # noqa: E402

#: A held-out object's id in ``--save``'s rows: group * HELD_OUT_ID_STRIDE + its row in the group.
HELD_OUT_ID_STRIDE = 10_000

#: Half-width of the relative change of t between policy draws (``--draws``).
DRAW_SPREAD = 0.02


def replaced_labels(ws: Workspace, evidence: Evidence, path: Path) -> Evidence:
    """``evidence`` with the volume models' labels read from ``path`` (by model file), after
    checking its rows are the dataset's volume models in order (their recorded labels are the
    classifier_eval stage's argmax)."""
    dataset = load_dataset(ws.require("dataset"))
    models = dataset.with_role("volume")
    outputs = load_volume_probabilities(ws.require("classifier_eval"))
    recorded = np.stack([outputs.of(m).argmax(axis=1) for m in models])
    if recorded.shape != evidence.predicted.shape or \
            not np.array_equal(recorded, evidence.predicted):
        raise SystemExit(f"{ws.root}: the observe stage's evidence rows are not the volume "
                         "models in the dataset's order; cannot replace their labels")
    arrays = load_npz(path)
    by_file = dict(zip((str(f) for f in arrays["files"]), arrays["predicted"], strict=True))
    missing = [m.file for m in models if m.file not in by_file]
    if missing:
        raise SystemExit(f"{path}: no labels of {missing[:3]}")
    predicted = np.stack([by_file[m.file] for m in models]).astype(evidence.predicted.dtype)
    return Evidence(evidence.labels, predicted, evidence.groups, evidence.volume_mask)


def declared_at_stops(ws: Workspace, finals: dict[tuple[str, float], list[np.ndarray]],
                      random_model: str, random_threshold: float) -> None:
    """Print the declared confidence at each method's held-out stops (``--declared``)."""
    offered, _ = offered_observation_models(ws.require("observe"), ws.stage_dir("vptree"))
    print("\ndeclared confidence at the held-out stops: confidence - accuracy / ECE")
    print(f"{'method':12s} {'lambda':>6s} {'belief':>15s} {'stage a':>7s} {'as declared':>15s} "
          f"{'loop a':>7s} {'loop a, held out':>17s}")
    for (name, lam), values in finals.items():
        data = np.stack(values)
        log_b = np.log(np.maximum(data[:, :-2], 1e-300))
        truth, group = data[:, -2].astype(np.int64), data[:, -1].astype(np.int64)
        right = log_b.argmax(axis=1) == truth
        model = random_model if name == "random" else name
        a_stage = declared_temperatures(
            ws.require("observe"), {model: offered[model]}, ws.stage_dir("vptree"),
            random_threshold if name == "random" else None)[model]
        fit = stops_declared_confidence(log_b, truth, group)
        held = f"{fit.declared_confidence - fit.accuracy:+.3f} / {fit.declared_ece:.3f}"

        belief = _gap(np.exp(log_b.max(axis=1)), right)
        declared = _gap(np.exp(declared_log_beliefs(log_b, a_stage).max(axis=1)), right)
        print(f"{name:12s} {lam:6g} {belief:>15s} {a_stage:7.3f} {declared:>15s} "
              f"{fit.temperature:7.3f} {held:>17s}")


def _gap(confidence: np.ndarray, right: np.ndarray) -> str:
    """'confidence − accuracy / ECE'."""
    return (f"{confidence.mean() - right.mean():+.3f} / "
            f"{expected_calibration_error(confidence, right):.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workspace", "-w", type=Path, required=True)
    parser.add_argument("--lambdas", type=float, nargs="+", default=[2.0, 8.0])
    parser.add_argument("--models", nargs="+", default=["ra", "classifier"])
    parser.add_argument("--starts", type=int, default=4)
    parser.add_argument("--seconds", type=float, default=60.0, help="solver CPU budget each")
    parser.add_argument("--naive", action="store_true",
                        help="naive Bayes (t = 1) instead of the observe stage's correction")
    parser.add_argument("--correction", choices=["none", "temperature", "after_first"],
                        default=None,
                        help="this belief correction for every model, with the temperature the "
                             "observe stage fitted for it on held-out walks "
                             "(calibration.json: held_out_belief)")
    parser.add_argument("--temperature", type=float, default=None,
                        help="every model tempered by this t (planner and belief alike) "
                             "instead of the observe stage's correction")
    parser.add_argument("--lookahead", action=argparse.BooleanOptionalAction, default=None,
                        help="the POMDP methods act by a one-step lookahead on their value "
                             "(--no-lookahead: by the solved plans); default: as the "
                             "workspace's evaluate.lookahead")
    parser.add_argument("--lookahead-depth", type=int, choices=[1, 2], default=None,
                        help="views the lookahead looks ahead; default: as the workspace's "
                             "evaluate.lookahead_depth")
    parser.add_argument("--lookahead-width", type=int, default=None,
                        help="moves a depth-2 lookahead values two views deep; default: as "
                             "the workspace's evaluate.lookahead_width")
    parser.add_argument("--draws", type=int, default=1,
                        help="solve each POMDP K times, its model tempered by factors evenly "
                             f"spaced in [1 - {DRAW_SPREAD:g}, 1 + {DRAW_SPREAD:g}], and pool "
                             "their episodes: the solved policy changes a lot under such "
                             "changes, so one solve is one draw (docs/awareness.md §4.5)")
    parser.add_argument("--kernel", type=float, nargs=3, default=None,
                        metavar=("POWER", "BANDWIDTH_DEG", "PRIOR"),
                        help="refit ra_transfer with this kernel instead of the one the observe "
                             "stage chose (calibration.json: transfer_kernel), its walk "
                             "temperature refitted alike")
    parser.add_argument("--iterations", type=int, default=None,
                        help="solver iterations (default: the workspace's solve.iterations)")
    parser.add_argument("--wrong-labels", choices=["none", "recorded"], default="none",
                        help="recorded: each model's wrong labels shrunk by the amount the "
                        "observe stage chose (calibration.json: wrong_labels; chosen on every "
                        "volume group, the held-out one included); none: as counted")
    parser.add_argument("--volume-labels", type=Path, default=None, metavar="F.npz",
                        help="another classifier's labels of the volume models at X_rho "
                             "(train_recipe.py --save-ensemble: files, predicted) in place of "
                             "the trained one's, every model refitted on them and every "
                             "temperature refitted on their walks (the saliency scores stay "
                             "the trained classifier's): what that classifier would do held "
                             "out")
    parser.add_argument("--declared", action="store_true",
                        help="the declared confidence at each method's held-out stops (above)")
    parser.add_argument("--fit-groups", type=int, default=None, metavar="K",
                        help="fit each group's models on K of the other groups (default: all)")
    parser.add_argument("--size-prior", action="store_true",
                        help="every moving method's belief starts from a class prior by the "
                             "object's measured size (size_prior.py: fitted on the training "
                             "models) instead of the uniform one")
    parser.add_argument("--region-weight", type=float, default=0.0, metavar="W",
                        help="RA-POMDP's model made region-aware by W (above); 0: as fitted")
    parser.add_argument("--nested", action="store_true",
                        help="each group's RA variant, kernel, wrong-label shrinkage and "
                             "temperatures chosen without it (above)")
    parser.add_argument("--class-shrinkage", default=None, metavar="auto|W",
                        help="ra_class's class intercepts shrunk toward their mean (above)")
    parser.add_argument("--save", type=Path, default=None,
                        help="write every episode's (correct, energy, belief, confidence, "
                             "held-out model) per (method, λ) to this .npz, for paired "
                             "comparisons between runs (the same starts in the same order)")
    args = parser.parse_args()
    ws = Workspace(args.workspace)
    config = ws.config()
    recorded = RecordedObservation.load(ws.require("observe"))
    observe, calibration, classes = recorded.arrays, recorded.calibration, recorded.classes
    evidence, scores, variant = recorded.evidence, recorded.scores, recorded.variant
    kernel = (TransferKernel(*args.kernel) if args.kernel is not None
              else recorded.transfer_kernel)  # as the observe stage chose it (older: default)
    if not evidence.volume_mask.all():
        raise SystemExit(f"{args.workspace}: its evidence holds cross-fitted rows; this closed "
                         "loop refits volume-only models: observe with observe.evidence=volume")
    volume_groups = np.unique(evidence.groups[evidence.volume_mask])
    nested: dict[int, ObserveChoices] | None = None
    if args.nested:
        clash = [flag for flag, on in (
            ("--kernel", args.kernel is not None), ("--correction", args.correction is not None),
            ("--naive", args.naive), ("--temperature", args.temperature is not None),
            ("--volume-labels", args.volume_labels is not None),
            ("--fit-groups", args.fit_groups is not None),
            ("--region-weight", bool(args.region_weight)),
            ("--wrong-labels none", args.wrong_labels != "recorded"),
            ("--models vptree", "vptree" in args.models)) if on]
        if clash:
            raise SystemExit(f"--nested chooses every knob per fold as the observe stage does "
                             f"(wrong labels as chosen: --wrong-labels recorded); drop "
                             f"{', '.join(clash)}")
        nested = nested_choices(ws, recorded)
    if args.volume_labels is not None:
        evidence = replaced_labels(ws, evidence, args.volume_labels)
    size_model, size_extents = workspace_size_model(ws) if args.size_prior else (None, {})
    robot = load_robot(ws.require("robot"))
    motion = Motion.from_robot(robot)
    start = start_viewpoint(motion.reachable)
    temperatures, corrections = calibration["temperatures"], calibration["belief_corrections"]
    if args.naive:
        args.correction = "none"
    if args.correction is not None:
        fits = calibration["held_out_belief"]
        key = "after_first_temperature" if args.correction == "after_first" else "temperature"
        corrections = dict.fromkeys(corrections, args.correction)
        temperatures = {m: (1.0 if args.correction == "none" else fits[m][key]) for m in fits}
        temperatures["ra"] = temperatures[variant]
    if args.volume_labels is not None and args.correction != "none":
        # other labels make other models: every temperature refitted as the observe stage
        # fits it (the same folds and walks)
        refit, _ = held_out_temperatures(
            evidence, leave_one_group_out(evidence, scores, classes, config.observe,
                                          observe["directions"], kernel),
            observe["directions"], TEMPERATURE_WALK_LENGTH, TEMPERATURE_WALKS_PER_ROW,
            TEMPERATURE_NEIGHBOURS, class_seed(config.seed, "observe/temperature"))
        temperatures = {**temperatures, **refit, "ra": refit[variant]}
    if args.kernel is not None and variant == "ra_transfer" and corrections[variant] != "none":
        # another kernel is another model: its walk temperature refitted as the observe stage
        # fits it (the same folds and walks)
        refit, _ = held_out_temperatures(
            evidence, leave_one_group_out(evidence, scores, classes, config.observe,
                                          observe["directions"], kernel),
            observe["directions"], TEMPERATURE_WALK_LENGTH, TEMPERATURE_WALKS_PER_ROW,
            TEMPERATURE_NEIGHBOURS, class_seed(config.seed, "observe/temperature"),
            after_first=corrections[variant] == "after_first")
        temperatures["ra"] = temperatures[variant] = refit[variant]
    if "vptree" in args.models:
        vptree = load_npz(ws.require("vptree") / VPTREE_OBSERVATION_FILE)
        if "volume_predictions" not in vptree:
            raise SystemExit(f"{args.workspace}: its vptree stage predates the saved volume "
                             "labels: rapomdp run -w W --redo vptree")
        temperatures["vptree"] = (1.0 if args.correction == "none"
                                  else float(vptree["temperature"]))
    wrong_amounts = {name: float(c.get("amount", 0.0))
                     for name, c in calibration.get("wrong_labels", {}).items()}
    # ra_class's class intercepts as the stage shrank them (--wrong-labels recorded: its knobs)
    class_w = recorded.class_shrinkage if args.wrong_labels == "recorded" else 0.0
    if args.class_shrinkage is not None:
        if variant != "ra_class" or args.wrong_labels != "recorded" or nested is not None \
                or args.fit_groups is not None or args.volume_labels is not None \
                or args.correction is not None or args.temperature is not None:
            raise SystemExit("--class-shrinkage: RA-POMDP's model must be ra_class, with "
                             "--wrong-labels recorded and none of --nested, --fit-groups, "
                             "--volume-labels, --correction, --temperature")
        folds = leave_one_group_out(evidence, scores, classes, config.observe,
                                    observe["directions"], kernel)
        class_w = (choose_class_shrinkage(evidence, folds, "auto").amount
                   if args.class_shrinkage == "auto" else float(args.class_shrinkage))
        folds = class_shrunk_folds(folds, class_w)
        wrong_amounts["ra"] = wrong_amounts["ra_class"] = choose_wrong_label_shrinkage(
            evidence, folds, "ra_class", config.observe.wrong_labels).amount
        refit, _ = held_out_temperatures(
            evidence, shrunk_folds(folds, wrong_amounts), observe["directions"],
            TEMPERATURE_WALK_LENGTH, TEMPERATURE_WALKS_PER_ROW, TEMPERATURE_NEIGHBOURS,
            class_seed(config.seed, "observe/temperature"),
            after_first=corrections["ra_class"] == "after_first")
        temperatures["ra"] = temperatures["ra_class"] = refit["ra_class"]
    cfg = config.evaluate
    lookahead = cfg.lookahead if args.lookahead is None else args.lookahead
    depth = cfg.lookahead_depth if args.lookahead_depth is None else args.lookahead_depth
    width = cfg.lookahead_width if args.lookahead_width is None else args.lookahead_width
    rows: dict[tuple[str, float], list[tuple[bool, float, float, float, float, float]]] = {}
    finals: dict[tuple[str, float], list[np.ndarray]] = {}  # (final belief, truth, group)
    if args.fit_groups is not None and not 1 <= args.fit_groups < len(volume_groups):
        raise SystemExit(f"--fit-groups must be 1 to {len(volume_groups) - 1} (the other "
                         f"volume groups), got {args.fit_groups}")
    for i, g in enumerate(volume_groups):
        held = evidence.groups == g
        others = np.roll(volume_groups, -i)[1:][:args.fit_groups]  # the next K after g
        if nested is not None:  # every knob chosen without g; the models shrunk
            choices = nested[int(g)]
            fold_single = choices.models
            fold_t, fold_corrections = choices.temperatures, choices.corrections
        else:
            fitted = fit_observation_models(
                evidence.subset(np.isin(evidence.groups, others)), scores, classes,
                config.observe, observe["directions"], kernel)
            fitted["ra"] = fitted[variant]
            fold_single = {name: m.probabilities for name, m in fitted.items()}
            if class_w:
                fold_single["ra_class"] = shrink_class_intercepts(fitted["ra_class"],
                                                                  class_w).probabilities
                if variant == "ra_class":
                    fold_single["ra"] = fold_single["ra_class"]
            if args.wrong_labels == "recorded":
                fold_single = {name: shrink_wrong_labels(p, wrong_amounts.get(name, 0.0))
                               for name, p in fold_single.items()}
            fold_t, fold_corrections = temperatures, corrections
        rest = evidence.subset(np.isin(evidence.groups, others))
        region = (viewpoint_logit(rest.labels, rest.predicted, len(classes),
                                  observe["directions"], pooled=True)[0]
                  if args.region_weight else None)
        part = evidence.subset(held)
        for name in ("random", *args.models):
            held_labels, held_predicted = part.labels, part.predicted
            if name == "vptree":  # its own labels of the same volume models, its own count
                in_group = vptree["volume_groups"] == g
                single = viewpoint_confusion(
                    vptree["volume_labels"][~in_group], vptree["volume_predictions"][~in_group],
                    len(classes), config.vptree.pseudo_count)
                planner = first = temper(single, args.temperature if args.temperature
                                         is not None else temperatures["vptree"])
                held_labels = vptree["volume_labels"][in_group]
                held_predicted = vptree["volume_predictions"][in_group]
            else:
                key = cfg.random.observation_model if name == "random" else name
                single = fold_single[key]
                if name == "ra" and region is not None:
                    single = shift_level(single, args.region_weight * region)
                if args.temperature is not None:
                    planner = first = temper(single, args.temperature)
                else:
                    planner = temper(single, fold_t[key])
                    first = single if fold_corrections[key] == "after_first" else planner
            draws = (np.array([1.0]) if name == "random" or args.draws == 1
                     else np.linspace(1.0 - DRAW_SPREAD, 1.0 + DRAW_SPREAD, args.draws))
            for lam in ([0.0] if name == "random" else args.lambdas):
                for d, factor in enumerate(draws):
                    model = temper(planner, float(factor))
                    first_model = first if first is single else temper(first, float(factor))
                    method: RandomWalkPolicy | POMDPPolicy
                    if name == "random":
                        method = RandomWalkPolicy(model, motion.distance_m, motion.reachable,
                                                  cfg.random.neighbours,
                                                  cfg.random.belief_threshold,
                                                  cfg.random.max_moves,
                                                  first_view_model=first_model)
                    else:
                        problem = build_active_recognition_problem(
                            model, motion.energy, motion.reachable, lam,
                            config.solve.discount, start)
                        policy = solve_active_recognition(
                            problem, config.solve.precision, args.seconds,
                            max_iterations=args.iterations or config.solve.iterations).policy
                        method = POMDPPolicy(policy, model, name, first_view_model=first_model,
                                             lookahead_over=(motion.reachable if lookahead
                                                             else None),
                                             lookahead_depth=depth, lookahead_width=width)
                    for r in range(len(held_labels)):
                        if size_model is not None:  # row r: the g-th volume model of its class
                            extents = size_extents[classes[int(held_labels[r])]][g]
                            method._bayes.prior = size_model.prior(extents)[0]
                        rng = class_seed(config.seed, f"held-out/{g}/{r}")
                        starts = rng.choice(np.flatnonzero(motion.reachable), args.starts,
                                            replace=False)
                        for s in starts:
                            episode = run_episode(
                                LabelScene(), LabelRecogniser(held_predicted[r], len(classes)),
                                method, motion, int(s), cfg.max_moves, rng)
                            truth = int(held_labels[r])
                            rows.setdefault((name, lam), []).append(
                                (episode.declared == truth, float(episode.move_energy.sum()),
                                 float(episode.beliefs[-1, truth]),
                                 float(episode.beliefs[-1, episode.declared]),
                                 float(g * HELD_OUT_ID_STRIDE + r), float(d)))
                            finals.setdefault((name, lam), []).append(
                                np.concatenate([episode.beliefs[-1], [truth, g]]))
        static = part.predicted == part.labels[:, None]
        rows.setdefault(("static", 0.0), []).extend(
            (bool(c), 0.0, float("nan"), float("nan"), float(g * HELD_OUT_ID_STRIDE + r),
             0.0)
            for r, row in enumerate(static[:, motion.reachable]) for c in row)
    fitted_t = ", ".join(f"{m} {temperatures[m]:.3f}" for m in args.models)
    belief = ("each group's own (nested)" if nested is not None
              else f"t = {args.temperature:g}" if args.temperature is not None
              else f"{args.correction} (t: {fitted_t})" if args.correction is not None
              else f"the observe stage corrections (t: {fitted_t})")
    print(f"held-out closed loop on {len(volume_groups)} volume group(s) of "
          f"{len(classes)} classes ({args.starts} starts a model); RA model "
          f"{variant if nested is None else 'per group, nested (below)'}; "
          f"POMDPs act by {f'a {depth}-step lookahead' if lookahead else 'the solved plans'}"
          f"{f' (width {width})' if lookahead and depth > 1 else ''}; "
          f"belief: {belief}; ra_transfer kernel "
          f"{kernel.to_dict() if nested is None else 'per group'}; wrong labels: "
          f"{args.wrong_labels if nested is None else 'per group'}"
          + (f"; each group's models counted on {args.fit_groups} other group(s)"
             if args.fit_groups is not None else "")
          + (f"; volume labels: {args.volume_labels} (temperatures refitted)"
             if args.volume_labels is not None else "")
          + ("; beliefs start from the size prior" if args.size_prior else "")
          + (f"; ra_class's class intercepts shrunk by {class_w:g} (--class-shrinkage "
             f"{args.class_shrinkage}; t ra {temperatures['ra']:.3f}, wrong labels "
             f"{wrong_amounts.get('ra', 0.0):g})" if args.class_shrinkage is not None else "")
          + ("; nested: " + "; ".join(
              f"without group {g} {c.variant}, kernel {c.kernel.to_dict()}, shrinkage ra "
              f"{c.shrinkage['ra']:g} classifier {c.shrinkage['classifier']:g}, t ra "
              f"{c.temperatures['ra']:.3f} classifier {c.temperatures['classifier']:.3f}"
              for g, c in nested.items())
             if nested is not None else ""))
    print("belief: final belief in the true class; confidence: in the declared class; "
          "ECE over the confidence (10 bins)")
    print(f"{'method':12s} {'lambda':>6s} {'accuracy':>8s} {'energy':>7s} {'belief':>7s} "
          f"{'confid.':>7s} {'ECE':>6s} n")
    table = {}
    for (name, lam), values in rows.items():
        a = np.array(values, dtype=np.float64)
        table[(name, lam)] = a[:, 1].mean()
        known = np.isfinite(a[:, 3])
        ece = (expected_calibration_error(a[known, 3], a[known, 0]) if known.any()
               else float("nan"))
        per_draw = [a[a[:, 5] == d, 0].mean() for d in np.unique(a[:, 5])]
        spread = (f"  draws {min(per_draw):.3f}-{max(per_draw):.3f}" if len(per_draw) > 1
                  else "")
        print(f"{name:12s} {lam:6g} {a[:, 0].mean():8.3f} {a[:, 1].mean():7.3f} "
              f"{np.nanmean(a[:, 2]) if known.any() else float('nan'):7.3f} "
              f"{np.nanmean(a[:, 3]) if known.any() else float('nan'):7.3f} {ece:6.3f} "
              f"{len(a)}{spread}")
    if args.save is not None:
        save_npz(args.save, **{f"{name}@{lam:g}": np.array(v, dtype=np.float64)
                               for (name, lam), v in rows.items()})
    if args.declared:
        declared_at_stops(ws, finals, cfg.random.observation_model,
                          cfg.random.belief_threshold)
    if "ra" not in args.models:
        return
    budget = table[("random", 0.0)]
    fitting = [lam for lam in args.lambdas if table[("ra", lam)] <= budget]
    print(f"λ rule: largest λ whose RA-POMDP held-out energy <= Random's ({budget:.3f}): "
          f"{max(fitting) if fitting else 'none'}")


if __name__ == "__main__":
    main()
