"""Table 1 of the paper from scored episodes: means with 95 % confidence intervals.

Accuracy is a proportion: its interval is Wilson's score interval (it stays inside [0, 1] and
behaves at 0 % and 100 %). Belief, steps, distance and energy are means with Student's t
interval, mean ± t(0.975, n − 1)·s/√n. Episodes of one class share a test model, so the
intervals treat the episodes as independent draws: they describe the spread over this
protocol's starts and classes, not over unseen objects.
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
from rapomdp.io import markdown_table

if TYPE_CHECKING:
    from rapomdp.experiment.episode_table import EpisodeTable

Z95 = float(stats.norm.ppf(0.975))
QUANTITIES = ("belief", "moves", "distance_m", "energy")


def wilson_interval(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson's score interval of a proportion (95 % by default)."""
    if n == 0:
        return float("nan"), float("nan")
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return float(max(0.0, centre - half)), float(min(1.0, centre + half))


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


def _pm(mean: float, half: float, digits: int = 3) -> str:
    return f"{mean:.{digits}f} ± {half:.{digits}f}"


TABLE1_HEADER = ["Method", "Accuracy [95 % CI]", "Belief", "# steps", "Distance (m)",
                 "Energy (m)", "Episodes"]
#: What the per-class table's cells hold.
PER_CLASS_NOTE = "Accuracy per class (mean final belief in the true class in brackets)."


def table1_cells(rows: Sequence[MethodSummary]) -> tuple[list[str], list[list[str]]]:
    """Table 1's header and cells: mean (95 % interval) per method; — where a method never
    moves. The markdown file and the report both show these."""
    cells = []
    for r in rows:
        move_cells = ([_pm(r.means[k], r.halfwidths[k]) for k in QUANTITIES[1:]]
                      if r.moves_at_all else ["—"] * 3)
        budget = f" ({r.exhausted} hit the step budget)" if r.exhausted else ""
        cells.append([METHOD_NAMES.get(r.method, r.method),
                      f"{r.accuracy:.3f} [{r.accuracy_low:.3f}, {r.accuracy_high:.3f}]",
                      _pm(r.means["belief"], r.halfwidths["belief"]), *move_cells,
                      f"{r.episodes}{budget}"])
    return list(TABLE1_HEADER), cells


def table1_markdown(rows: Sequence[MethodSummary]) -> str:
    """Table 1 as markdown (:func:`table1_cells`)."""
    return markdown_table(*table1_cells(rows))


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
