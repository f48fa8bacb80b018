"""Table 1 of the paper from scored episodes: means with 95 % confidence intervals.

Accuracy is a proportion: its interval is Wilson's score interval (it stays inside [0, 1] and
behaves at 0 % and 100 %). Belief, steps, distance and energy are means with Student's t
interval, mean ± t(0.975, n − 1)·s/√n. These per-method intervals treat the episodes as
independent draws. Episodes of one test model are not independent, and every method runs from
the same (test model, start) pairs, so methods are compared by the *paired* accuracy
difference with a cluster bootstrap interval that resamples test models
(:func:`paired_accuracy_difference`).
"""

from __future__ import annotations

import csv
import io
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy import stats

from rapomdp.config import METHOD_NAMES
from rapomdp.document import markdown_table

if TYPE_CHECKING:
    from rapomdp.experiment.episode_table import EpisodeTable

QUANTITIES = ("belief", "moves", "distance_m", "energy")


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson's score interval of a proportion (SciPy's): exactly 0 and 1 at 0 % and 100 %
    (a closed form lands ~1e-16 past them), always holding the proportion; NaN when ``n`` is 0."""
    if n == 0:
        return float("nan"), float("nan")
    ci = stats.binomtest(int(successes), int(n)).proportion_ci(confidence, method="wilson")
    p = successes / n
    return float(min(ci.low, p)), float(max(ci.high, p))


def mean_interval(values: np.ndarray) -> tuple[float, float]:
    """Mean and the half-width of its 95 % Student's t interval (0 for one value)."""
    values = np.asarray(values, dtype=np.float64)
    n = values.size
    if n == 0:
        return float("nan"), float("nan")
    if n == 1:
        return float(values[0]), 0.0
    half = stats.t.ppf(0.975, n - 1) * values.std(ddof=1) / np.sqrt(n)
    return float(values.mean()), float(half)


@dataclass(frozen=True)
class MethodSummary:
    """One row of Table 1."""

    method: str
    episodes: int
    accuracy: float
    accuracy_low: float
    accuracy_high: float
    means: dict[str, float]
    halfwidths: dict[str, float]
    exhausted: int

    @property
    def moves_at_all(self) -> bool:
        return self.means["moves"] > 0


def summarise(correct: np.ndarray, belief: np.ndarray, moves: np.ndarray,
              distance_m: np.ndarray, energy: np.ndarray, exhausted: np.ndarray,
              method: str) -> MethodSummary:
    """A Table 1 row from one method's episodes."""
    n = int(np.asarray(correct).size)
    low, high = wilson_interval(int(np.sum(correct)), n)
    columns = {"belief": belief, "moves": moves, "distance_m": distance_m, "energy": energy}
    stats_ = {k: mean_interval(v) for k, v in columns.items()}
    return MethodSummary(method, n, float(np.mean(correct)) if n else float("nan"), low, high,
                         {k: v[0] for k, v in stats_.items()},
                         {k: v[1] for k, v in stats_.items()}, int(np.sum(exhausted)))


def table1(table: EpisodeTable, methods: Sequence[str]) -> list[MethodSummary]:
    """Table 1: one row per method over every episode."""
    rows = []
    for key in methods:
        sel = table.method == key
        rows.append(summarise(table.correct[sel], table.belief[sel], table.moves[sel],
                              table.distance_m[sel], table.energy[sel], table.exhausted[sel],
                              key))
    return rows


def per_class(table: EpisodeTable, methods: Sequence[str]) -> list[tuple[str, MethodSummary]]:
    """(class name, row) for every class and method."""
    out = []
    for c, name in enumerate(table.classes):
        for key in methods:
            sel = (table.method == key) & (table.class_index == c)
            if sel.any():
                out.append((name, summarise(table.correct[sel], table.belief[sel],
                                            table.moves[sel], table.distance_m[sel],
                                            table.energy[sel], table.exhausted[sel], key)))
    return out


@dataclass(frozen=True)
class PairedDifference:
    """Accuracy of ``method`` minus that of ``reference`` over the same (model, start) pairs,
    with a 95 % cluster-bootstrap interval over test models."""

    method: str
    reference: str
    difference: float
    low: float
    high: float
    pairs: int
    models: int


def cluster_bootstrap_difference(per_model_sum: np.ndarray, per_model_pairs: np.ndarray,
                                 resamples: int = 10_000, seed: int = 0,
                                 level: float = 0.95) -> tuple[float, float, float]:
    """Ratio estimate sum(d) / sum(n) and its percentile interval from resampling clusters.

    ``per_model_sum`` (M,) is each model's summed paired difference, ``per_model_pairs`` (M,)
    its number of pairs; each resample draws M models with replacement (as multinomial counts).
    """
    d = np.asarray(per_model_sum, dtype=np.float64)
    n = np.asarray(per_model_pairs, dtype=np.float64)
    if d.shape != n.shape or d.ndim != 1 or d.size == 0 or np.any(n <= 0):
        raise ValueError("need one positive pair count per model and at least one model")
    estimate = float(d.sum() / n.sum())
    counts = np.random.default_rng(seed).multinomial(d.size, np.full(d.size, 1.0 / d.size),
                                                     size=resamples)
    draws = (counts @ d) / (counts @ n)
    tail = (1.0 - level) / 2.0 * 100.0
    low, high = np.percentile(draws, [tail, 100.0 - tail])
    return estimate, float(low), float(high)


def paired_cluster_sums(pairs: np.ndarray, correct: np.ndarray, clusters: np.ndarray,
                        reference_pairs: np.ndarray, reference_correct: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each cluster's summed paired accuracy difference (a method's ``correct`` minus the
    reference's, matched by their ``pairs`` keys, in any order) and its number of pairs:
    ``(clusters, sums, pairs)``, clusters sorted. ``clusters`` names each of the method's
    episodes' cluster (the object it ran on). A ValueError where the two sets of keys differ
    or a key repeats."""
    order, reference_order = (np.argsort(pairs, kind="stable"),
                              np.argsort(reference_pairs, kind="stable"))
    if pairs.shape != reference_pairs.shape \
            or np.any(pairs[order] != reference_pairs[reference_order]) \
            or np.unique(pairs).size != pairs.size:
        raise ValueError("not the same pairs")
    diff = (np.asarray(correct)[order].astype(np.float64)
            - np.asarray(reference_correct)[reference_order].astype(np.float64))
    names, cluster = np.unique(np.asarray(clusters)[order], return_inverse=True)
    sums = np.bincount(cluster, weights=diff, minlength=names.size)
    sizes = np.bincount(cluster, minlength=names.size).astype(np.float64)
    return names, sums, sizes


def paired_model_sums(table: EpisodeTable, method: str, reference: str,
                      reference_table: EpisodeTable | None = None,
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each test model's summed paired accuracy difference ``method`` − ``reference`` and its
    number of (model, start) pairs: ``(models, sums, pairs)``, models sorted.

    Both methods must have run from exactly the same pairs (the evaluation guarantees it; a
    table that breaks it is an error). ``reference_table``: the reference's episodes come from
    another table of the same pairs (another configuration of the same seed).
    """
    other = table if reference_table is None else reference_table
    sides = ((method, table), (reference, other))  # by position: the names may be the same
    rows = []
    for key, source in sides:
        sel = np.flatnonzero(source.method == key)
        if sel.size == 0:
            raise ValueError(f"no episodes of method '{key}'")
        rows.append(sel)
    keys = [np.char.add(np.char.add(source.model[sel].astype(str), "#"),
                        source.start[sel].astype(str))
            for (_, source), sel in zip(sides, rows, strict=True)]
    try:
        return paired_cluster_sums(keys[0], table.correct[rows[0]], table.model[rows[0]],
                                   keys[1], other.correct[rows[1]])
    except ValueError:
        raise ValueError(f"methods '{method}' and '{reference}' did not run from the same "
                         "(test model, start) pairs") from None


def paired_accuracy_difference(table: EpisodeTable, method: str, reference: str,
                               resamples: int = 10_000, seed: int = 0) -> PairedDifference:
    """``method``'s accuracy minus ``reference``'s over their common (test model, start) pairs
    (:func:`paired_model_sums`); the interval resamples test models, keeping each model's
    episodes together."""
    models, sums, sizes = paired_model_sums(table, method, reference)
    estimate, low, high = cluster_bootstrap_difference(sums, sizes, resamples, seed)
    return PairedDifference(method, reference, estimate, low, high, int(sizes.sum()),
                            int(models.size))


def paired_against(table: EpisodeTable, methods: Sequence[str], reference: str = "ra",
                   resamples: int = 10_000, seed: int = 0) -> dict[str, PairedDifference]:
    """Every other method's paired difference to ``reference`` (empty when it did not run)."""
    if reference not in methods:
        return {}
    return {m: paired_accuracy_difference(table, m, reference, resamples, seed)
            for m in methods if m != reference}


def paired_csv(paired: dict[str, PairedDifference]) -> str:
    """The paired differences as CSV (one row per method)."""
    lines = ["method,reference,accuracy_difference,ci95_low,ci95_high,pairs,test_models"]
    lines += [f"{p.method},{p.reference},{p.difference:.6g},{p.low:.6g},{p.high:.6g},"
              f"{p.pairs},{p.models}" for p in paired.values()]
    return "\n".join(lines) + "\n"


def _pm(mean: float, half: float, digits: int = 3) -> str:
    return f"{mean:.{digits}f} ± {half:.{digits}f}"


TABLE1_HEADER = ["Method", "Accuracy [95 % CI]", "Belief", "# steps", "Distance (m)",
                 "Energy (m)", "Episodes"]
#: What the per-class table's cells hold.
PER_CLASS_NOTE = "Accuracy per class (mean final belief in the true class in brackets)."


def table1_cells(rows: Sequence[MethodSummary],
                 paired: dict[str, PairedDifference] | None = None
                 ) -> tuple[list[str], list[list[str]]]:
    """Table 1's header and cells: mean (95 % interval) per method; — where a method never
    moves. With ``paired``, a column of each method's paired accuracy difference to the
    reference (its cluster-bootstrap interval over test models). The markdown file and the
    report both show these."""
    reference = next(iter(paired.values())).reference if paired else None
    header = list(TABLE1_HEADER)
    if reference is not None:
        header.insert(-1, f"Δ accuracy vs {METHOD_NAMES.get(reference, reference)} [95 % CI]")
    cells = []
    for r in rows:
        move_cells = ([_pm(r.means[k], r.halfwidths[k]) for k in QUANTITIES[1:]]
                      if r.moves_at_all else ["—"] * 3)
        budget = f" ({r.exhausted} hit the step budget)" if r.exhausted else ""
        row = [METHOD_NAMES.get(r.method, r.method),
               f"{r.accuracy:.3f} [{r.accuracy_low:.3f}, {r.accuracy_high:.3f}]",
               _pm(r.means["belief"], r.halfwidths["belief"]), *move_cells]
        if reference is not None:
            p = (paired or {}).get(r.method)
            row.append("—" if p is None else f"{p.difference:+.3f} [{p.low:+.3f}, {p.high:+.3f}]")
        cells.append([*row, f"{r.episodes}{budget}"])
    return header, cells


def paired_note(paired: dict[str, PairedDifference]) -> str:
    """What Table 1's Δ column means (the pairs and the test models resampled)."""
    p = next(iter(paired.values()))
    name = METHOD_NAMES.get(p.reference, p.reference)
    return (f"Δ: a method's accuracy minus {name}'s over the same {p.pairs} (test model, start) "
            f"pairs; 95 % cluster-bootstrap interval resampling the {p.models} test models.")


def table1_markdown(rows: Sequence[MethodSummary],
                    paired: dict[str, PairedDifference] | None = None) -> str:
    """Table 1 as markdown (:func:`table1_cells`), with the Δ column's note under it."""
    out = markdown_table(*table1_cells(rows, paired))
    return out + f"\n{paired_note(paired)}\n" if paired else out


CALIBRATED_ECE_NOTE = ("ECE if calibrated: the 95th percentile of the ECE a reporter calibrated "
                       "by construction shows at the same confidences on as many stops (each "
                       "outcome drawn as a coin of its confidence); an ECE below it is not "
                       "evidence of miscalibration.")
"""What the calibration tables' last ECE column is, for the text beside them."""

BELIEF_CALIBRATION_HEADER = ["Method", "Accuracy", "Belief in the true class", "Confidence",
                             "Confidence − accuracy", "ECE", "ECE if calibrated (95 %)"]


REPORTED_BELIEF_NOTE = (
    "Random, the POMDP methods and the learned baseline report their belief raised to a "
    "declared-confidence temperature (Random's fitted where held-out walks reach its stop "
    "belief, the others' where their own held-out closed loop stops; their actions are the "
    "belief's), Static the classifier's softmax at its held-out temperature.")
"""What the methods' final beliefs in the calibration tables are, for the text beside them."""


def belief_calibration_cells(table: EpisodeTable) -> tuple[list[str], list[list[str]]]:
    """Every method's final belief against its accuracy: the mean belief in the true class, the
    mean confidence (the belief in the declared class, which a calibrated belief's accuracy
    equals), their difference, the confidence's ECE (10 equal-width bins) and the ECE that
    sampling alone gives a calibrated reporter of the same confidences, 95th percentile
    (:func:`~rapomdp.recognition.belief.calibrated_ece`)."""
    from rapomdp.recognition.belief import calibrated_ece, expected_calibration_error

    confidence = table.final_confidence()
    cells = []
    for method in table.methods:
        mine = table.method == method
        right = table.correct[mine].astype(float)
        cells.append([METHOD_NAMES.get(method, method), f"{right.mean():.3f}",
                      f"{table.belief[mine].mean():.3f}", f"{confidence[mine].mean():.3f}",
                      f"{confidence[mine].mean() - right.mean():+.3f}",
                      f"{expected_calibration_error(confidence[mine], right):.3f}",
                      f"{calibrated_ece(confidence[mine]):.3f}"])
    return list(BELIEF_CALIBRATION_HEADER), cells


def per_class_cells(rows: Sequence[tuple[str, MethodSummary]],
                    methods: Sequence[str]) -> tuple[list[str], list[list[str]]]:
    """The per-class table's header and cells: accuracy (mean final belief) per class and
    method."""
    classes = list(dict.fromkeys(name for name, _ in rows))
    cell = {(name, r.method): r for name, r in rows}
    header = ["Class", *(METHOD_NAMES.get(m, m) for m in methods)]
    body = [[name, *(f"{cell[name, m].accuracy:.2f} ({cell[name, m].means['belief']:.2f})"
                     if (name, m) in cell else "" for m in methods)] for name in classes]
    return header, body


def per_class_markdown(rows: Sequence[tuple[str, MethodSummary]],
                       methods: Sequence[str]) -> str:
    """The per-class table as markdown, after :data:`PER_CLASS_NOTE`."""
    return PER_CLASS_NOTE + "\n\n" + markdown_table(*per_class_cells(rows, methods))


def rows_csv(rows: Sequence[MethodSummary], classes: Sequence[str] | None = None) -> str:
    """Rows as CSV (a ``class`` column first when ``classes`` is given, one per row)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    head = ["method", "episodes", "accuracy", "accuracy_low", "accuracy_high", "exhausted"]
    for k in QUANTITIES:
        head += [k, f"{k}_ci95"]
    writer.writerow((["class"] if classes is not None else []) + head)
    for i, r in enumerate(rows):
        values: list[object] = [r.method, r.episodes, f"{r.accuracy:.6g}",
                                f"{r.accuracy_low:.6g}", f"{r.accuracy_high:.6g}", r.exhausted]
        for k in QUANTITIES:
            values += [f"{r.means[k]:.6g}", f"{r.halfwidths[k]:.6g}"]
        writer.writerow(([classes[i]] if classes is not None else []) + values)
    return buffer.getvalue()


@dataclass(frozen=True)
class TradeoffPoint:
    """One point of a method's accuracy-energy curve: the method run with one setting.

    ``parameter`` is what was varied (``lambda``: the wrong-declaration cost in metres of
    energy the POMDP was solved with; ``threshold``: Random's stop belief; ``none``: Static),
    ``configured`` marks the setting of Table 1.
    """

    method: str
    parameter: str
    value: float
    configured: bool
    summary: MethodSummary


def tradeoff_csv(points: Sequence[TradeoffPoint]) -> str:
    """The accuracy-energy points as CSV, one row per (method, setting)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["method", "parameter", "value", "configured", "episodes", "accuracy",
                     "accuracy_low", "accuracy_high", "energy", "energy_ci95", "moves",
                     "belief"])
    for p in points:
        s = p.summary
        writer.writerow([p.method, p.parameter, f"{p.value:.6g}", int(p.configured), s.episodes,
                         f"{s.accuracy:.6g}", f"{s.accuracy_low:.6g}", f"{s.accuracy_high:.6g}",
                         f"{s.means['energy']:.6g}", f"{s.halfwidths['energy']:.6g}",
                         f"{s.means['moves']:.6g}", f"{s.means['belief']:.6g}"])
    return buffer.getvalue()


def tradeoff_markdown(points: Sequence[TradeoffPoint]) -> str:
    """The accuracy-energy points as a markdown table (Table 1's settings marked *)."""
    header = ["Method", "Setting", "Accuracy [95 % CI]", "Energy (m)", "# steps", "Episodes"]
    rows = []
    for p in points:
        s = p.summary
        setting = {"lambda": f"λ = {p.value:g} m", "threshold": f"stop at belief {p.value:g}",
                   "none": "—"}[p.parameter] + (" *" if p.configured else "")
        rows.append([METHOD_NAMES.get(p.method, p.method), setting,
                     f"{s.accuracy:.3f} [{s.accuracy_low:.3f}, {s.accuracy_high:.3f}]",
                     _pm(s.means["energy"], s.halfwidths["energy"]),
                     f"{s.means['moves']:.2f}", f"{s.episodes}"])
    return markdown_table(header, rows) + "\n* the setting of Table 1.\n"


def read_tradeoff_csv(text: str) -> list[TradeoffPoint]:
    """The accuracy-energy points back from :func:`tradeoff_csv`'s text (the report reads the
    evaluate stage's ``tradeoff.csv``); a malformed file raises ``ValueError``."""
    rows = list(csv.DictReader(io.StringIO(text)))
    try:
        return [TradeoffPoint(
            r["method"], r["parameter"], float(r["value"]), r["configured"] == "1",
            MethodSummary(r["method"], int(r["episodes"]), float(r["accuracy"]),
                          float(r["accuracy_low"]), float(r["accuracy_high"]),
                          {"energy": float(r["energy"]), "moves": float(r["moves"]),
                           "belief": float(r["belief"])},
                          {"energy": float(r["energy_ci95"])}, 0)) for r in rows]
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"not an accuracy-energy table ({exc})") from None


def standing_phrases(differences: Sequence[tuple[str, float, float, float]]) -> list[str]:
    """How a reference method stands against others from (name, that method's accuracy minus
    the reference's, its 95 % interval's low and high): "more accurate than A (by 0.1)",
    "less accurate than B (by 0.05)", "not distinguishable from C" (an interval holding 0)."""
    below = [f"{n} (by {-d:.3f})" for n, d, _, high in differences if high < 0]
    above = [f"{n} (by {d:.3f})" for n, d, low, _ in differences if low > 0]
    level = [n for n, _, low, high in differences if low <= 0 <= high]
    said = []
    if below:
        said.append(f"more accurate than {', '.join(below)}")
    if above:
        said.append(f"less accurate than {', '.join(above)}")
    if level:
        said.append(f"not distinguishable from {', '.join(level)}")
    return said


def table1_story(rows: Sequence[MethodSummary], paired: dict[str, PairedDifference],
                 points: Sequence[TradeoffPoint] = ()) -> str:
    """One paragraph saying what Table 1 and the accuracy-energy points show on this run,
    written from the numbers (which method is best, which paired differences exclude 0, what
    the energy bought)."""
    name = {r.method: METHOD_NAMES.get(r.method, r.method) for r in rows}
    best = max(rows, key=lambda r: r.accuracy)
    parts = [f"On this run {name[best.method]} is the most accurate method "
             f"({best.accuracy:.3f} of {best.episodes} episodes)"]
    by_method = {r.method: r for r in rows}
    if "static" in by_method and best.method != "static":
        parts[-1] += f"; Static, one view, reaches {by_method['static'].accuracy:.3f}"
    parts[-1] += "."
    if paired:
        ref = next(iter(paired.values())).reference
        ref_name = METHOD_NAMES.get(ref, ref)
        said = standing_phrases([(name.get(m, m), p.difference, p.low, p.high)
                                 for m, p in paired.items()])
        parts.append("Over the same (test model, start) pairs, with 95 % intervals that "
                     f"resample test models, {ref_name} is {'; '.join(said)}.")
        if ref in by_method:
            spent = ", ".join(f"{name[r.method]} {r.means['energy']:.2f} m"
                              for r in rows if r.moves_at_all)
            parts.append(f"Mean movement energy per episode: {spent or 'none moved'}.")
    if points:
        top = max(points, key=lambda p: p.summary.accuracy)
        setting = {"lambda": f"λ = {top.value:g} m", "threshold": f"stop belief {top.value:g}",
                   "none": "its one setting"}[top.parameter]
        parts.append(f"Over the accuracy-energy sweep the highest accuracy is "
                     f"{METHOD_NAMES.get(top.method, top.method)} at {setting} "
                     f"({top.summary.accuracy:.3f} for {top.summary.means['energy']:.2f} m).")
    return " ".join(parts)
