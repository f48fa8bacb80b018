"""The headroom decomposition: how far estimation, belief and planning each fall short.

For a finished workspace, the evaluate stage's RA-POMDP — the same solver settings, λ,
lookahead and revisit rule, the same (test model, start) pairs and episode seeds — runs with
other observation models; every other row is an *oracle* diagnostic, read off the test models
themselves, so it is an upper bound and never feeds a choice:

- ``learned``: the learned model as evaluated (must reproduce the evaluate stage's RA-POMDP
  episodes one for one: :attr:`HeadroomResult.evaluate_mismatches`);
- ``oracle_in_sample``: P(o | c, x) counted on the test models' own labels at X_rho (the
  Classifier model's count and pseudo-count:
  :func:`~rapomdp.recognition.evaluation.viewpoint_confusion`);
- ``oracle_cross_object``: the same count on the other half of each class's test models only
  (:func:`cross_object_halves`): an object's episodes never use a model that counted it;
- ``oracle_correct_in_sample`` / ``oracle_correct_cross_object``: the learned single-view rows
  with their P(correct) replaced by the oracle's (:func:`with_correct_probability`), then
  tempered by the learned temperature as evaluated (only P(correct) differs from ``learned``);
- ``oracle_temperature``: the learned single-view rows tempered by the belief temperature
  fitted on the test models' labels (the observe stage's rule: :func:`oracle_temperature`);
  ``oracle_in_sample_temperature``: the in-sample oracle tempered alike (estimation and
  belief both from the test models).

The counted models (``oracle_in_sample``, ``oracle_cross_object``) are used as counted (t = 1,
naive Bayes); the ``*temperature`` rows temper by a temperature fitted on the test models.

The labels are the closed loop's own: every test model rendered at every viewpoint of X_rho and
classified one image at a time (as an episode looks), and the episodes read them back. Writes
only under ``out`` (default ``W/headroom/``): ``headroom.md|csv|json`` and the oracle policies
under ``policies/``.
"""

from __future__ import annotations

import csv
import io
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from rapomdp.awareness.choices import RecordedObservation
from rapomdp.belief import temper
from rapomdp.config import METHOD_NAMES, Config
from rapomdp.context import RunContext
from rapomdp.data.dataset import Dataset, ModelEntry, load_dataset
from rapomdp.data.splits import class_seed
from rapomdp.data.test_views import TEST_STREAM, xrho_noise_rng
from rapomdp.document import markdown_table
from rapomdp.experiment.episode import Motion, run_episode
from rapomdp.experiment.episode_table import EPISODES_FILE, EpisodeRecord, EpisodeTable
from rapomdp.experiment.evaluation import ClosedLoop, episode_rng, start_viewpoints
from rapomdp.experiment.methods import POMDPPolicy
from rapomdp.experiment.metrics import table1
from rapomdp.io import write_json_atomic, write_text_atomic
from rapomdp.parallel import pooled, run_tasks
from rapomdp.pipeline import STAGE_NAMES, get_stage
from rapomdp.planning.artefacts import load_solve_summary, policy_file
from rapomdp.planning.policy import ActiveRecognitionPolicy
from rapomdp.planning.stage import start_viewpoint
from rapomdp.planning.workspace import solve_workspace_problems
from rapomdp.recognition.belief import fit_temperature, held_out_walks
from rapomdp.recognition.evaluation import viewpoint_confusion
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import StageError, StageInputs, Workspace

HEADROOM_DIR = "headroom"
HEADROOM_MD = "headroom.md"
HEADROOM_CSV = "headroom.csv"
HEADROOM_JSON = "headroom.json"
POLICIES_DIR = "policies"
#: Written beside every oracle row, in every output.
ORACLE_NOTE = "oracle: never used for any choice"
#: The evaluate stage's method whose planner and belief every row shares.
METHOD = "ra"

ROWS: dict[str, tuple[str, bool]] = {
    "learned": ("(a) RA-POMDP as evaluated: the learned model", False),
    "oracle_in_sample": ("(b) in-sample oracle: counted on the test models, t = 1", True),
    "oracle_cross_object": ("(c) cross-object oracle: counted on the class's other test "
                            "objects, t = 1", True),
    "oracle_correct_in_sample": ("(d) learned wrong labels, P(correct) of the in-sample "
                                 "oracle, learned t", True),
    "oracle_correct_cross_object": ("(d) learned wrong labels, P(correct) of the cross-object "
                                    "oracle, learned t", True),
    "oracle_temperature": ("(e) learned model, belief temperature fitted on the test "
                           "models", True),
    "oracle_in_sample_temperature": ("(e) in-sample oracle, belief temperature fitted on the "
                                     "test models", True),
}
"""Row key -> (label, oracle?), in table order."""
CROSS_ROWS = ("oracle_cross_object", "oracle_correct_cross_object")


@dataclass(frozen=True)
class HeadroomRow:
    """One row: the episodes of one observation model under RA-POMDP's planner and belief.

    ``overconfidence``: the mean final confidence (belief in the declared class) minus the
    accuracy; ``solve_s``: CPU seconds of its solves (0 for the learned model: the solve
    stage's policy); ``episodes_cpu_s``: CPU seconds of its episodes."""

    name: str
    accuracy: float
    energy_m: float
    moves: float
    overconfidence: float
    episodes: int
    label: str
    oracle: bool
    accuracy_low: float
    accuracy_high: float
    confidence: float
    exhausted: int
    solve_s: float
    episodes_cpu_s: float

    @property
    def seconds(self) -> float:
        return self.solve_s + self.episodes_cpu_s


@dataclass
class HeadroomResult:
    """The rows and what they were built from: the test models' ``labels`` (N,) and the
    recogniser's labels ``predicted`` (N, V) at X_rho; per observation model (``models``, the
    planner's and the belief's) the test model files
    it was counted on (``counted_on``, empty for the learned model); per row and test model file
    the observation model its episodes used (``assignment``); ``halves`` (N,) of the
    cross-object split; ``temperatures``: the oracle-fitted ones by row;
    ``evaluate_mismatches``: row (a)'s episodes that differ from the evaluate stage's RA-POMDP
    ones; ``label_agreement``: the share of labels equal to the observe stage's record."""

    rows: list[HeadroomRow]
    table: EpisodeTable
    test_models: list[str]
    labels: np.ndarray
    predicted: np.ndarray
    models: dict[str, np.ndarray]
    counted_on: dict[str, tuple[str, ...]]
    assignment: dict[str, dict[str, str]]
    halves: np.ndarray | None
    learned_temperature: float
    correction: str
    temperatures: dict[str, float]
    evaluate_mismatches: int
    label_agreement: float
    seconds: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


# -- the observation models --------------------------------------------------------------------

def cross_object_halves(models: Sequence[ModelEntry]) -> np.ndarray:
    """Each test model's half (N,) of 0 / 1: alternating within its class in the given order,
    so each half holds about half of every class's test models. ValueError naming a class
    with fewer than two (nothing else of the class to count on)."""
    halves = np.zeros(len(models), dtype=np.int64)
    seen: dict[str, int] = {}
    for i, model in enumerate(models):
        halves[i] = seen.get(model.class_name, 0) % 2
        seen[model.class_name] = seen.get(model.class_name, 0) + 1
    few = sorted(name for name, n in seen.items() if n < 2)
    if few:
        raise ValueError(f"the cross-object oracle needs two or more test models a class; "
                         f"{', '.join(few)} has fewer (dataset.split.test)")
    return halves


def with_correct_probability(model: np.ndarray, correct: np.ndarray) -> np.ndarray:
    """``model`` (V, C, C) with P(o = c | c, x) set to ``correct`` (V, C) and each row's wrong
    labels rescaled to ``1 - correct``, their proportions kept (uniform where the model had
    no wrong mass)."""
    p = np.asarray(model, dtype=np.float64)
    c = p.shape[1]
    idx = np.arange(c)
    wrong = p.copy()
    wrong[:, idx, idx] = 0.0
    mass = wrong.sum(axis=2, keepdims=True)
    uniform = np.broadcast_to((1.0 - np.eye(c)) / max(c - 1, 1), p.shape)
    shares = np.where(mass > 0, wrong / np.where(mass > 0, mass, 1.0), uniform)
    out = shares * (1.0 - np.asarray(correct, dtype=np.float64))[:, :, None]
    out[:, idx, idx] = correct
    return out


def oracle_temperature(single_view: np.ndarray, labels: np.ndarray, predicted: np.ndarray,
                       directions: np.ndarray, seed: int) -> float:
    """The belief temperature of ``single_view`` (V, C, C) fitted as the observe stage fits
    it — :func:`~rapomdp.recognition.belief.fit_temperature` on random walks of the project's
    length, count and neighbours — but on the test models' labels (``labels`` (N,),
    ``predicted`` (N, V)): an oracle."""
    row_model = np.zeros(len(labels), dtype=np.int64)
    walks, walk_row = held_out_walks(row_model, directions,
                                     class_seed(seed, "headroom/temperature"))
    return fit_temperature([single_view], row_model, labels, predicted, walks, walk_row)


@dataclass
class RowModels:
    """Each row's observation models: by model key the planner's and belief's (``models``), the
    test model files counted (``counted_on``);
    per row and test model file the model its episodes use (``assignment``); the oracle-fitted
    temperatures by row."""

    models: dict[str, np.ndarray]
    counted_on: dict[str, tuple[str, ...]]
    assignment: dict[str, dict[str, str]]
    temperatures: dict[str, float]


def row_models(rows: Sequence[str], files: Sequence[str], labels: np.ndarray,
               predicted: np.ndarray, halves: np.ndarray | None, classes: int,
               pseudo_count: float, learned: np.ndarray,
               learned_temperature: float, directions: np.ndarray,
               seed: int) -> RowModels:
    """The observation models of ``rows`` (keys of :data:`ROWS`) from the test models'
    ``files``, ``labels`` (N,) and ``predicted`` labels (N, V) at X_rho, the cross-object
    ``halves`` (N,) and the learned model as evaluated (``learned``, tempered by
    ``learned_temperature``). Counts use ``pseudo_count``."""
    if halves is None and set(rows) & set(CROSS_ROWS):
        raise ValueError("the cross-object rows need the halves (cross_object_halves)")
    single = temper(learned, 1.0 / learned_temperature)  # the single-view rows it tempers
    out = RowModels({"learned": learned}, {"learned": ()},
                    {"learned": dict.fromkeys(files, "learned")}, {})

    def add(key: str, model: np.ndarray, on: np.ndarray) -> None:
        out.models[key] = model
        out.counted_on[key] = tuple(f for f, used in zip(files, on, strict=True) if used)

    def add_oracle_correct(key: str, oracle: np.ndarray, on: np.ndarray) -> None:
        # the learned single-view rows with the oracle's P(correct), then the learned belief
        # correction as evaluated (its temperature)
        rows_of = with_correct_probability(single, np.diagonal(oracle, axis1=1, axis2=2))
        tempered = temper(rows_of, learned_temperature)
        add(key, tempered, on)

    everything = np.ones(len(files), dtype=bool)
    in_sample = viewpoint_confusion(labels, predicted, classes, pseudo_count)
    if "oracle_in_sample" in rows:
        add("oracle_in_sample", in_sample, everything)
    if "oracle_correct_in_sample" in rows:
        add_oracle_correct("oracle_correct_in_sample", in_sample, everything)
    for row, rows_of in (("oracle_temperature", single),
                         ("oracle_in_sample_temperature", in_sample)):
        if row in rows:
            t = oracle_temperature(rows_of, labels, predicted, directions, seed)
            out.temperatures[row] = t
            tempered = temper(rows_of, t)
            add(row, tempered, everything)
    for row in rows:
        if row in out.models:
            out.assignment[row] = dict.fromkeys(files, row)
    if halves is not None:
        for h in (0, 1):
            on = halves == h
            half = viewpoint_confusion(labels[on], predicted[on], classes, pseudo_count)
            if "oracle_cross_object" in rows:
                add(f"oracle_cross_object_h{h}", half, on)
            if "oracle_correct_cross_object" in rows:
                add_oracle_correct(f"oracle_correct_cross_object_h{h}", half, on)
        for row in CROSS_ROWS:  # an object's episodes use the model of the other half
            if row in rows:
                out.assignment[row] = {f: f"{row}_h{1 - h}"
                                       for f, h in zip(files, halves, strict=True)}
    out.assignment = {row: out.assignment[row] for row in rows}  # in the rows' order
    return out


# -- the closed loop's labels and episodes (worker tasks) ----------------------------------------

def _ra_only(config: Config) -> Config:
    variant = config.model_copy(deep=True)
    variant.evaluate.methods = [METHOD]
    return variant


def _outputs_task(config_json: str, inputs: StageInputs, files: list[str]) -> list[np.ndarray]:
    """The recogniser's output (V, C) at every X_rho viewpoint of each test model, each view
    rendered (:meth:`TestViews.look`) and classified alone, as an episode looks."""
    loop = ClosedLoop.load(Config.model_validate_json(config_json), inputs, threads=1)
    by_file = {m.file: m for m in loop.dataset.with_role("test")}
    cnn = loop.recognisers["cnn"]
    out = []
    for name in files:
        model = by_file[name]
        scene = loop.scene(model)
        rng = xrho_noise_rng(loop.config.seed, TEST_STREAM, model)  # draws with noise only
        out.append(np.stack([np.asarray(cnn.predict(scene.look(v, rng)[None])[0])
                             for v in range(loop.motion.viewpoints)]))
    return out


def _episodes_task(config_json: str, inputs: StageInputs,
                   arms: dict[str, tuple[str, np.ndarray]],
                   assignment: dict[str, dict[str, str]], files: list[str],
                   outputs: list[np.ndarray]) -> list[EpisodeRecord]:
    """Every start x row episode of each test model: RA-POMDP's planner and belief (the
    evaluate stage's method, its settings and seeds) with each row's observation model."""
    loop = ClosedLoop.load(Config.model_validate_json(config_json), inputs, threads=1)
    evaluated = loop.methods[METHOD]
    assert isinstance(evaluated, POMDPPolicy)
    policies = {key: POMDPPolicy(ActiveRecognitionPolicy.load(path), model, evaluated.name,
                                 evaluated.recogniser, evaluated.revisit,
                                 lookahead_over=evaluated.lookahead_over)
                for key, (path, model) in arms.items()}
    by_file = {m.file: m for m in loop.dataset.with_role("test")}
    cnn = loop.recognisers[evaluated.recogniser]
    cfg = loop.config
    records = []
    for name, output in zip(files, outputs, strict=True):
        model = by_file[name]
        scene = loop.scene(model)
        memo = None if scene.noise.enabled else {v: output[v] for v in range(len(output))}
        for start in start_viewpoints(cfg.seed, model, loop.motion.reachable,
                                      cfg.evaluate.starts_per_model):
            for row, arm_of in assignment.items():
                rng = episode_rng(cfg.seed, model, int(start), METHOD)
                began = time.process_time()
                episode = run_episode(scene, cnn, policies[arm_of[name]], loop.motion,
                                      int(start), cfg.evaluate.max_moves, rng, memo)
                records.append(EpisodeRecord(row, name, int(start), episode,
                                             time.process_time() - began))
    return records


def _shares(files: list[str], count: int) -> list[list[str]]:
    return [[files[i] for i in share]
            for share in np.array_split(np.arange(len(files)), max(1, min(count, len(files))))]


def _mismatches(mine: EpisodeTable, evaluated: EpisodeTable) -> int:
    """Episodes of ``mine`` (row ``learned``) that differ from ``evaluated``'s RA-POMDP ones:
    test model, start, declaration, viewpoints visited or energy."""
    a = np.flatnonzero(mine.method == "learned")
    b = np.flatnonzero(evaluated.method == METHOD)
    if a.size != b.size:
        return max(a.size, b.size)
    bad = 0
    for i, j in zip(a, b, strict=True):
        same = (mine.model[i] == evaluated.model[j] and mine.start[i] == evaluated.start[j]
                and mine.declared[i] == evaluated.declared[j]
                and mine.energy[i] == evaluated.energy[j]
                and np.array_equal(mine.viewpoints_of(int(i)), evaluated.viewpoints_of(int(j))))
        bad += not same
    return bad


def _check_out(ws: Workspace, out: Path) -> None:
    target = out.resolve()
    for name in STAGE_NAMES:
        stage = ws.stage_dir(name).resolve()
        if target == stage or stage in target.parents:
            raise StageError(f"{out}: inside the {name} stage's folder; the headroom writes "
                             f"only to {ws.root / HEADROOM_DIR} or a folder of its own")


# -- the decomposition ---------------------------------------------------------------------------

def run_headroom(workspace: str | Path | Workspace, out: str | Path | None = None,
                 context: RunContext = RunContext(),
                 rows: Sequence[str] | None = None) -> HeadroomResult:
    """Every row of :data:`ROWS` (or ``rows``; None: all, the cross-object ones dropped with a
    note when a class has fewer than two test models) on a finished workspace, its policies
    solved as the solve stage solves (``solve`` settings, λ, start viewpoint) over
    ``context``'s workers; writes ``headroom.md|csv|json`` into ``out`` (default
    ``W/headroom/``).

    How far estimation, belief and planning each fall short: each row reruns the evaluate
    stage's RA-POMDP episodes (the same pairs, seeds and solver settings) with another
    observation model, an oracle read off the test models themselves (an upper bound that
    never feeds a choice).

    Args:
        workspace: A workspace whose evaluate stage has finished.
        out: The folder of the tables (default ``W/headroom/``).
        context: Workers, threads and progress bars.
        rows: The rows to compute (names of :data:`ROWS`); None: all.

    Returns:
        The rows (accuracy, energy in metres, moves, overconfidence per row) and what they
        were built from.

    Example:
        On a finished demo workspace (a minute)::

            from rapomdp.study.headroom import run_headroom

            result = run_headroom("runs/demo")
            print(headroom_markdown(result.rows))
    """
    with pooled(context) as shared:
        return _headroom(workspace, out, shared, rows)


def _headroom(workspace: str | Path | Workspace, out: str | Path | None,
              context: RunContext, rows: Sequence[str] | None) -> HeadroomResult:
    began = time.perf_counter()
    ws = workspace if isinstance(workspace, Workspace) else Workspace(workspace)
    config = ws.config()
    if METHOD not in config.evaluate.methods:
        raise StageError(f"{ws.root}: evaluate.methods has no '{METHOD}': the headroom reruns "
                         "the evaluate stage's RA-POMDP")
    inputs = ws.inputs(get_stage("evaluate"))
    evaluate_dir = ws.require("evaluate")
    out = Path(out) if out is not None else ws.root / HEADROOM_DIR
    _check_out(ws, out)
    notes: list[str] = []
    dataset: Dataset = load_dataset(inputs.dataset)
    test = dataset.with_role("test")
    files = [m.file for m in test]
    labels = np.array([dataset.label(m) for m in test])
    try:
        halves: np.ndarray | None = cross_object_halves(test)
    except ValueError as exc:
        if rows is not None and set(rows) & set(CROSS_ROWS):
            raise StageError(str(exc)) from None
        halves = None
        notes.append(f"cross-object rows left out: {exc}")
    wanted = [r for r in (rows if rows is not None else ROWS)
              if halves is not None or r not in CROSS_ROWS]
    unknown = [r for r in wanted if r not in ROWS]
    if unknown:
        raise ValueError(f"unknown headroom rows {unknown}; rows are {', '.join(ROWS)}")
    wanted = ["learned", *(r for r in ROWS if r in wanted and r != "learned")]
    config_json = _ra_only(config).model_dump_json()
    count = context.worker_count

    # 1. the recogniser's labels of every test model at X_rho, as the episodes see them
    shares = _shares(files, count)
    per_share = run_tasks(_outputs_task, [(config_json, inputs, share) for share in shares],
                          count, "headroom: test models at X_rho", context.progress,
                          context.scheduler, unit="test models",
                          sizes=[len(share) for share in shares], pool=context.pool)
    outputs = [o for share in per_share for o in share]
    predicted = np.stack([o.argmax(axis=1) for o in outputs])
    recorded = RecordedObservation.load(inputs.observe)
    observe_labels = recorded.arrays.get("test_predictions")
    agreement = (float(np.mean(observe_labels == predicted))
                 if observe_labels is not None and observe_labels.shape == predicted.shape
                 else float("nan"))
    labels_s = time.perf_counter() - began

    # 2. the observation models, each row's per test model, and their policies
    classes = recorded.classes
    learned = np.asarray(recorded.arrays[METHOD], dtype=np.float64)
    t_learned = float(recorded.calibration["temperatures"][METHOD])
    correction = str(recorded.calibration["belief_corrections"][METHOD])
    built = row_models(wanted, files, labels, predicted, halves, len(classes),
                       config.observe.classifier_pseudo_count, learned, t_learned,
                       np.asarray(recorded.arrays["directions"]), config.seed)
    models, assignment = built.models, built.assignment
    robot = load_robot(inputs.robot)
    motion = Motion.from_robot(robot)
    policies = out / POLICIES_DIR
    to_solve = {k: m for k, m in models.items() if k != "learned"}
    solve_began = time.perf_counter()
    if to_solve:
        s = config.solve
        solve_workspace_problems(
            to_solve, motion.energy, motion.reachable, policies,
            lambda_=s.wrong_declaration_cost_m, discount=s.discount,
            start_viewpoint=start_viewpoint(motion.reachable), precision=s.precision,
            timeout=s.timeout_s, max_iterations=s.iterations, workers=count,
            allow_stay=False, class_names=classes, memory_gb=s.memory_gb,
            scheduler=context.scheduler, pool=context.pool)
    summary = load_solve_summary(policies) if to_solve else {}
    solve_s = time.perf_counter() - solve_began
    paths = {k: str(policies / policy_file(k)) for k in to_solve}
    paths["learned"] = str(inputs.solve / policy_file(METHOD))

    # 3. the episodes: every (test model, start) pair of the evaluate stage, every row
    arms = {k: (paths[k], models[k]) for k in models}
    episodes_began = time.perf_counter()
    tasks = []
    for share in _shares(files, count):
        idx = [files.index(f) for f in share]
        tasks.append((config_json, inputs, arms, assignment, share, [outputs[i] for i in idx]))
    records = [r for share in run_tasks(_episodes_task, tasks, count, "headroom: episodes",
                                        context.progress, context.scheduler,
                                        unit="test models", sizes=[len(t[4]) for t in tasks],
                                        pool=context.pool)
               for r in share]
    episodes_s = time.perf_counter() - episodes_began
    table = EpisodeTable.from_records(records, dataset, wanted)
    mismatches = _mismatches(table, EpisodeTable.load(evaluate_dir / EPISODES_FILE))

    confidence = table.final_confidence()
    result_rows = []
    for key, summary_row in zip(wanted, table1(table, wanted), strict=True):
        mine = table.method == key
        label, oracle = ROWS[key]
        arms_of = set(assignment[key].values())
        result_rows.append(HeadroomRow(
            key, summary_row.accuracy, summary_row.means["energy"], summary_row.means["moves"],
            float(confidence[mine].mean() - summary_row.accuracy), summary_row.episodes,
            label, oracle, summary_row.accuracy_low, summary_row.accuracy_high,
            float(confidence[mine].mean()), summary_row.exhausted,
            float(sum(float(summary[a]["seconds"]) for a in arms_of if a in summary)),
            float(table.cpu_seconds[mine].sum())))
    result = HeadroomResult(
        result_rows, table, files, labels, predicted, models, built.counted_on,
        assignment, halves, t_learned, correction, built.temperatures,
        mismatches, agreement,
        {"labels_wall": labels_s, "solve_wall": solve_s, "episodes_wall": episodes_s,
         "total": time.perf_counter() - began}, notes)
    write_headroom(result, out)
    return result


# -- outputs -------------------------------------------------------------------------------------

HEADER = ["Row", "Observation model", "Accuracy [95 % CI]", "Energy (m)", "# moves",
          "Confidence − accuracy", "Episodes", "Seconds (solve + episodes CPU)"]


def headroom_markdown(rows: Sequence[HeadroomRow]) -> str:
    """The rows as a markdown table under a line saying what they are; every oracle row says
    :data:`ORACLE_NOTE`."""
    cells = [[r.name, f"{r.label} — {ORACLE_NOTE}" if r.oracle else r.label,
              f"{r.accuracy:.3f} [{r.accuracy_low:.3f}, {r.accuracy_high:.3f}]",
              f"{r.energy_m:.3f}", f"{r.moves:.2f}", f"{r.overconfidence:+.3f}",
              str(r.episodes), f"{r.solve_s:.1f} + {r.episodes_cpu_s:.1f}"] for r in rows]
    return (f"Headroom decomposition (diagnostics; {ORACLE_NOTE}): RA-POMDP's planner and "
            f"belief ({METHOD_NAMES[METHOD]}: its solver settings, λ, lookahead and episode "
            "seeds) with each observation model, from the evaluate stage's (test model, start) "
            "pairs.\n\n" + markdown_table(HEADER, cells))


def headroom_csv(rows: Sequence[HeadroomRow]) -> str:
    """One line per row (every :class:`HeadroomRow` field, and ``note``)."""
    names = list(HeadroomRow.__dataclass_fields__)
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow([*names, "note"])
    for r in rows:
        values = asdict(r)
        writer.writerow([*(values[n] for n in names),
                         ORACLE_NOTE if r.oracle else "as evaluated"])
    return text.getvalue()


def write_headroom(result: HeadroomResult, out: str | Path) -> None:
    """``headroom.md``, ``headroom.csv`` and ``headroom.json`` (rows, temperatures, counts,
    times, the cross-object split) into ``out``."""
    out = Path(out)
    write_text_atomic(out / HEADROOM_MD, headroom_markdown(result.rows))
    write_text_atomic(out / HEADROOM_CSV, headroom_csv(result.rows))
    write_json_atomic(out / HEADROOM_JSON, {
        "note": ORACLE_NOTE,
        "rows": [{**asdict(r), "note": ORACLE_NOTE if r.oracle else "as evaluated"}
                 for r in result.rows],
        "learned_temperature": result.learned_temperature,
        "belief_correction": result.correction,
        "oracle_temperatures": result.temperatures,
        "evaluate_mismatches": result.evaluate_mismatches,
        "label_agreement_with_observe": result.label_agreement,
        "counted_on": {k: list(v) for k, v in result.counted_on.items()},
        "assignment": result.assignment,
        "halves": None if result.halves is None else dict(zip(result.test_models,
                                                               result.halves.tolist(),
                                                               strict=True)),
        "seconds": result.seconds,
        "notes": result.notes,
    })
