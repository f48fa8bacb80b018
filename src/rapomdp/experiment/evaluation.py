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
  ``evaluate.random_thresholds``, Static one point; Table 1's settings are points of it;
- ``evaluate.json``: counts, timing, images per second of the episode loop.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rapomdp.config import Config
from rapomdp.data.dataset import Dataset, ModelEntry, load_dataset
from rapomdp.data.splits import class_seed
from rapomdp.experiment.config import METHOD_NAMES
from rapomdp.experiment.episode import (
    Episode,
    Motion,
    Policy,
    Recogniser,
    Scene,
    run_episode,
    score,
)
from rapomdp.experiment.methods import POMDPPolicy, RandomWalkPolicy, StaticPolicy
from rapomdp.io import load_npz
from rapomdp.parallel import run_tasks, worker_count
from rapomdp.planning.policy import ActiveRecognitionPolicy
from rapomdp.planning.stage import offered_observation_models
from rapomdp.recognition.stage import TRAIN_SECTIONS, load_stage_classifier
from rapomdp.robot.stage import load_robot
from rapomdp.workspace import StageError

if TYPE_CHECKING:
    from rapomdp.experiment.metrics import TradeoffPoint

EVALUATE_SECTIONS = (*TRAIN_SECTIONS, "viewpoints", "evaluate")
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

    @classmethod
    def load(cls, config: Config, inputs: dict[str, Path]) -> ClosedLoop:
        dataset = load_dataset(inputs["dataset"])
        robot = load_robot(inputs["robot"])
        motion = Motion.from_robot(robot)
        observation, _ = offered_observation_models(inputs["observe"], inputs.get("vptree"))
        cfg = config.evaluate

        def method(key: str, random_threshold: float, solve_dir: Path) -> Policy:
            recogniser = VPTREE_RECOGNISER if key == "vptree" else "cnn"
            if key == "static":
                return StaticPolicy(METHOD_NAMES[key])
            if key == "random":
                name = cfg.random.observation_model
                if name not in observation:
                    raise StageError(f"evaluate.random.observation_model is '{name}'; the "
                                     f"workspace has {', '.join(observation)}")
                return RandomWalkPolicy(
                    observation[name], motion.distance_m, motion.reachable,
                    cfg.random.neighbours, random_threshold, cfg.random.max_moves,
                    METHOD_NAMES[key])
            path = solve_dir / f"policy_{key}.npz"
            if not path.exists() or key not in observation:
                raise StageError(f"method '{key}' needs {path.name} from the solve stage: "
                                 f"add '{key}' to solve.models")
            return POMDPPolicy(ActiveRecognitionPolicy.load(path), observation[key],
                               METHOD_NAMES[key], recogniser, cfg.revisit)

        methods = {key: method(key, cfg.random.belief_threshold, inputs["solve"])
                   for key in cfg.methods}
        if "sweep" in inputs:  # the accuracy-energy sweep's settings, run alongside
            for key, parameter, value, folder in sweep_settings(config):
                threshold = value if parameter == "threshold" else cfg.random.belief_threshold
                solve_dir = inputs["sweep"] / folder if folder else inputs["solve"]
                methods[sweep_key(key, parameter, value)] = method(key, threshold, solve_dir)
        recognisers: dict[str, Recogniser] = {}
        if any(m.recogniser == "cnn" for m in methods.values()):
            recognisers["cnn"] = load_stage_classifier(config, inputs["train"], dataset.classes)
        if any(m.recogniser == VPTREE_RECOGNISER for m in methods.values()):
            from rapomdp.recognition.vptree_stage import load_workspace_vptree

            recognisers[VPTREE_RECOGNISER] = load_workspace_vptree(inputs["vptree"])
        return cls(config, dataset, recognisers, methods, motion)

    def scene(self, model: ModelEntry) -> Scene:
        return Scene.of_model(self.config, self.dataset, model)

    def run_model(self, model: ModelEntry) -> list[EpisodeRecord]:
        """Every start x method episode of one test model."""
        scene = self.scene(model)
        starts = start_viewpoints(self.config.seed, model, self.motion.reachable,
                                  self.config.evaluate.starts_per_model)
        records = []
        for start in starts:
            for key, method in self.methods.items():
                # a sweep setting draws as its method does (common random numbers)
                rng = episode_rng(self.config.seed, model, int(start), key.split("@")[0])
                began = time.process_time()
                episode = run_episode(scene, self.recognisers[method.recogniser], method,
                                      self.motion, int(start), self.config.evaluate.max_moves,
                                      rng)
                records.append(EpisodeRecord(key, model.file, int(start), episode,
                                             time.process_time() - began))
        return records


@dataclass(frozen=True)
class EpisodeRecord:
    """One episode as run: method key, test model (its file in the dataset), start viewpoint."""

    method: str
    model: str
    start: int
    episode: Episode
    cpu_seconds: float


_LOOP: dict[str, ClosedLoop] = {}


def _run_model_task(config_json: str, inputs: dict[str, str],
                    model_file: str) -> list[EpisodeRecord]:
    """A worker's task: load the closed loop once per process, run one test model."""
    key = config_json + repr(sorted(inputs.items()))
    if key not in _LOOP:
        _LOOP.clear()
        _LOOP[key] = ClosedLoop.load(Config.model_validate_json(config_json),
                                     {k: Path(v) for k, v in inputs.items()})
    loop = _LOOP[key]
    model = next(m for m in loop.dataset.with_role("test") if m.file == model_file)
    return loop.run_model(model)


def run_episodes(config: Config, inputs: dict[str, Path],
                 processes: int | None = None) -> tuple[list[EpisodeRecord], Dataset]:
    """Every test model x start x method, over ``processes`` (default: the configured worker
    count) processes; records in a fixed order
    (test models as listed, then start, then method)."""
    dataset = load_dataset(inputs["dataset"])
    models = dataset.with_role("test")
    count = processes or worker_count()
    if count <= 1:
        loop = ClosedLoop.load(config, inputs)
        per_model = run_tasks(loop.run_model, [(m,) for m in models], 1,
                              "evaluate: test models")
    else:
        config_json = config.model_dump_json()
        paths = {k: str(v) for k, v in inputs.items()}
        per_model = run_tasks(_run_model_task, [(config_json, paths, m.file) for m in models],
                              count, "evaluate: test models")
    return [r for records in per_model for r in records], dataset


@dataclass
class EpisodeTable:
    """Episodes and their scores as arrays (one row per episode) plus the concatenated steps."""

    classes: list[str]
    methods: list[str]
    method: np.ndarray
    class_index: np.ndarray
    model: np.ndarray
    start: np.ndarray
    declared: np.ndarray
    exhausted: np.ndarray
    correct: np.ndarray
    belief: np.ndarray
    moves: np.ndarray
    distance_m: np.ndarray
    energy: np.ndarray
    offsets: np.ndarray
    step_viewpoints: np.ndarray
    step_outputs: np.ndarray
    step_beliefs: np.ndarray
    cpu_seconds: np.ndarray

    @classmethod
    def from_records(cls, records: Sequence[EpisodeRecord], dataset: Dataset,
                     methods: Sequence[str]) -> EpisodeTable:
        by_file = {m.file: m for m in dataset.with_role("test")}
        truth = np.array([dataset.label(by_file[r.model]) for r in records])
        scores = [score(r.episode, int(t)) for r, t in zip(records, truth, strict=True)]
        lengths = np.array([r.episode.viewpoints.size for r in records])
        return cls(
            classes=list(dataset.classes),
            methods=list(methods),
            method=np.array([r.method for r in records]),
            class_index=truth,
            model=np.array([r.model for r in records]),
            start=np.array([r.start for r in records]),
            declared=np.array([r.episode.declared for r in records]),
            exhausted=np.array([r.episode.exhausted for r in records]),
            correct=np.array([s.correct for s in scores]),
            belief=np.array([s.belief for s in scores]),
            moves=np.array([s.moves for s in scores]),
            distance_m=np.array([s.distance_m for s in scores]),
            energy=np.array([s.energy for s in scores]),
            offsets=np.concatenate([[0], np.cumsum(lengths)]),
            step_viewpoints=np.concatenate([r.episode.viewpoints for r in records]),
            step_outputs=np.concatenate([r.episode.outputs for r in records]),
            step_beliefs=np.concatenate([r.episode.beliefs for r in records]),
            cpu_seconds=np.array([r.cpu_seconds for r in records]),
        )

    def arrays(self) -> dict[str, Any]:
        out = {k: v for k, v in self.__dict__.items() if isinstance(v, np.ndarray)}
        return {**out, "classes": np.array(self.classes), "methods": np.array(self.methods)}

    @classmethod
    def load(cls, path: str | Path) -> EpisodeTable:
        data = load_npz(path)
        fields = {k: data[k] for k in cls.__dataclass_fields__ if k not in ("classes", "methods")}
        return cls(classes=[str(c) for c in data["classes"]],
                   methods=[str(m) for m in data["methods"]], **fields)

    def beliefs_in_true_class(self, episode: int) -> np.ndarray:
        """Belief in the true class after each image of one episode."""
        rows = slice(self.offsets[episode], self.offsets[episode + 1])
        return self.step_beliefs[rows, self.class_index[episode]]

    def viewpoints_of(self, episode: int) -> np.ndarray:
        return self.step_viewpoints[self.offsets[episode]:self.offsets[episode + 1]]


#: The methods that are POMDP policies (solved per λ); the others are Static and Random.
NOT_POMDP = ("static", "random")


def sweep_settings(config: Config) -> list[tuple[str, str, float, str | None]]:
    """The accuracy-energy sweep's extra settings: (method, parameter, value, λ folder) for
    every POMDP method at every extra λ and Random at every extra stop belief.

    Table 1's own settings (``solve.wrong_declaration_cost_m``, ``random.belief_threshold``)
    are not repeated: the main episodes are their points.
    """
    cfg = config.evaluate
    pomdp = [m for m in cfg.methods if m not in NOT_POMDP]
    out: list[tuple[str, str, float, str | None]] = []
    for lam in dict.fromkeys(cfg.lambdas):
        if not np.isclose(lam, config.solve.wrong_declaration_cost_m):
            out += [(m, "lambda", float(lam), f"lambda_{lam:g}") for m in pomdp]
    if "random" in cfg.methods:
        out += [("random", "threshold", float(t), None)
                for t in dict.fromkeys(cfg.random_thresholds)
                if not np.isclose(t, cfg.random.belief_threshold)]
    return out


def sweep_key(method: str, parameter: str, value: float) -> str:
    """The episode key of a method at a sweep setting (``ra@lambda=0.5``)."""
    return f"{method}@{parameter}={value:g}"


def solve_sweep(config: Config, inputs: dict[str, Path], sweep_dir: Path) -> None:
    """Solve every POMDP method of the evaluation at every extra λ of the sweep, as the solve
    stage does (``sweep_dir/lambda_<λ>/policy_<method>.npz``)."""
    from rapomdp.planning.stage import start_viewpoint, workspace_arrays
    from rapomdp.planning.workspace import solve_workspace_problems

    folders: dict[str, tuple[float, list[str]]] = {}
    for method, _, value, folder in sweep_settings(config):
        if folder is not None:
            folders.setdefault(folder, (value, []))[1].append(method)
    for folder, (lam, methods) in folders.items():
        variant = config.model_copy(deep=True)
        variant.solve.models = methods
        models, energy, reachable, classes = workspace_arrays(
            variant, inputs["observe"], inputs["robot"], inputs.get("vptree"))
        solve = config.solve
        solve_workspace_problems(
            models, energy, reachable, sweep_dir / folder, lambda_=lam, discount=solve.discount,
            start_viewpoint=start_viewpoint(reachable), precision=solve.precision,
            timeout=solve.timeout_s, max_iterations=solve.iterations, workers=worker_count(),
            allow_stay=False, class_names=classes)


def tradeoff_points(config: Config, table: EpisodeTable, sweep: Sequence[EpisodeRecord],
                    dataset: Dataset) -> list[TradeoffPoint]:
    """Accuracy against energy: Table 1's rows, then every sweep setting's episodes (all from
    the same (test model, start) pairs), one curve per method ordered by its setting."""
    from rapomdp.experiment.metrics import TradeoffPoint, table1

    cfg = config.evaluate
    points: list[TradeoffPoint] = []
    for row in table1(table, cfg.methods):
        if row.method == "static":
            points.append(TradeoffPoint("static", "none", 0.0, True, row))
        elif row.method == "random":
            points.append(TradeoffPoint("random", "threshold", cfg.random.belief_threshold,
                                        True, row))
        else:
            points.append(TradeoffPoint(row.method, "lambda",
                                        config.solve.wrong_declaration_cost_m, True, row))
    settings = sweep_settings(config)
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


def run_evaluate_stage(config: Config, inputs: dict[str, Path], out: Path) -> None:
    """Run every episode, score them, write Table 1, the per-class table and the figures."""
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
    run_inputs = dict(inputs)
    if sweep_settings(config):
        solve_sweep(config, inputs, out / "sweep")
        run_inputs["sweep"] = out / "sweep"
    solved_s = time.perf_counter() - began
    records, dataset = run_episodes(config, run_inputs)
    episodes_s = time.perf_counter() - began - solved_s
    methods = list(config.evaluate.methods)
    sweep = [r for r in records if r.method not in methods]
    table = EpisodeTable.from_records([r for r in records if r.method in methods], dataset,
                                      methods)
    save_npz(out / "episodes.npz", compressed=True, **table.arrays())
    rows = table1(table, methods)
    classes_rows = per_class(table, methods)
    paired = paired_against(table, methods, PAIRED_REFERENCE, seed=config.seed)
    write_text_atomic(out / "table1.md", table1_markdown(rows, paired))
    write_text_atomic(out / "table1.csv", rows_csv(rows))
    if paired:
        write_text_atomic(out / "paired.csv", paired_csv(paired))
    write_text_atomic(out / "per_class.md", per_class_markdown(classes_rows, methods))
    write_text_atomic(out / "per_class.csv", rows_csv([r for _, r in classes_rows],
                                                      [name for name, _ in classes_rows]))
    write_text_atomic(out / "episodes.csv", _episodes_csv(table))
    points = tradeoff_points(config, table, sweep, dataset)
    write_text_atomic(out / "tradeoff.csv", tradeoff_csv(points))
    write_text_atomic(out / "tradeoff.md", tradeoff_markdown(points))
    figures.tradeoff(points, out / "tradeoff.png")
    shown = figure_class(config, dataset.classes)
    robot = load_robot(inputs["robot"])
    figures.fig3(table, methods, shown, out / "fig3.png")
    figures.trajectories(table, methods, shown, robot["directions"],
                         robot["reachable"].astype(bool), out / "trajectories.png")
    images = int(table.step_viewpoints.size)
    cpu = float(table.cpu_seconds.sum())
    write_json_atomic(out / "evaluate.json", {
        "methods": [METHOD_NAMES[m] for m in methods],
        "method_keys": methods,
        "classes": dataset.classes,
        "figure_class": shown,
        "episodes": int(table.method.size),
        "images": images,
        "images_per_s": images / cpu if cpu > 0 else None,
        "workers": min(worker_count(), len(dataset.with_role("test"))),
        "tradeoff_points": len(points),
        "sweep_episodes": len(sweep),
        "seconds": {"sweep_solve_wall": solved_s, "episodes_wall": episodes_s,
                    "episodes_cpu": cpu,
                    "sweep_episodes_cpu": float(sum(r.cpu_seconds for r in sweep)),
                    "total": time.perf_counter() - began},
    })


def _episodes_csv(table: EpisodeTable) -> str:
    lines = ["method,class,model,start,declared,correct,belief,moves,distance_m,energy,"
             "exhausted,viewpoints"]
    for i in range(table.method.size):
        views = " ".join(str(v) for v in table.viewpoints_of(i))
        lines.append(
            f"{table.method[i]},{table.classes[table.class_index[i]]},{table.model[i]},"
            f"{table.start[i]},{table.classes[table.declared[i]]},{int(table.correct[i])},"
            f"{table.belief[i]:.6g},{table.moves[i]},{table.distance_m[i]:.6g},"
            f"{table.energy[i]:.6g},{int(table.exhausted[i])},{views}")
    return "\n".join(lines) + "\n"
