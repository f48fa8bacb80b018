"""The study's report and README block, from the tiny study's seed workspaces."""

from __future__ import annotations

import csv
import io
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from rapomdp.cli import app
from rapomdp.experiment.episode_table import EPISODES_FILE, EpisodeTable
from rapomdp.experiment.metrics import CALIBRATED_ECE_NOTE
from rapomdp.io import save_npz
from rapomdp.recognition.belief import calibrated_ece
from rapomdp.study.pooled import load_seed_results, pooled_table
from rapomdp.study.report import (
    BEGIN,
    END,
    pooled_cells,
    study_markdown,
    update_study_readme,
    write_study_report,
)
from rapomdp.workspace import Workspace
from tests.study.conftest import TinyStudy


def _rows(path: Path) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(path.read_text())))


def test_report_pools_each_seed_and_pairs_against_ra(tiny_study: TinyStudy) -> None:
    written = write_study_report(tiny_study.spec, tiny_study.root, resamples=500)
    out = written.html.parent
    assert written.markdown == out / "report.md"
    assert written.stories["tiny"].startswith("On 'tiny', over 2 seeds (0, 1; the same split")
    assert {p.name for p in out.iterdir()} >= {
        "report.html", "report.md", "table1_pooled.csv", "table1_seeds.csv",
        "tradeoff_pooled.csv", "tradeoff_tiny.png"}
    results = load_seed_results(tiny_study.spec, tiny_study.root)["tiny"]
    pooled = {r["method"]: r for r in _rows(out / "table1_pooled.csv")}
    for method, row in pooled.items():
        per_seed = [r.table.correct[r.table.method == method].mean() for r in results]
        assert float(row["accuracy"]) == pytest.approx(np.mean(per_seed), abs=1e-6)
        assert int(row["seeds"]) == 2
        if method == "ra":
            assert row["difference_vs_ra"] == ""
        else:
            low, mid, high = (float(row[k]) for k in ("ci95_low", "difference_vs_ra",
                                                      "ci95_high"))
            assert low <= mid <= high
            ra = [r.table.correct[r.table.method == "ra"].mean() for r in results]
            assert mid == pytest.approx(np.mean(per_seed) - np.mean(ra), abs=1e-6)
    seeds = _rows(out / "table1_seeds.csv")
    assert len(seeds) == 2 * len(pooled)
    assert {r["seed"] for r in seeds} == {"0", "1"}
    text = (out / "report.md").read_text()
    assert "2 seeds (0, 1), vary: train" in text and "### Seed 1" in text
    # the seconds every seed's manifest records for its stages' latest runs, summed
    recorded = sum(float(r.get("seconds", 0.0)) for result in results
                   for r in Workspace(result.workspace).manifest()["stages"].values())
    assert (f"Stage time of the study's 2 seeds: {recorded:.0f} s (each stage's latest run; "
            "shared stages counted once") in text
    # what the confidence columns are: the declared confidence, as the seeds' evaluate ran
    assert "Confidence − accuracy and ECE: Random, the POMDP methods and the learned " \
        "baseline report their belief raised to a declared-confidence temperature" in text


def test_vary_train_pairs_crossed_over_the_same_test_models(tiny_study: TinyStudy) -> None:
    rows = pooled_table(load_seed_results(tiny_study.spec, tiny_study.root)["tiny"], 200)
    assert all(r.difference.crossed for r in rows if r.difference is not None)


def test_the_pooled_ece_sits_beside_what_sampling_gives_a_calibrated_reporter(
        tiny_study: TinyStudy) -> None:
    results = load_seed_results(tiny_study.spec, tiny_study.root)["tiny"]
    rows = pooled_table(results, 200)
    header, cells = pooled_cells(rows)
    column = header.index("ECE if calibrated (95 %)")
    assert header[column - 1] == "ECE"
    for row, cell in zip(rows, cells, strict=True):
        confidence = np.concatenate([r.table.final_confidence()[r.table.method == row.method]
                                     for r in results])
        assert row.ece_if_calibrated == calibrated_ece(confidence)
        assert cell[column] == f"{row.ece_if_calibrated:.3f}"


def test_the_readme_block_follows_the_study(tiny_study: TinyStudy, tmp_path: Path) -> None:
    root = tmp_path / "study"
    shutil.copytree(tiny_study.root, root)
    readme = tmp_path / "README.md"
    readme.write_text(f"# x\n\n{BEGIN}\nold\n{END}\n\nafter\n")
    update_study_readme(tiny_study.spec, root, readme)
    first = readme.read_text()
    assert "\nold\n" not in first and first.endswith(f"{END}\n\nafter\n")
    assert "Over 2 seeds (0, 1; the same split, models and starts; each seed its own " \
        "classifier)" in first and "on 'tiny' (" in first
    assert "| Method | 'tiny' accuracy | energy (m) | Δ vs RA-POMDP [95 %] |" in first
    # another outcome in seed 1: every RA-POMDP episode right
    path = root / "tiny" / "seed-1" / "evaluate" / EPISODES_FILE
    table = EpisodeTable.load(path)
    table.correct = np.where(table.method == "ra", True, table.correct)
    path.unlink()  # a hard link shared with nothing, but replace rather than write through
    save_npz(path, **table.arrays())
    update_study_readme(tiny_study.spec, root, readme)
    second = readme.read_text()
    assert second != first
    assert second.split(BEGIN)[1].split(END)[0].strip() == study_markdown(
        tiny_study.spec, root).strip()


def test_cli_reports_and_refuses_a_changed_study(tiny_study: TinyStudy) -> None:
    runner = CliRunner()
    done = runner.invoke(app, ["study", "-s", str(tiny_study.root), "--report-only"])
    assert done.exit_code == 0, done.output
    assert str(tiny_study.root / "report" / "report.html") in done.output
    assert "On 'tiny', over 2 seeds" in done.output
    changed = runner.invoke(app, ["study", "-s", str(tiny_study.root), "--seeds", "3",
                                  "--report-only"])
    assert changed.exit_code == 2
    assert "seeds [0, 1]" in changed.output and "--reconfigure" in changed.output


def test_the_confidence_line_says_what_every_method_reported(tiny_study: TinyStudy) -> None:
    from rapomdp.experiment.metrics import REPORTED_BELIEF_NOTE
    from rapomdp.study.report import REPORTED_CONFIDENCE

    assert REPORTED_CONFIDENCE == ("Confidence − accuracy and ECE: " + REPORTED_BELIEF_NOTE
                                   + " " + CALIBRATED_ECE_NOTE)
    written = write_study_report(tiny_study.spec, tiny_study.root, resamples=200)
    assert REPORTED_CONFIDENCE in written.markdown.read_text()


def _comparison(ra: float, random: float, sums: list[float]) -> dict:
    """A held-out comparison of two methods on four objects, four starts each."""
    return {"reference": "ra", "order": ["random", "ra"], "unpaired": [],
            "methods": {"ra": {"accuracy": ra, "energy_m": 1.0, "episodes": 16, "objects": 4},
                        "random": {"accuracy": random, "energy_m": 2.0, "episodes": 16,
                                   "objects": 4}},
            "paired": {"random": {"difference": sum(sums) / 16, "low": -1, "high": 1,
                                  "pairs": 16, "objects": 4,
                                  "per_object": {"objects": ["0/0", "0/1", "1/0", "1/1"],
                                                 "sums": sums, "pairs": [4, 4, 4, 4]}}}}


def test_the_held_out_comparisons_pool_over_seeds_with_objects_as_clusters() -> None:
    from rapomdp.study.pooled import pool_held_out

    records = [_comparison(0.75, 0.5, [-2.0, -1.0, -1.0, 0.0]),
               _comparison(0.5, 0.5, [1.0, -1.0, 0.0, 0.0])]
    rows = pool_held_out(records, crossed=False, resamples=2000)
    assert [r.method for r in rows] == ["random", "ra"]  # the order the stages ran them in
    random, ra = rows
    assert (random.accuracy, random.energy_m, ra.accuracy) == (0.5, 2.0, 0.625)
    assert ra.difference is None
    d = random.difference
    assert d.estimate == pytest.approx((-4 / 16 + 0 / 16) / 2)  # the mean of the seeds' ratios
    assert d.seeds == 2 and not d.crossed and d.low <= d.estimate <= d.high
    # a seed without RA-POMDP, or without per-object sums, pools nothing / pairs nothing
    no_ra = _comparison(0.5, 0.5, [0.0] * 4)
    del no_ra["methods"]["ra"]
    assert pool_held_out([records[0], no_ra], crossed=False) == []
    unpaired = _comparison(0.5, 0.5, [0.0] * 4)
    del unpaired["paired"]["random"]["per_object"]
    assert pool_held_out([records[0], unpaired], crossed=False)[0].difference is None


def test_the_report_shows_the_held_out_forecast_beside_table_1(tiny_study: TinyStudy,
                                                                 tmp_path: Path) -> None:
    from rapomdp.io import write_json_atomic

    root = tmp_path / "study"
    shutil.copytree(tiny_study.root, root)
    plain = write_study_report(tiny_study.spec, root, resamples=200).markdown.read_text()
    assert "held-out objects" not in plain  # one volume model a class: nothing held out
    for seed, sums in ((0, [-2.0, -1.0, -1.0, 0.0]), (1, [1.0, -1.0, 0.0, 0.0])):
        write_json_atomic(root / "tiny" / f"seed-{seed}" / "evaluate" / "held_out" /
                          "comparison.json", _comparison(0.7, 0.5, sums))
    text = write_study_report(tiny_study.spec, root, resamples=200).markdown.read_text()
    assert "On the held-out objects (the volume models, run by the evaluate stages before " \
        "any test model was read; 2 seeds" in text
    assert "| Random | 0.500 | 2.000 | -0.125 [" in text
    assert "Test Δ vs RA-POMDP [95 %, seeds × test models]" in text
    block = study_markdown(tiny_study.spec, root, resamples=200)  # the README: test models only
    assert "held-out" not in block and "| Random | 0.500 | 2.000 | -0.125 [" not in block
