"""A study's results gathered from its seed workspaces and pooled: Table 1 as the mean over
seeds, each method's paired difference to RA-POMDP with a seeds × test-models interval, the
per-seed spread, the accuracy–energy points averaged over seeds, and the same comparison on
the held-out objects (the evaluate stages' held-out closed loop, seeds × held-out objects)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rapomdp.config import METHOD_NAMES
from rapomdp.experiment.episode_table import EPISODES_FILE, TRADEOFF_CSV, EpisodeTable
from rapomdp.experiment.held_out import load_held_out_comparison
from rapomdp.experiment.metrics import (
    MethodSummary,
    TradeoffPoint,
    paired_model_sums,
    read_tradeoff_csv,
    table1,
)
from rapomdp.io import read_text
from rapomdp.recognition.belief import calibrated_ece, expected_calibration_error
from rapomdp.study.bootstrap import PooledInterval, SeedClusters, hierarchical_bootstrap
from rapomdp.study.runner import seed_workspace
from rapomdp.study.spec import StudySpec
from rapomdp.workspace import StageError

#: The method every paired difference is taken against.
REFERENCE = "ra"


@dataclass(frozen=True)
class SeedResult:
    """One seed's evaluated episodes and accuracy–energy points, and its dataset stage's key
    (equal keys: the seeds evaluated the same test models)."""

    dataset: str
    seed: int
    workspace: Path
    table: EpisodeTable
    points: list[TradeoffPoint]
    dataset_key: str


def load_seed_results(spec: StudySpec, root: str | Path) -> dict[str, list[SeedResult]]:
    """Every seed's results, per configuration; a seed not yet evaluated is a named error."""
    out: dict[str, list[SeedResult]] = {}
    for dataset in spec.datasets:
        results = []
        for seed in spec.seeds:
            ws = seed_workspace(root, dataset.name, seed)
            try:
                evaluate = ws.require("evaluate")
            except StageError:
                raise StageError(f"{ws.root}: seed {seed} of '{dataset.name}' has not been "
                                 f"evaluated; run `rapomdp study -s {root}` to finish the "
                                 "study") from None
            points = (read_tradeoff_csv(read_text(evaluate / TRADEOFF_CSV))
                      if (evaluate / TRADEOFF_CSV).exists() else [])
            key = str(ws.manifest()["stages"]["dataset"]["key"])
            results.append(SeedResult(dataset.name, seed, ws.root,
                                      EpisodeTable.load(evaluate / EPISODES_FILE), points, key))
        out[dataset.name] = results
    return out


@dataclass(frozen=True)
class PooledRow:
    """One method of the pooled Table 1: means over seeds, each seed's value, and the paired
    difference to RA-POMDP (None for RA-POMDP itself)."""

    method: str
    accuracy: float
    energy_m: float
    moves: float
    overconfidence: float
    ece: float
    #: The ECE a calibrated reporter of the same confidences shows from sampling alone, 95th
    #: percentile (:func:`~rapomdp.recognition.belief.calibrated_ece`): below it, no evidence
    #: of miscalibration.
    ece_if_calibrated: float
    episodes: int
    accuracy_by_seed: tuple[float, ...]
    energy_by_seed: tuple[float, ...]
    difference: PooledInterval | None

    @property
    def name(self) -> str:
        return METHOD_NAMES.get(self.method, self.method)

    @property
    def accuracy_sd(self) -> float:
        """The spread of the per-seed accuracies (sample standard deviation; 0 for one)."""
        values = np.asarray(self.accuracy_by_seed)
        return float(values.std(ddof=1)) if values.size > 1 else 0.0


def common_methods(results: Sequence[SeedResult]) -> list[str]:
    """The methods every seed evaluated, in the first seed's order."""
    return [m for m in results[0].table.methods
            if all(m in r.table.methods for r in results)]


def pooled_table(results: Sequence[SeedResult], resamples: int = 10_000,
                 seed: int = 0) -> list[PooledRow]:
    """The pooled Table 1 of one configuration's seeds (paired, seeds × test models)."""
    if not results:
        raise ValueError("no seeds to pool")
    methods = common_methods(results)
    crossed = len({r.dataset_key for r in results}) == 1
    rows: list[PooledRow] = []
    per_seed: list[dict[str, MethodSummary]] = [
        {s.method: s for s in table1(r.table, methods)} for r in results]
    for method in methods:
        summaries = [by[method] for by in per_seed]
        confidence, correct = [], []
        for r in results:
            mine = r.table.method == method
            confidence.append(r.table.final_confidence()[mine])
            correct.append(r.table.correct[mine].astype(float))
        all_conf, all_correct = np.concatenate(confidence), np.concatenate(correct)
        difference = None
        if method != REFERENCE and REFERENCE in methods:
            clusters = []
            for r in results:
                models, sums, pairs = paired_model_sums(r.table, method, REFERENCE)
                clusters.append(SeedClusters(models, sums, pairs))
            difference = hierarchical_bootstrap(clusters, resamples, seed,
                                                crossed=None if crossed else False)
        rows.append(PooledRow(
            method,
            float(np.mean([s.accuracy for s in summaries])),
            float(np.mean([s.means["energy"] for s in summaries])),
            float(np.mean([s.means["moves"] for s in summaries])),
            float(np.mean([c.mean() - k.mean() for c, k in zip(confidence, correct,
                                                                 strict=True)])),
            expected_calibration_error(all_conf, all_correct),
            calibrated_ece(all_conf),
            sum(s.episodes for s in summaries),
            tuple(s.accuracy for s in summaries),
            tuple(s.means["energy"] for s in summaries),
            difference))
    return rows


@dataclass(frozen=True)
class PooledPoint:
    """One (method, setting) of the accuracy–energy curve averaged over seeds, with the
    per-seed range of its accuracy."""

    method: str
    parameter: str
    value: float
    configured: bool
    accuracy: float
    accuracy_min: float
    accuracy_max: float
    energy_m: float
    seeds: int


def pooled_points(results: Sequence[SeedResult]) -> list[PooledPoint]:
    """The accuracy–energy points every seed has, averaged over seeds."""
    grouped: dict[tuple[str, str, float], list[TradeoffPoint]] = {}
    for r in results:
        for p in r.points:
            grouped.setdefault((p.method, p.parameter, round(p.value, 9)), []).append(p)
    out = []
    for (method, parameter, value), points in grouped.items():
        if len(points) != len(results):
            continue
        accuracy = np.array([p.summary.accuracy for p in points])
        out.append(PooledPoint(method, parameter, value, points[0].configured,
                               float(accuracy.mean()), float(accuracy.min()),
                               float(accuracy.max()),
                               float(np.mean([p.summary.means["energy"] for p in points])),
                               len(points)))
    return out


def as_tradeoff_points(points: Sequence[PooledPoint]) -> list[TradeoffPoint]:
    """The pooled points in the form the accuracy–energy figure draws (the error bars: the
    range over seeds)."""
    return [TradeoffPoint(p.method, p.parameter, p.value, p.configured,
                          MethodSummary(p.method, p.seeds, p.accuracy, p.accuracy_min,
                                        p.accuracy_max, {"energy": p.energy_m}, {}, 0))
            for p in points]


@dataclass(frozen=True)
class HeldOutRow:
    """One method on the held-out objects, pooled over seeds: its held-out accuracy and
    energy (means of seeds) and its paired difference to RA-POMDP there (None for RA-POMDP,
    or where a seed could not pair it)."""

    method: str
    accuracy: float
    energy_m: float
    difference: PooledInterval | None

    @property
    def name(self) -> str:
        return METHOD_NAMES.get(self.method, self.method)


def held_out_table(results: Sequence[SeedResult], resamples: int = 10_000,
                   seed: int = 0) -> list[HeldOutRow]:
    """Table 1's methods on each seed's held-out objects (``evaluate/held_out/
    comparison.json``), pooled by :func:`pool_held_out`. Empty where a seed has no comparison
    (one held-out group, or an evaluate stage from before it)."""
    records = [load_held_out_comparison(r.workspace / "evaluate") for r in results]
    present = [rec for rec in records if rec is not None]
    if not present or len(present) < len(records):
        return []
    return pool_held_out(present, len({r.dataset_key for r in results}) == 1, resamples, seed)


def pool_held_out(records: Sequence[dict[str, Any]], crossed: bool, resamples: int = 10_000,
                  seed: int = 0) -> list[HeldOutRow]:
    """The seeds' held-out comparisons pooled as :func:`pooled_table` pools the test models,
    the held-out objects being the clusters: means of seeds and each method's paired
    difference to RA-POMDP over seeds × held-out objects. ``crossed``: every seed held out the
    same objects (the dataset stage is shared). Empty where a seed did not run RA-POMDP."""
    if not records or any(REFERENCE not in rec["methods"] for rec in records):
        return []
    order = records[0].get("order", list(records[0]["methods"]))
    methods = [m for m in order if all(m in rec["methods"] for rec in records)]
    rows = []
    for method in methods:
        difference = None
        per_object = [rec["paired"].get(method, {}).get("per_object") for rec in records]
        if method != REFERENCE and all(p is not None for p in per_object):
            clusters = [SeedClusters(np.asarray(p["objects"]),
                                     np.asarray(p["sums"], dtype=np.float64),
                                     np.asarray(p["pairs"], dtype=np.float64))
                        for p in per_object if p is not None]
            difference = hierarchical_bootstrap(clusters, resamples, seed,
                                                crossed=None if crossed else False)
        rows.append(HeldOutRow(
            method, float(np.mean([rec["methods"][method]["accuracy"] for rec in records])),
            float(np.mean([rec["methods"][method]["energy_m"] for rec in records])),
            difference))
    return rows
