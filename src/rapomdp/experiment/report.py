"""The ``report`` stage: one markdown and one HTML page gathering a workspace's results.

``W/report/`` holds ``report.md`` and ``report.html`` and a copy of every figure they show (PNG),
so the folder is self-contained. The report reads, from the stages it needs:

- ``evaluate``: ``episodes.npz`` (Table 1 and the per-class table are computed from the
  episodes, not parsed back from the markdown files), ``fig3.png``, ``trajectories.png`` and
  ``evaluate.json`` (episodes, images, images/s, methods, figure class, seconds);
- ``observe``: ``quality.csv`` (the self-awareness table's numbers) and ``calibration.png``;
- ``classifier_eval``: ``metrics.json``, ``confusion_xrho.png``, ``accuracy_hemisphere.png``;
- ``train``: ``training.png``; ``robot``: ``robot.json`` and ``robot.png``;
- ``solve``: ``solve_summary.json`` (the solver's bounds per observation model);
- Fig. 1, made here for the figure class from the render, saliency, volume and observe stages.

and, when present (they are not among its inputs): ``W/figures/fig2.png`` (``rapomdp figure
fig2``, expensive: it trains three classifiers) and ``W/vptree/vptree.json`` (the VP-tree
baseline). A missing file gives a line saying what is missing and which command makes it.

The pages are written by the document layer (:mod:`rapomdp.document`); the self-awareness
section (Figs. 1 and 2, the observe stage's tables and figures, the declared confidence) is
:mod:`rapomdp.experiment.report_awareness`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from rapomdp.awareness.report import write_fig1
from rapomdp.config import METHOD_NAMES, Config
from rapomdp.context import RunContext
from rapomdp.data.dataset import load_dataset
from rapomdp.document import Builder, Code, Heading, Paragraph, Table, to_html, to_markdown
from rapomdp.experiment.episode_table import (
    EPISODES_FILE,
    FIG3_FILE,
    SUMMARY_FILE,
    TRADEOFF_CSV,
    TRADEOFF_FIGURE,
    TRAJECTORIES_FILE,
    EpisodeTable,
)
from rapomdp.experiment.evaluation import PAIRED_REFERENCE
from rapomdp.experiment.evaluation import figure_class as evaluation_figure_class
from rapomdp.experiment.held_out import load_held_out_comparison
from rapomdp.experiment.learned import CURVES_FIGURE, LEARN_SUMMARY
from rapomdp.experiment.metrics import (
    PER_CLASS_NOTE,
    MethodSummary,
    PairedDifference,
    TradeoffPoint,
    paired_against,
    paired_note,
    per_class,
    per_class_cells,
    read_tradeoff_csv,
    standing_phrases,
    table1,
    table1_cells,
    table1_story,
)
from rapomdp.experiment.report_awareness import awareness_section
from rapomdp.experiment.sections import REPORT_INPUTS
from rapomdp.io import ArtefactError, stable_hash, write_text_atomic
from rapomdp.planning.artefacts import SOLVE_SUMMARY
from rapomdp.recognition.artefacts import (
    HEMISPHERE_FIGURE,
    METRICS_FILE,
    TRAINING_FIGURE,
    VPTREE_SUMMARY_FILE,
    confusion_file,
    load_single_view_metrics,
    load_vptree_summary,
)
from rapomdp.robot.artefacts import ROBOT_FIGURE, ROBOT_SUMMARY, describe
from rapomdp.workspace import StageError, StageInputs, Workspace, read_stage_record

REPORT_MD = "report.md"
REPORT_HTML = "report.html"


def _fmt(value: Any, digits: int = 3) -> str:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return str(value)
    return str(value) if isinstance(value, int) else f"{value:.{digits}f}"


def figure_class(evaluation: dict[str, Any] | None, config: Config,
                 classes: Sequence[str]) -> str:
    """The class of Figs. 1 and 3: the one the evaluate stage drew, else the configuration's
    (:func:`rapomdp.experiment.evaluation.figure_class`)."""
    drawn = (evaluation or {}).get("figure_class")
    return drawn if drawn in classes else evaluation_figure_class(config, classes)


def _provenance(builder: Builder, config: Config, given: dict[str, Path]) -> None:
    """The configuration hash and every stage's key: the workspace's, then those of the
    report's input folders (``given``: ``{stage: folder}``) not recorded there."""
    builder.add(Paragraph(
        f"Configuration hash {stable_hash(config.model_dump(mode='json'))[:12]}, "
        f"seed {config.seed}, workspace {builder.root}. Every stage the workspace holds, by "
        f"when it last finished (key: the hash of its configuration sections and inputs):"))
    ran = Workspace(builder.root).manifest().get("stages", {})
    order = sorted((str(record.get("finished", "")), name) for name, record in ran.items()
                   if name != "report" and isinstance(record, dict))
    folders = {name: builder.root / name for _, name in order}
    folders.update({name: folder for name, folder in given.items() if name not in folders})
    rows = []
    for name, folder in folders.items():
        try:
            record = read_stage_record(folder)
        except StageError:
            rows.append([name, "-", "-", "-"])
            continue
        rows.append([name, str(record.get("key", "-"))[:12], str(record.get("finished", "-")),
                     _fmt(record.get("seconds", "-"), 1)])
    builder.add(Table(["stage", "key", "finished", "seconds"], rows))
    builder.add(Code(config.to_commented_yaml(),
                     "The configuration of this run (as `rapomdp config` prints it)"))


#: What Table 1's columns mean (metrics.table1_markdown writes them).
TABLE1_COLUMNS = (
    "Columns: Accuracy — the fraction of episodes whose declared class is the test model's "
    "true class, with Wilson's 95 % score interval; Belief — the method's final belief in the "
    "true class; # steps — the moves made (images after the first); Distance — the camera's "
    "path along the sphere of radius ρ, in metres; Energy — the summed movement energy E_M of "
    "Eq. 3, in metres; each as mean ± the half-width of Student's 95 % interval; — where a "
    "method never moves. Episodes — test models × start viewpoints (those that hit the step "
    "budget had to declare there). The intervals treat episodes as independent draws: they "
    "describe the spread over this protocol's starts and classes, not over unseen objects.")


def _timing(seconds: Any, workers: Any) -> str:
    """The evaluate stage's times in words."""
    if not isinstance(seconds, dict):
        return f"Time: {_fmt(seconds, 1)} s." if seconds is not None else ""
    parts = []
    if "episodes_cpu" in seconds:
        parts.append(f"the episodes took {_fmt(seconds['episodes_cpu'], 1)} s of CPU time")
    if "episodes_wall" in seconds:
        over = f" over {workers} worker(s)" if isinstance(workers, int) else ""
        parts.append(f"{_fmt(seconds['episodes_wall'], 1)} s of wall time{over}")
    if "total" in seconds:
        parts.append(f"the stage {_fmt(seconds['total'], 1)} s in all")
    return ("Time: " + ", ".join(parts) + ".") if parts else ""


def evaluation_summaries(table: EpisodeTable, folder: Path, seed: int
                         ) -> tuple[list[MethodSummary], dict[str, PairedDifference],
                                    list[TradeoffPoint], str]:
    """Table 1's rows, the paired differences to RA-POMDP (empty, with the reason as the last
    item, when the episodes share no (test model, start) pairs) and the accuracy-energy points
    of an evaluate folder: what the report and the README's generated block say."""
    rows = table1(table, table.methods)
    try:
        paired, unpaired = paired_against(table, table.methods, PAIRED_REFERENCE, seed=seed), ""
    except ValueError as exc:
        paired, unpaired = {}, str(exc)
    points = (read_tradeoff_csv((folder / TRADEOFF_CSV).read_text(encoding="utf-8"))
              if (folder / TRADEOFF_CSV).is_file() else [])
    return rows, paired, points, unpaired


def _evaluation(b: Builder, folder: Path, cmd: str, seed: int) -> dict[str, Any] | None:
    how = f"made by `{cmd} evaluate -w {b.root}`"
    b.add(Heading("Closed-loop recognition (Table 1)"))
    data = b.json(folder / SUMMARY_FILE, how)
    if data is not None:
        methods = data.get("methods", [])
        b.add(Paragraph(
            f"{data.get('episodes', '?')} episodes of the methods "
            f"{', '.join(map(str, methods)) if isinstance(methods, list) else methods}; "
            f"{data.get('images', '?')} depth images rendered and classified "
            f"({_fmt(data.get('images_per_s', '?'), 1)} images per CPU second). "
            f"{_timing(data.get('seconds'), data.get('workers'))}"))
    table = b.load(folder / EPISODES_FILE, EpisodeTable.load, how)
    if table is not None:
        rows, paired, points, unpaired = evaluation_summaries(table, folder, seed)
        if unpaired:
            b.add(Paragraph(f"No paired comparison: {unpaired}."))
        b.add(Paragraph(table1_story(rows, paired, points)))
        b.add(Table(*table1_cells(rows, paired)))
        if paired:
            b.add(Paragraph(paired_note(paired)))
        b.add(Paragraph(TABLE1_COLUMNS))
        _held_out_comparison(b, folder)
        b.add(Paragraph("Per class:"), Paragraph(PER_CLASS_NOTE),
              Table(*per_class_cells(per_class(table, table.methods), table.methods)))
    figure = (data or {}).get("figure_class", "the figure class")
    classes = f"the {len(table.classes)} classes" if table is not None else "every class"
    b.figure(folder / FIG3_FILE,
             f"Fig. 3: the mean belief in the true class after each image, per method: left, "
             f"the test models of class {figure}; right, the mean over {classes} (step 0 is "
             f"the start viewpoint; an episode that has declared keeps its final belief).",
             how)
    b.figure(folder / TRAJECTORIES_FILE,
             "The camera's trajectories on the test viewsphere X_rho, per method.", how)
    if (folder / TRADEOFF_FIGURE).exists():
        b.add(Heading("Accuracy against energy"))
        b.figure(folder / TRADEOFF_FIGURE,
                 "Accuracy against mean movement energy: each POMDP method solved at every "
                 "λ of evaluate.lambdas, Random at every stop belief, from the same (test "
                 "model, start) pairs as Table 1 (the points: evaluate/tradeoff.md and .csv).",
                 how)
    return data


HELD_OUT_COMPARISON_NOTE = (
    "What held-out objects say, before any test model is read: every method run on the volume "
    "models, which the classifier never trained on, from the same seeded starts; each group's "
    "views are the labels the classifier gave them, its beliefs (and a POMDP's lookahead) use "
    "the observation models fitted without the group, and a POMDP's plan is the solve "
    "stage's. A forecast "
    "of Table 1's direction, with intervals as wide as the held-out objects are few (how "
    "often it has forecast it on the development sets: docs/experiment.md, \"The held-out "
    "comparison\"). Each fold's models are fitted on one group of volume models fewer than "
    "Table 1's; on the real-CAD development sets it understated the VP-tree against RA-POMDP "
    "(its held-out loop reads its own labels of the volume models), and Random and the "
    "Classifier POMDP by less than their seeds resolve.")


def held_out_comparison_story(record: dict[str, Any]) -> str:
    """One sentence of how the reference method stands against the others held out."""
    reference = record["reference"]
    name = METHOD_NAMES.get(reference, reference)
    paired = record["paired"]
    said = standing_phrases([(METHOD_NAMES.get(m, m), p["difference"], p["low"], p["high"])
                             for m, p in paired.items()])
    if not said:
        why = record.get("skipped", {}).get(reference, "it is not among evaluate.methods")
        return f"{name} has no held-out closed loop to pair the others with: {why}."
    objects = max(p["objects"] for p in paired.values())
    left_out = "".join(f" {METHOD_NAMES.get(m, m)} is not compared: {why}."
                       for m, why in record.get("not_held_out", {}).items())
    return (f"On the {objects} held-out objects, with 95 % intervals that resample them, "
            f"{name} is {'; '.join(said)}.{left_out}")


def held_out_comparison_cells(record: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """The held-out comparison (``held_out/comparison.json``) as a table: per method accuracy,
    mean energy, episodes and the paired difference to the reference."""
    reference = record["reference"]
    header = ["Method", "Held-out accuracy", "Energy (m)",
              f"Δ accuracy vs {METHOD_NAMES.get(reference, reference)} [95 %, held-out objects]",
              "Episodes"]
    rows = []
    for name in record.get("order", record["methods"]):
        row, p = record["methods"][name], record["paired"].get(name)
        delta = ("—" if name == reference else "not paired" if p is None else
                 f"{p['difference']:+.3f} [{p['low']:+.3f}, {p['high']:+.3f}]")
        rows.append([METHOD_NAMES.get(name, name), f"{row['accuracy']:.3f}",
                     f"{row['energy_m']:.2f}", delta, str(row["episodes"])])
    return header, rows


def _held_out_comparison(b: Builder, folder: Path) -> None:
    """Table 1's methods on the held-out objects (the evaluate stage's comparison)."""
    record = load_held_out_comparison(folder)
    if record is None or not record["methods"]:
        return
    b.add(Paragraph(held_out_comparison_story(record) + " " + HELD_OUT_COMPARISON_NOTE))
    b.add(Table(*held_out_comparison_cells(record)))


def _learned(b: Builder, folder: Path | None, cmd: str) -> None:
    """The learned baseline's training (time, curves) and its held-out scores beside Random's,
    when the learn stage trained it (``evaluate.methods`` lists ``learned``; it changes only
    with the evaluate stage, an input, so the folder is read beside it like the VP-tree's)."""
    if folder is None or not (folder / LEARN_SUMMARY).is_file():
        return
    how = f"made by `{cmd} learn -w {b.root}` (with learned in evaluate.methods)"
    data = b.json(folder / LEARN_SUMMARY, how)
    if not data or not data.get("trained"):
        return
    b.add(Heading("Learned baseline (MaskablePPO)"))
    try:
        seconds, evidence = data["seconds"], data["evidence"]
        b.add(Paragraph(
            f"One policy per λ ({', '.join(f'{v:g}' for v in data['lambdas'])} m), each "
            f"trained for {data['timesteps']:,} environment steps on the recorded evidence of "
            f"{evidence['models']} held-out volume models (no test model), its belief Eq. 5 "
            f"with the "
            f"'{data['observation_model']}' observation model. Training took "
            f"{seconds['train_wall']:.0f} s of wall time ({seconds['train_cpu']:.0f} s of CPU "
            f"over {data['workers']} process(es)); recording the evidence "
            f"{seconds['record']:.0f} s."))
        rows = [[METHOD_NAMES.get(r["method"], r["method"]),
                 f"{r['parameter']} = {r['value']:g}", _fmt(r["accuracy"]),
                 _fmt(r["mean_energy"]), _fmt(r["mean_moves"], 2), _fmt(r["episodes"])]
                for r in data["held_out"]]
    except (KeyError, TypeError, ValueError) as exc:
        b.missing(f"learn/{LEARN_SUMMARY} lacks {exc}", how)
        return
    b.add(Paragraph("On the held-out models themselves (every reachable start; in-sample for "
                    "the learned policy, which trained on them):"),
          Table(["method", "setting", "accuracy", "energy (m)", "moves", "episodes"], rows))
    b.figure(folder / CURVES_FIGURE,
             "Training curves of the learned baseline: mean return, accuracy and energy of "
             "the training episodes that ended in each PPO update, one line per λ.", how)


def _classifier(b: Builder, inputs: StageInputs, cmd: str) -> None:
    b.add(Heading("Single-view classifier"))
    how = f"made by `{cmd} classifier_eval -w {b.root}`"
    metrics = b.load(inputs.classifier_eval / METRICS_FILE,
                     lambda p: load_single_view_metrics(p.parent), how)
    if metrics is not None:
        rows = [[label, _fmt(part.images), _fmt(part.accuracy), _fmt(part.chance)]
                for part, label in ((metrics.xrho, "test viewpoints X_rho"),
                                    (metrics.sphere, "whole sphere"))]
        b.add(Table(["test views", "images", "accuracy", "chance"], rows))
    b.figure(inputs.classifier_eval / confusion_file("xrho", "png"),
             "Single-view confusion of the classifier on the test models over X_rho.", how)
    b.figure(inputs.classifier_eval / HEMISPHERE_FIGURE,
             "Single-view accuracy and mean probability of the true class per test viewpoint.",
             how)
    b.figure(inputs.train / TRAINING_FIGURE,
             "Training curves: loss and accuracy per epoch.",
             f"made by `{cmd} train -w {b.root}`")
    vptree = b.root / "vptree" / VPTREE_SUMMARY_FILE
    how = f"made by `{cmd} vptree -w {b.root}` (the VP-tree baseline)"
    if vptree.is_file():
        data = b.load(vptree, lambda p: load_vptree_summary(p.parent), how)
        if data is not None:
            accuracy = "?" if data.accuracy_test_xrho is None else data.accuracy_test_xrho
            b.add(Paragraph(f"VP-tree baseline (vocabulary tree), single-view accuracy on the "
                            f"test models over X_rho: {_fmt(accuracy)}."))
    else:
        b.missing(f"VP-tree baseline accuracy (vptree/{VPTREE_SUMMARY_FILE} not found)", how)


def _robot_and_solver(b: Builder, config: Config, inputs: StageInputs, cmd: str
                      ) -> None:
    b.add(Heading("Robot and planner"))
    how = f"made by `{cmd} robot -w {b.root}`"
    summary = b.json(inputs.robot / ROBOT_SUMMARY, how)
    if summary is not None:
        try:
            b.add(Paragraph(f"Panda arm: {describe(summary)}."))
        except (KeyError, TypeError) as exc:
            b.missing(f"robot/{ROBOT_SUMMARY} lacks {exc}", how)
    b.figure(inputs.robot / ROBOT_FIGURE,
             "The Panda's reachability of the test viewpoints, coloured by manipulability, with "
             "the arm drawn at a few of its solutions.", how)
    how = f"made by `{cmd} solve -w {b.root}`"
    bounds = b.json(inputs.solve / SOLVE_SUMMARY, how)
    if bounds is not None:
        solved = {str(name): v for name, v in bounds.items() if isinstance(v, dict)}
        rows = [[name, _fmt(v.get("lower", "-"), 4), _fmt(v.get("upper", "-"), 4),
                 _gap(v), _fmt(v.get("seconds", "-"), 1), _fmt(v.get("vectors", "-"))]
                for name, v in solved.items()]
        b.add(Paragraph("The solver's bounds on the value of the start belief, per observation "
                        "model (values are negative costs, metres of energy):"),
              Table(["observation model", "lower", "upper", "gap", "seconds", "alpha vectors"],
                    rows),
              Paragraph(solver_gap_note(solved, config.solve, _mean_energies(inputs))))


def _gap(row: dict[str, Any]) -> str:
    lower, upper = row.get("lower"), row.get("upper")
    if isinstance(lower, int | float) and isinstance(upper, int | float):
        return f"{max(upper - lower, 0.0):.4f}"  # bounds equal up to rounding: 0, not -0
    return "-"


def _mean_energies(inputs: StageInputs) -> dict[str, float]:
    """Each method's mean movement energy per episode in Table 1's episodes (none without
    them)."""
    episodes = inputs.evaluate / EPISODES_FILE
    if not episodes.is_file():
        return {}
    try:
        table = EpisodeTable.load(episodes)
    except (ArtefactError, KeyError, ValueError):
        return {}
    return {m: float(table.energy[table.method == m].mean()) for m in table.methods}


def solver_gap_note(solved: dict[str, dict[str, Any]], solve: Any,
                    energies: dict[str, float]) -> str:
    """What the solver's gap (upper − lower bound at the start belief) means for each policy:
    the lower bound is the expected discounted value of the policy the solver returned, the
    upper bound one no policy exceeds, so the policy is at most the gap worse than optimal —
    for the observation model it was solved on — in metres, set against a wrong declaration's
    cost λ and the method's mean episode energy in Table 1 (``energies``, by method: the
    observation model's name). ``solve`` is the configuration's solve section."""
    lam, discount = float(solve.wrong_declaration_cost_m), float(solve.discount)
    parts, converged = [], []
    for name, row in solved.items():
        lower, upper = row.get("lower"), row.get("upper")
        if not (isinstance(lower, int | float) and isinstance(upper, int | float)):
            continue
        gap = max(upper - lower, 0.0)
        if row.get("converged") or gap <= solve.precision:
            converged.append(f"`{name}`")
            continue
        stop = ("stopped at the CPU-time limit (solve.timeout_s)" if row.get("timed_out")
                else f"stopped at the iteration budget (solve.iterations: "
                     f"{row.get('iterations', solve.iterations)})")
        energy = energies.get(name)
        against = (f"; its mean episode energy in Table 1 is {energy:.2f} m, so the gap is "
                   f"{gap / energy:.2g} times what an episode spends moving"
                   if energy is not None and energy > 0 else "")
        parts.append(f"`{name}`: {stop} with a gap of {gap:.2f} m: its policy may cost up to "
                     f"{gap:.2f} m more per episode than an optimal one, as much as "
                     f"{gap / lam:.2g} wrong declaration(s) at λ = {lam:g} m{against}")
    if converged:
        parts.insert(0, f"{', '.join(converged)}: converged (gap within the precision "
                        f"{solve.precision:g} m), so each policy is optimal to that amount")
    if not parts:
        return ""
    return ("What the gap means: the lower bound is the expected discounted (γ = "
            f"{discount:g}) value, from the start belief, of the policy the solver returned; "
            "no policy is worth more than the upper bound. A policy is therefore at most its "
            "gap worse than optimal — optimal for the observation model it was solved on; how "
            "it does on the test models is Table 1's — and the bound does not say how much of "
            "the gap is the policy's and how much the upper bound's looseness. "
            + "; ".join(parts) + ".")


def write_report(config: Config, inputs: StageInputs, out: Path,
                 fig1: Callable[..., tuple[Path, Path]] | None = None,
                 command: str = "rapomdp") -> tuple[Path, Path]:
    """Write ``report.md`` and ``report.html`` (and the figures) into ``out``.

    ``inputs`` holds the folder of each of :data:`REPORT_INPUTS` in one workspace; a missing
    one raises :class:`StageError` naming it. ``fig1`` makes Fig. 1 (default
    :func:`~rapomdp.awareness.report.write_fig1`). Returns (html, markdown) paths.
    """
    given = inputs.given()
    missing = [name for name in REPORT_INPUTS if name not in given or not given[name].is_dir()]
    if missing:
        raise StageError(f"report: needs the stage(s) {', '.join(missing)}, which have not "
                         f"run; run `{command} {missing[0]} -w WORKSPACE` first")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    root = inputs.dataset.parent
    classes = load_dataset(inputs.dataset).classes
    b = Builder(root, out)
    title = f"rapomdp report: {root.name}"
    b.add(Heading(title, 1))
    _provenance(b, config, {name: given[name] for name in REPORT_INPUTS})
    b.add(Paragraph(f"Classes ({len(classes)}): {', '.join(classes)}."))
    evaluation = _evaluation(b, inputs.evaluate, command, config.seed)
    _learned(b, inputs.learn_dir or root / "learn", command)
    awareness_section(b, config, inputs, figure_class(evaluation, config, classes),
                      fig1 or write_fig1, command)
    _classifier(b, inputs, command)
    _robot_and_solver(b, config, inputs, command)
    md = write_text_atomic(out / REPORT_MD, to_markdown(b.blocks))
    page = write_text_atomic(out / REPORT_HTML, to_html(b.blocks, title))
    return page, md


def run_report_stage(config: Config, inputs: StageInputs, out: Path,
                     context: RunContext) -> None:
    """The pipeline stage: the report of the workspace the inputs belong to.

    Args:
        config: the run's configuration; the stage reads every section, to say how the run
            was made.
        inputs: the folders of the stages it reads (every earlier stage).
        out: the stage's temporary folder; the workspace swaps it in when the stage finishes.
        context: worker processes, threads and progress bars (no artefact depends on them).

    Returns:
        None. Writes into ``out``: ``report.md`` and ``report.html`` and their figures (PNG) and
            tables (CSV).
    """
    del context  # one process, no long loops
    write_report(config, inputs, out)
