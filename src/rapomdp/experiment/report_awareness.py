"""The report's self-awareness section: Figs. 1 and 2, RA-POMDP's observation model and the
held-out validation that chose it, the observation models' quality table, the calibration and
reliability figures, and the declared confidence (held-out walks and closed loop).

:func:`awareness_section` adds it to the report :mod:`rapomdp.experiment.report` gathers.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from rapomdp.awareness.artefacts import (
    CALIBRATION_FIGURE,
    CALIBRATION_FILE,
    OBSERVATION_FILE,
    QUALITY_CSV,
    VALIDATION_CSV,
    RAChoice,
    load_quality,
    load_ra_choice,
)
from rapomdp.awareness.figures import RELIABILITY_MIN_COUNT, calibration_caption
from rapomdp.awareness.quality import quality_cells
from rapomdp.awareness.report import FIGURES_DIR, declared_confidence_cells, floor_cell
from rapomdp.config import METHOD_NAMES, Config
from rapomdp.document import Builder, Heading, Image, Link, Paragraph, Table
from rapomdp.experiment.episode_table import EPISODES_FILE, EpisodeTable
from rapomdp.experiment.held_out import load_declared_fit
from rapomdp.experiment.metrics import (
    CALIBRATED_ECE_NOTE,
    REPORTED_BELIEF_NOTE,
    belief_calibration_cells,
)
from rapomdp.experiment.sections import LEARNED
from rapomdp.io import ArtefactError, load_npz
from rapomdp.workspace import StageError, StageInputs, Workspace

BELIEF_RELIABILITY_FIGURE = "belief_reliability.png"


def awareness_section(b: Builder, config: Config, inputs: StageInputs, class_name: str,
                      fig1: Callable[..., tuple[Path, Path]], cmd: str) -> None:
    """The report's "Recognition self-awareness" section, added to ``b``.

    Args:
        b: The report being gathered.
        config: The run's configuration.
        inputs: The report stage's input folders.
        class_name: The class of Fig. 1 (the report's figure class).
        fig1: Makes Fig. 1: ``fig1(workspace, class_name, out_dir=...)`` gives (png, html).
        cmd: The command line's name, in the lines saying how to make what is missing.
    """
    b.add(Heading("Recognition self-awareness"))
    ws = Workspace(b.root)
    fig1_how = f"made by `{cmd} figure fig1 -w {b.root} --class {class_name}`"
    try:
        png, page = fig1(ws, class_name, out_dir=b.out)
    except (StageError, ArtefactError) as exc:
        b.missing(f"Fig. 1 for class {class_name} could not be made ({exc})", fig1_how)
    else:
        b.figure(png, f"Fig. 1, class {class_name}: (a) a depth view of its volume model, "
                      f"(b) the 2D saliency of that view, (c) the 3D dense saliency volume, "
                      f"(d) the normalised viewpoint scores on X_rho.", fig1_how, png.name)
        b.interactive(page, "Fig. 1")
    fig2 = b.root / FIGURES_DIR / "fig2.png"
    fig2_how = (f"`{cmd} figure fig2 -w {b.root}` or `{cmd} report --fig2 -w {b.root}` makes "
                f"it (it trains three two-class classifiers, so the report does not by default)")
    if fig2.is_file():
        b.figure(fig2, "Fig. 2: one class's saliency volume in two-class problems and in the "
                       "all-class problem, all seen from one camera.", fig2_how)
        b.interactive(fig2.with_suffix(".html"), "Fig. 2")
    else:  # optional: not asked for, so not a missing figure
        b.add(Paragraph(f"Fig. 2 (one class's saliency volume in two-class problems) is "
                        f"optional: {fig2_how}."))
    observe_how = f"made by `{cmd} observe -w {b.root}`"
    choice = _ra_choice(b, inputs.observe, observe_how)
    b.add(Paragraph("How well each observation model predicts the classifier's correctness on "
                    "the test models over X_rho (single view, before the belief's "
                    "temperature):"))
    quality = b.load(inputs.observe / QUALITY_CSV, lambda p: load_quality(p.parent),
                     observe_how)
    if quality is not None:
        b.add(Table(*quality_cells(quality)))
        note = _identical_rows(inputs.observe, choice)
        if note:
            b.add(Paragraph(note))
    b.figure(inputs.observe / CALIBRATION_FIGURE,
             calibration_caption(choice.variant, choice.method) if choice is not None else
             "Calibration: the classifier's accuracy per viewpoint-score bin on the held-out "
             "evidence (which RA variant is RA-POMDP's model could not be read).",
             observe_how)
    _self_awareness(b, inputs, class_name, observe_how)


def _ra_choice(b: Builder, observe: Path, how: str) -> RAChoice | None:
    """Which RA variant RA-POMDP's model is and what chose it: the held-out validation table
    (the chosen row marked), or why there is none."""
    choice = b.load(observe / CALIBRATION_FILE, lambda p: load_ra_choice(p.parent), how)
    if choice is None:
        return None
    validation = (b.load(observe / VALIDATION_CSV,
                         lambda p: load_quality(p.parent, VALIDATION_CSV), how)
                  if (observe / VALIDATION_CSV).exists() else None)
    if choice.configured == "mixture" and choice.weights:
        weights = ", ".join(f"`{name}` {w:.2f}" for name, w in
                            sorted(choice.weights.items(), key=lambda kv: -kv[1]) if w >= 0.005)
        why = ("the RA variants averaged with weights fitted on the held-out labels "
               f"(`observe.ra_model: mixture`, the default; each held-out object scored by the "
               f"variants fitted without its group, the test models play no part): {weights}")
    elif choice.configured == "mixture":
        why = (f"the fallback of `observe.ra_model: mixture` ({choice.rule}): {choice.reason}")
    else:
        why = (f"as configured (`observe.ra_model: {choice.configured}`)"
               + ("; the held-out validation below shows how the variants compare"
                  if validation else ""))
    b.add(Paragraph(f"RA-POMDP's observation model (`ra`) is `{choice.model}`, {why}. The row "
                    f"`ra` in the tables is that variant itself."))
    if validation:
        header, rows = quality_cells(validation)
        header = [*header[:-1], "held-out accuracy"]  # the accuracy of these groups' outcomes
        rows = [[f"{row[0]} (chosen)" if row[0] == choice.model else row[0], *row[1:]]
                for row in rows]
        b.add(Paragraph("Held-out validation (the groups of held-out evidence, each scored by "
                        "the models fitted without it):"), Table(header, rows))
    return choice


def _identical_rows(observe: Path, choice: RAChoice | None) -> str:
    """Which rows of the quality tables are equal because their models are, and why."""
    from rapomdp.awareness.report import identical_models

    try:
        groups = identical_models(load_npz(observe / OBSERVATION_FILE))
    except (ArtefactError, KeyError, ValueError):
        return ""
    parts = []
    for group in groups:
        if choice is not None and {"ra", choice.model} <= set(group):
            others = [f"`{n}`" for n in group if n not in ("ra", choice.model)]
            parts.append(f"`ra` and `{choice.model}` are one model (`ra` is the chosen "
                         f"variant), so their rows are equal by construction"
                         + (f"; {', '.join(others)} coincide with it on this evidence"
                            if others else ""))
        else:
            names = " and ".join(f"`{n}`" for n in group)
            parts.append(f"{names} give the same P(o | c, x) at every viewpoint on this "
                         f"evidence (their fits coincide), so their rows are equal")
    return ("Equal rows: " + "; ".join(parts) + ".") if parts else ""


def _self_awareness(b: Builder, inputs: StageInputs, class_name: str, how: str) -> None:
    """Predicted vs observed P(correct), one class's hemispheres and the calibration of every
    method's final belief."""
    from rapomdp.awareness.report import AWARENESS_RELIABILITY, write_awareness_figures

    observe = inputs.observe
    try:
        rel, hemi = write_awareness_figures(observe, class_name, b.out)
    except (StageError, ArtefactError, KeyError) as exc:
        b.missing(f"the self-awareness figures could not be made ({exc})", how)
    else:
        b.figure(rel, "Predicted against observed P(correct) on the test models, per "
                      "observation model (single view, before the belief's temperature; "
                      "marker area and the bars below: (test model, viewpoint) pairs per "
                      "bin).", how, rel.name)
        b.add(Link("Its bins and counts:", f"{AWARENESS_RELIABILITY}.csv",
                   f"{AWARENESS_RELIABILITY}.csv"))
        b.figure(hemi, f"Class {class_name}: predicted P(correct) per viewpoint (RA, "
                       f"Classifier) beside the test models' actual accuracy.", how, hemi.name)
    episodes = inputs.evaluate / EPISODES_FILE
    if episodes.exists():
        _belief_calibration(b, EpisodeTable.load(episodes), inputs.evaluate)
    vptree = b.root / "vptree"  # not an input of the report stage (as the VP-tree summary)
    header, rows = declared_confidence_cells(observe, vptree if vptree.is_dir() else None)
    if rows:
        b.add(Paragraph("The declared confidence, fitted on held-out random walks stopped at "
                        "belief thresholds 0.5 to 0.99: per model, a and, at those stops, the "
                        "belief's and the declared belief's confidence and ECE, each held-out "
                        "group scored by the a the other groups give (docs/awareness.md)."))
        b.add(Table(header, rows))
    record = load_declared_fit(inputs.evaluate)
    if record is not None and record["methods"]:
        whose = ("The POMDP methods' and the learned baseline's" if LEARNED in record["methods"]
                 else "The POMDP methods'")
        b.add(Paragraph(
            f"{whose} declared confidence, fitted at "
            f"their own held-out closed-loop stops: "
            f"each volume group's models run from {record['starts_per_model']} starts, the "
            "belief (and a POMDP's lookahead) by the model fitted without the group, a POMDP "
            f"by the solve stage's plan, λ = {record['lambda_m']:g} m; per "
            "method a, the loop's accuracy and energy, and at its stops the belief's and the "
            "declared belief's confidence and ECE (each group by the a the other groups "
            "give). These a are the ones the methods above reported with."))
        b.add(Table(*closed_loop_cells(record)))


def closed_loop_cells(record: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """The held-out closed loop's record (``held_out/declared_fit.json``) as a table: per
    POMDP method a, the loop's accuracy and mean energy, the belief's and the declared
    belief's (held out) confidence and ECE at its stops, and the stops."""
    header = ["Method", "a", "Accuracy", "Energy (m)",
              "Belief: confidence", "ECE", "Declared (held out): confidence", "ECE",
              "ECE if calibrated (95 %)", "Stops"]
    rows = []
    for name, fit in record["methods"].items():
        d = fit["declared_confidence"]
        rows.append([METHOD_NAMES.get(name, name), f"{d['temperature']:.3f}",
                     f"{fit['accuracy']:.3f}", f"{fit['energy']:.2f}",
                     f"{d['confidence']:.3f}", f"{d['ece']:.3f}",
                     f"{d['declared_confidence']:.3f}", f"{d['declared_ece']:.3f}",
                     floor_cell(d),
                     str(fit["episodes"])])
    return header, rows


def _belief_calibration(b: Builder, table: EpisodeTable, evaluate: Path) -> None:
    """Every method's final belief against its accuracy (:func:`belief_calibration_cells`) and
    the reliability of its confidence."""
    from rapomdp.awareness.figures import reliability_figure
    from rapomdp.awareness.report import write_reliability_csv
    from rapomdp.experiment.figures import method_style

    curves = belief_reliability(table)
    styles = {METHOD_NAMES.get(m, m): method_style(m, i)[::2]
              for i, m in enumerate(table.methods)}
    b.add(Paragraph("Calibration of every method's final belief in the closed loop on the test "
                    "models: the mean belief in the true class; the confidence (the belief in "
                    "the declared class), which a calibrated belief's accuracy equals; ECE of "
                    "the confidence over 10 equal-width bins. "
                    + REPORTED_BELIEF_NOTE + " " + CALIBRATED_ECE_NOTE))
    b.add(Table(*belief_calibration_cells(table)))
    figure = reliability_figure(curves, b.out / BELIEF_RELIABILITY_FIGURE,
                                xlabel="final belief in the declared class",
                                title="Final beliefs on the test models (10 bins)",
                                styles=styles)
    data = write_reliability_csv(curves, figure.with_suffix(".csv"))
    b.add(Image(figure.name, "Reliability of every method's final belief: accuracy against "
                             "confidence (belief in the declared class), from "
                             f"{b.shown(evaluate / EPISODES_FILE)}; marker area and the bars "
                             "below: episodes per bin (legend: episodes in all), bins of "
                             f"fewer than {RELIABILITY_MIN_COUNT} episodes hollow and off the "
                             "line."),
          Link("Its bins and counts:", data.name, data.name))


def belief_reliability(table: EpisodeTable, bins: int = 10
                       ) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Every method's final confidence (the belief in the declared class) against its
    accuracy, per equal-width bin: (mean confidence, accuracy, episodes), by display name (the
    reliability figure's and ``belief_reliability.csv``'s data)."""
    from rapomdp.recognition.belief import reliability

    confidence = table.final_confidence()
    return {METHOD_NAMES.get(m, m): reliability(confidence[table.method == m],
                                                table.correct[table.method == m], bins)
            for m in table.methods}

