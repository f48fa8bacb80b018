"""The closed-loop evaluation (paper Sec. 5.2) and its pipeline stage ``evaluate``.

Every test model x ``starts_per_model`` seeded reachable start viewpoints x every method runs
one :func:`~rapomdp.experiment.episode.run_episode`; test models are spread over worker
processes (each episode has its own seeded generator, so the result does not depend on the
number of workers). Writes into the stage folder:

- ``episodes.npz``: one row per episode (``method``, ``class_index``, ``model``, ``start``,
  ``declared``, ``exhausted`` and the scores ``correct``, ``belief``, ``moves``, ``distance_m``,
  ``energy``) and the steps of all episodes concatenated (``step_viewpoints``, ``step_outputs``,
  ``step_beliefs``; episode i is rows ``offsets[i]:offsets[i + 1]``); ``classes``, ``methods``;
- ``episodes.csv`` (one row per episode), ``table1.md|csv``, ``per_class.md|csv``;
- ``paired.csv``: each method's accuracy minus RA-POMDP's over the same (test model, start)
  pairs, with a 95 % cluster-bootstrap interval over test models (when RA-POMDP ran);
- ``fig3.png`` (belief in the true class against step), ``trajectories.png``;
- ``tradeoff.csv|md|png``: accuracy against mean energy, one curve per method: every POMDP
  method solved (``sweep/lambda_<λ>/``) and run at each ``evaluate.lambdas``, Random at each
  ``evaluate.random_thresholds``, the learned baseline (``learned``) at each λ the learn stage
  trained it at, Static one point; Table 1's settings are points of it;
- ``held_out/comparison.json``: every method run on the held-out volume models (the
  classifier's recorded labels, each observation model fitted without the object's group):
  accuracy, energy and the paired difference to RA-POMDP resampling held-out objects, what
  held-out objects say about the methods on this dataset before any test model is read;
- ``held_out/declared_fit.json``: where the POMDP methods and the learned baseline stop in
  their held-out closed loop and the a fitted there (:mod:`rapomdp.experiment.held_out`);
- ``evaluate.json``: counts, timing, images per second of the episode loop.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rapomdp.awareness.artefacts import load_softmax_temperature
from rapomdp.config import METHOD_NAMES, Config, EvaluateConfig
from rapomdp.context import RunContext
from rapomdp.data.dataset import Dataset, ModelEntry, load_dataset
from rapomdp.data.splits import class_seed
from rapomdp.data.test_views import TestViews
from rapomdp.experiment.episode import (
    Motion,
    Policy,
    Recogniser,
    run_episode,
)
from rapomdp.experiment.episode_table import (
    EPISODES_CSV,
    EPISODES_FILE,
    FIG3_FILE,
    PAIRED_CSV,
    PER_CLASS_CSV,
    PER_CLASS_MD,
    SUMMARY_FILE,
    TABLE1_CSV,
    TABLE1_MD,
    TRADEOFF_CSV,
    TRADEOFF_FIGURE,
    TRADEOFF_MD,
    TRAJECTORIES_FILE,
    EpisodeRecord,
    EpisodeTable,
    episodes_csv,
)
from rapomdp.experiment.held_out import (
    COMPARISON_FILE,
    HELD_OUT_DIR,
    NOT_POMDP,
    closed_loop_declared,
    held_out_comparison,
    held_out_runs,
)
from rapomdp.experiment.learned import LearnedPolicy, load_learned_policy
from rapomdp.experiment.methods import POMDPPolicy, RandomWalkPolicy, StaticPolicy
from rapomdp.experiment.sections import LEARNED
from rapomdp.parallel import run_tasks
from rapomdp.planning.artefacts import policy_file
from rapomdp.planning.policy import ActiveRecognitionPolicy
from rapomdp.planning.stage import (
    declared_temperatures,
    offered_observation_models,
)
from rapomdp.recognition.artefacts import (
    VPTREE_OUTPUTS_FILE,
    XrhoProbabilities,
    load_xrho_probabilities,
)
from rapomdp.recognition.stage import load_stage_classifier
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import StageError, StageInputs

if TYPE_CHECKING:
    from rapomdp.experiment.metrics import TradeoffPoint

#: The method every other is compared with, pair by pair, in Table 1.
PAIRED_REFERENCE = "ra"
VPTREE_RECOGNISER = "vptree"


def start_viewpoints(seed: int, model: ModelEntry, reachable: np.ndarray,
                     count: int) -> np.ndarray:
    """``count`` distinct reachable start viewpoints of a test model (seeded by its file)."""
    candidates = np.flatnonzero(reachable)
    if count > candidates.size:
        raise StageError(f"evaluate.starts_per_model is {count} but only {candidates.size} "
                         "viewpoints are reachable")
    rng = class_seed(seed, f"evaluate/start/{model.file}")
    return np.sort(rng.choice(candidates, size=count, replace=False))


def episode_rng(seed: int, model: ModelEntry, start: int, method: str) -> np.random.Generator:
    """The generator of one episode (sensor noise, random moves): independent of scheduling,
    and of the model's class (seeded by its file), which only the scorer may read."""
    return class_seed(seed, f"evaluate/{model.file}/{start}/{method}")


@dataclass
class ClosedLoop:
    """Everything an episode needs, loaded once per process from the stage folders."""

    config: Config
    dataset: Dataset
    recognisers: dict[str, Recogniser]
    methods: dict[str, Policy]
    motion: Motion
    #: Each recogniser's outputs on the test models at X_rho, stored by the stages that
    #: classified the xrho stage's images (None: a noisy sensor, rendered at every look).
    stored: dict[str, XrhoProbabilities] | None = None

    @classmethod
    def load(cls, config: Config, inputs: StageInputs, threads: int | None = None,
             sweep_dir: Path | None = None,
             declared_fit: Mapping[str, float] | None = None
             ) -> ClosedLoop:
        """The closed loop of a workspace's stage folders; the CNN uses ``threads`` threads.

        With ``sweep_dir`` (the evaluate stage's ``sweep/``, from :func:`solve_sweep`) the
        accuracy-energy sweep's settings run alongside Table 1's methods. ``declared_fit``:
        the declared-confidence a of POMDP methods and of the learned baseline fitted on their
        held-out closed loop (:func:`~rapomdp.experiment.held_out.closed_loop_declared`), in
        place of the walks' (the learned baseline's: 1). Random reports with the a the observe
        stage fitted on held-out walks stopped at its belief threshold.
        """
        dataset = load_dataset(inputs.dataset)
        robot = load_robot(inputs.robot)
        motion = Motion.from_robot(robot)
        observation, _ = offered_observation_models(inputs.observe, inputs.vptree_dir)
        cfg = config.evaluate
        # what each belief reports after its views: Random stops at a belief threshold, so it
        # reports with the a fitted at its threshold
        pooled = declared_temperatures(inputs.observe, observation, inputs.vptree_dir)

        def declared(name: str, stop_threshold: float | None = None) -> float:
            if stop_threshold is None:
                return (declared_fit or {}).get(name, pooled[name])
            return declared_temperatures(inputs.observe, {name: observation[name]},
                                         inputs.vptree_dir, stop_threshold)[name]

        def method(key: str, random_threshold: float, solve_dir: Path,
                   lambda_: float = config.solve.wrong_declaration_cost_m) -> Policy:
            recogniser = VPTREE_RECOGNISER if key == "vptree" else "cnn"
            if key == LEARNED:  # the learn stage's policy trained at this λ
                network, spec = load_learned_policy(inputs.learn, lambda_)
                name = spec.observation_model
                if name not in observation:
                    raise StageError(f"the learned policy's belief uses observation model "
                                     f"'{name}', which the workspace lacks")
                # its a is fitted where its own held-out closed loop stops (else: 1)
                return LearnedPolicy(network, spec, observation[name], motion.reachable,
                                     METHOD_NAMES[key],
                                     declared_temperature=(declared_fit or {}).get(LEARNED, 1.0))
            if key == "static":
                return StaticPolicy(METHOD_NAMES[key],
                                    softmax_temperature=load_softmax_temperature(inputs.observe))
            if key == "random":
                name = cfg.random.observation_model
                if name not in observation:
                    raise StageError(f"evaluate.random.observation_model is '{name}'; the "
                                     f"workspace has {', '.join(observation)}")
                return RandomWalkPolicy(
                    observation[name], motion.distance_m, motion.reachable,
                    cfg.random.neighbours, random_threshold, cfg.random.max_moves,
                    METHOD_NAMES[key], declared_temperature=declared(name, random_threshold))
            path = solve_dir / policy_file(key)
            if not path.exists() or key not in observation:
                raise StageError(f"method '{key}' needs {path.name} from the solve stage: "
                                 f"add '{key}' to solve.models")
            return POMDPPolicy.configured(
                cfg, ActiveRecognitionPolicy.load(path), observation[key], METHOD_NAMES[key],
                motion.reachable, recogniser, declared_temperature=declared(key))

        methods = {key: method(key, cfg.random.belief_threshold, inputs.solve)
                   for key in cfg.methods}
        if sweep_dir is not None:  # the accuracy-energy sweep's settings, run alongside
            extra = sweep_settings(cfg, config.solve.wrong_declaration_cost_m)
            for key, parameter, value, folder in extra:
                threshold = value if parameter == "threshold" else cfg.random.belief_threshold
                lam = value if parameter == "lambda" else config.solve.wrong_declaration_cost_m
                solve_dir = sweep_dir / folder if folder else inputs.solve
                methods[sweep_key(key, parameter, value)] = method(key, threshold, solve_dir,
                                                                   lam)
        recognisers: dict[str, Recogniser] = {}
        if any(m.recogniser == "cnn" for m in methods.values()):
            recognisers["cnn"] = load_stage_classifier(config, inputs.train, dataset.classes,
                                                       threads)
        if any(m.recogniser == VPTREE_RECOGNISER for m in methods.values()):
            from rapomdp.recognition.vptree_stage import load_workspace_vptree

            recognisers[VPTREE_RECOGNISER] = load_workspace_vptree(inputs.vptree)
        stored = None
        if not config.render.noise.enabled:
            stored = {"cnn": load_xrho_probabilities(inputs.classifier_eval)}
            if VPTREE_RECOGNISER in recognisers:
                stored[VPTREE_RECOGNISER] = load_xrho_probabilities(inputs.vptree,
                                                                    VPTREE_OUTPUTS_FILE)
        return cls(config, dataset, recognisers, methods, motion, stored)

    def scene(self, model: ModelEntry) -> TestViews:
        return TestViews.of_model(self.dataset, model, self.config.viewpoints,
                                  self.config.camera, self.config.render.noise)

    def run_model(self, model: ModelEntry) -> list[EpisodeRecord]:
        """Every start x method episode of one test model."""
        scene = self.scene(model)
        starts = start_viewpoints(self.config.seed, model, self.motion.reachable,
                                  self.config.evaluate.starts_per_model)
        # a noiseless sensor sees the same image at every look from a viewpoint: the one the
        # xrho stage rendered, which classifier_eval and vptree classified once (the memos)
        memos: dict[str, dict[int, np.ndarray]] | None = None
        if self.stored is not None:
            memos = {name: dict(enumerate(self.stored[name].of(model)))
                     if name in self.stored else {} for name in self.recognisers}
        records = []
        for start in starts:
            for key, method in self.methods.items():
                # a sweep setting draws as its method does (common random numbers)
                rng = episode_rng(self.config.seed, model, int(start), key.split("@")[0])
                began = time.process_time()
                episode = run_episode(scene, self.recognisers[method.recogniser], method,
                                      self.motion, int(start), self.config.evaluate.max_moves,
                                      rng, None if memos is None else memos[method.recogniser])
                records.append(EpisodeRecord(key, model.file, int(start), episode,
                                             time.process_time() - began))
        return records


def _run_models_task(config_json: str, inputs: StageInputs, sweep_dir: Path | None,
                     declared_fit: dict[str, float] | None,
                     model_files: list[str],
                     report: Callable[[int], None] | None = None) -> list[list[EpisodeRecord]]:
    """A worker's task: load the closed loop once, run each of its test models (``report``:
    told each model's episodes as they finish)."""
    loop = ClosedLoop.load(Config.model_validate_json(config_json), inputs, threads=1,
                           sweep_dir=sweep_dir, declared_fit=declared_fit)
    by_file = {m.file: m for m in loop.dataset.with_role("test")}
    out = []
    for name in model_files:
        out.append(loop.run_model(by_file[name]))
        if report is not None:
            report(len(out[-1]))
    return out


def run_episodes(config: Config, inputs: StageInputs,
                 context: RunContext = RunContext(), sweep_dir: Path | None = None,
                 declared_fit: dict[str, float] | None = None
                 ) -> tuple[list[EpisodeRecord], Dataset]:
    """Every test model x start x method (and sweep setting, with ``sweep_dir``; the
    declared confidence of the methods in ``declared_fit`` by it: see :meth:`ClosedLoop.load`), over
    ``context``'s worker processes (each loads the closed loop once and runs a contiguous
    share of the test models); records in a fixed order (test models as listed, then start,
    then method), whatever the number of workers."""
    dataset = load_dataset(inputs.dataset)
    models = dataset.with_role("test")
    per_model = config.evaluate.starts_per_model * (
        len(config.evaluate.methods)
        + (len(sweep_settings(config.evaluate, config.solve.wrong_declaration_cost_m))
           if sweep_dir else 0))
    # On a Dask cluster every test model is a task of its own (the cluster spreads them).
    count = len(models) if context.uses_cluster else min(context.worker_count, len(models))
    if count <= 1 and not context.uses_cluster:
        loop = ClosedLoop.load(config, inputs, context.threads, sweep_dir, declared_fit)
        per_model_records = run_tasks(loop.run_model, [(m,) for m in models], 1,
                                      "evaluate: episodes", context.progress,
                                      unit="episodes", sizes=[per_model] * len(models))
    else:
        config_json = config.model_dump_json()
        shares = [[models[i].file for i in share]
                  for share in np.array_split(np.arange(len(models)), count)]
        per_share = run_tasks(_run_models_task, [(config_json, inputs, sweep_dir,
                                                   declared_fit, share)
                                                   for share in shares],
                              count, "evaluate: episodes", context.progress,
                              context.scheduler, unit="episodes",
                              sizes=[per_model * len(share) for share in shares], reports=True,
                              pool=context.pool)
        per_model_records = [records for share in per_share for records in share]
    return [r for records in per_model_records for r in records], dataset


def sweep_settings(cfg: EvaluateConfig, lambda_: float
                   ) -> list[tuple[str, str, float, str | None]]:
    """The accuracy-energy sweep's extra settings: every POMDP method at every extra λ (the
    learned baseline too, with no solve folder: the learn stage trained it there) and Random
    at every extra stop belief.

    Table 1's own settings (``lambda_``, ``random.belief_threshold``) are not repeated: the
    main episodes are their points.

    Args:
        cfg: The ``evaluate`` section: its ``methods``, ``lambdas``, ``random_thresholds`` and
            Random's ``belief_threshold``.
        lambda_: Table 1's λ in metres (``solve.wrong_declaration_cost_m``).

    Returns:
        (method, parameter, value, λ folder or None) per extra setting.

    Example:
        >>> from rapomdp.config import EvaluateConfig
        >>> cfg = EvaluateConfig(methods=["ra", "random"], lambdas=[1.0, 3.0],
        ...                      random_thresholds=[0.5, 0.9])
        >>> sweep_settings(cfg, lambda_=3.0)
        [('ra', 'lambda', 1.0, 'lambda_1'), ('random', 'threshold', 0.5, None)]
    """
    pomdp = [m for m in cfg.methods if m not in NOT_POMDP]
    out: list[tuple[str, str, float, str | None]] = []
    for lam in dict.fromkeys(cfg.lambdas):
        if not np.isclose(lam, lambda_):
            out += [(m, "lambda", float(lam), f"lambda_{lam:g}") for m in pomdp]
            if LEARNED in cfg.methods:  # trained at every λ by the learn stage, not solved
                out.append((LEARNED, "lambda", float(lam), None))
    if "random" in cfg.methods:
        out += [("random", "threshold", float(t), None)
                for t in dict.fromkeys(cfg.random_thresholds)
                if not np.isclose(t, cfg.random.belief_threshold)]
    return out


def sweep_key(method: str, parameter: str, value: float) -> str:
    """The episode key of a method at a sweep setting (``ra@lambda=0.5``)."""
    return f"{method}@{parameter}={value:g}"


def solve_sweep(config: Config, inputs: StageInputs, sweep_dir: Path,
                context: RunContext = RunContext()) -> None:
    """Solve every POMDP method of the evaluation at every extra λ of the sweep, as the solve
    stage does (``sweep_dir/lambda_<λ>/policy_<method>.npz``), all in one pool of workers.

    The longest solves start first: larger λ first, then the methods whose solve-stage
    policies were furthest from converged (the gap between the bounds it reported at the
    start belief); the order changes the wall time only.
    """
    from rapomdp.planning.artefacts import SOLVE_SUMMARY, load_solve_summary
    from rapomdp.planning.stage import start_viewpoint, workspace_arrays
    from rapomdp.planning.workspace import solve_problem_sets

    folders: dict[str, tuple[float, list[str]]] = {}
    lambda_ = config.solve.wrong_declaration_cost_m
    for method, _, value, folder in sweep_settings(config.evaluate, lambda_):
        if folder is not None:
            folders.setdefault(folder, (value, []))[1].append(method)
    if not folders:
        return
    models, energy, reachable, classes = workspace_arrays(
        inputs.observe, inputs.robot, inputs.vptree_dir,
        list(dict.fromkeys(m for _, ms in folders.values() for m in ms)))
    rows = (load_solve_summary(inputs.solve) if (inputs.solve / SOLVE_SUMMARY).is_file()
            else {})
    gap = {name: float(row["upper"]) - float(row["lower"]) for name, row in rows.items()
           if isinstance(row, dict) and {"upper", "lower"} <= row.keys()}
    solve = config.solve
    sweep_lambdas = ", ".join(f"{lam:g}" for lam, _ in folders.values())
    solve_problem_sets(
        [(sweep_dir / folder, lam, {m: models[m] for m in methods})
         for folder, (lam, methods) in folders.items()],
        energy, reachable, discount=solve.discount, start_viewpoint=start_viewpoint(reachable),
        precision=solve.precision, timeout=solve.timeout_s, max_iterations=solve.iterations,
        workers=context.worker_count, allow_stay=False, class_names=classes,
        memory_gb=solve.memory_gb, scheduler=context.scheduler, cost=gap,
        description=f"evaluate: λ sweep ({sweep_lambdas} m)", pool=context.pool)


def tradeoff_points(table: EpisodeTable, sweep: Sequence[EpisodeRecord], dataset: Dataset,
                    cfg: EvaluateConfig, lambda_: float) -> list[TradeoffPoint]:
    """Accuracy against energy: Table 1's rows, then every sweep setting's episodes (all from
    the same (test model, start) pairs), one curve per method ordered by its setting.

    Args:
        table: Table 1's episodes.
        sweep: The sweep settings' episodes (keyed by :func:`sweep_key`).
        dataset: The dataset (the episodes' test models).
        cfg: The ``evaluate`` section (the methods, the sweep, Random's stop belief).
        lambda_: Table 1's λ in metres (``solve.wrong_declaration_cost_m``).

    Returns:
        One :class:`~rapomdp.experiment.metrics.TradeoffPoint` per (method, setting): its
        accuracy and mean energy in metres.
    """
    from rapomdp.experiment.metrics import TradeoffPoint, table1

    points: list[TradeoffPoint] = []
    for row in table1(table, cfg.methods):
        if row.method == "static":
            points.append(TradeoffPoint("static", "none", 0.0, True, row))
        elif row.method == "random":
            points.append(TradeoffPoint("random", "threshold", cfg.random.belief_threshold,
                                        True, row))
        else:
            points.append(TradeoffPoint(row.method, "lambda", lambda_, True, row))
    settings = sweep_settings(cfg, lambda_)
    if settings:
        keys = [sweep_key(m, p, v) for m, p, v, _ in settings]
        swept = EpisodeTable.from_records(sweep, dataset, keys)
        for (method, parameter, value, _), key in zip(settings, keys, strict=True):
            row = dataclasses.replace(table1(swept, [key])[0], method=method)
            points.append(TradeoffPoint(method, parameter, value, False, row))
    order = {m: i for i, m in enumerate(cfg.methods)}
    return sorted(points, key=lambda p: (order[p.method], p.value))


def figure_class(config: Config, classes: Sequence[str]) -> str:
    """The configured figure class, or the first class when the dataset has no such class."""
    wanted = config.evaluate.figure_class
    return wanted if wanted in classes else classes[0]


def run_evaluate_stage(config: Config, inputs: StageInputs, out: Path,
                       context: RunContext) -> None:
    """Run every episode, score them, write Table 1, the per-class table and the figures.

    Args:
        config: the run's configuration; the stage reads the sections of its key
            (the classifier's, ``viewpoints`` and ``evaluate``) and ``solve`` (λ).
        inputs: the folders of the stages it reads (dataset, train, classifier_eval, observe,
            vptree, robot, solve and learn).
        out: the stage's temporary folder; the workspace swaps it in when the stage finishes.
        context: worker processes, threads and progress bars (no artefact depends on them).

    Returns:
        None. Writes into ``out``: ``episodes.npz``/``episodes.csv`` (every episode's views,
            beliefs, declaration and energy), ``table1.md``/``table1.csv``, ``paired.csv``,
            ``per_class.md``/``.csv``, ``fig3.png``, the accuracy-energy ``sweep/`` and the
            ``held_out/`` comparison and declared-confidence fits, and ``evaluate.json``.
    """
    from rapomdp.experiment import figures
    from rapomdp.experiment.metrics import (
        paired_against,
        paired_csv,
        per_class,
        per_class_markdown,
        rows_csv,
        table1,
        table1_markdown,
        tradeoff_csv,
        tradeoff_markdown,
    )
    from rapomdp.io import save_npz, write_json_atomic, write_text_atomic

    began = time.perf_counter()
    sweep_dir = None
    if sweep_settings(config.evaluate, config.solve.wrong_declaration_cost_m):
        sweep_dir = out / "sweep"
        solve_sweep(config, inputs, sweep_dir, context)
    solved_s = time.perf_counter() - began
    cfg = config.evaluate
    # every method on the held-out volume models, compared before any test model is read
    # (the learned baseline, not held out for itself, for its declared fit)
    runs = held_out_runs(config, inputs, list(cfg.methods), context)
    ran, without_folds = runs
    if ran:
        write_json_atomic(out / HELD_OUT_DIR / COMPARISON_FILE,
                          held_out_comparison(ran, PAIRED_REFERENCE, seed=config.seed,
                                              skipped=without_folds))
    # the POMDPs' (and the learned baseline's) declared confidence, fitted where they stop on
    # held-out objects
    fits = closed_loop_declared(config, inputs, [m for m in cfg.methods
                                                 if m not in ("static", "random")],
                                out / HELD_OUT_DIR, context, runs=runs)
    held_out_s = time.perf_counter() - began - solved_s
    records, dataset = run_episodes(config, inputs, context, sweep_dir,
                                    {name: fit.declared.temperature
                                     for name, fit in fits.items()})
    episodes_s = time.perf_counter() - began - solved_s - held_out_s
    methods = list(config.evaluate.methods)
    sweep = [r for r in records if r.method not in methods]
    table = EpisodeTable.from_records([r for r in records if r.method in methods], dataset,
                                      methods)
    save_npz(out / EPISODES_FILE, compressed=True, **table.arrays())
    rows = table1(table, methods)
    classes_rows = per_class(table, methods)
    paired = paired_against(table, methods, PAIRED_REFERENCE, seed=config.seed)
    write_text_atomic(out / TABLE1_MD, table1_markdown(rows, paired))
    write_text_atomic(out / TABLE1_CSV, rows_csv(rows))
    if paired:
        write_text_atomic(out / PAIRED_CSV, paired_csv(paired))
    write_text_atomic(out / PER_CLASS_MD, per_class_markdown(classes_rows, methods))
    write_text_atomic(out / PER_CLASS_CSV, rows_csv([r for _, r in classes_rows],
                                                      [name for name, _ in classes_rows]))
    write_text_atomic(out / EPISODES_CSV, episodes_csv(table))
    points = tradeoff_points(table, sweep, dataset, config.evaluate,
                             config.solve.wrong_declaration_cost_m)
    write_text_atomic(out / TRADEOFF_CSV, tradeoff_csv(points))
    write_text_atomic(out / TRADEOFF_MD, tradeoff_markdown(points))
    figures.tradeoff(points, out / TRADEOFF_FIGURE)
    shown = figure_class(config, dataset.classes)
    robot = load_robot(inputs.robot)
    figures.fig3(table, methods, shown, out / FIG3_FILE)
    figures.trajectories(table, methods, shown, robot["directions"],
                         robot["reachable"].astype(bool), out / TRAJECTORIES_FILE)
    images = int(table.step_viewpoints.size)
    cpu = float(table.cpu_seconds.sum())
    write_json_atomic(out / SUMMARY_FILE, {
        "methods": [METHOD_NAMES[m] for m in methods],
        "method_keys": methods,
        "classes": dataset.classes,
        "figure_class": shown,
        "episodes": int(table.method.size),
        "images": images,
        "images_per_s": images / cpu if cpu > 0 else None,
        "workers": min(context.worker_count, len(dataset.with_role("test"))),
        "tradeoff_points": len(points),
        "sweep_episodes": len(sweep),
        "declared_fit": {"kind": "closed_loop",
                         "closed_loop": {name: fit.to_dict() for name, fit in fits.items()}},
        "seconds": {"sweep_solve_wall": solved_s, "held_out_wall": held_out_s,
                    "episodes_wall": episodes_s,
                    "episodes_cpu": cpu,
                    "sweep_episodes_cpu": float(sum(r.cpu_seconds for r in sweep)),
                    "total": time.perf_counter() - began},
    })
