"""Table 1's statistics: Wilson and Student intervals, the rows and their markdown."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from rapomdp.experiment.metrics import (
    REPORTED_BELIEF_NOTE,
    MethodSummary,
    PairedDifference,
    TradeoffPoint,
    cluster_bootstrap_difference,
    mean_interval,
    paired_accuracy_difference,
    paired_against,
    paired_csv,
    paired_model_sums,
    read_tradeoff_csv,
    rows_csv,
    summarise,
    table1_markdown,
    table1_story,
    tradeoff_csv,
    wilson_interval,
)


def test_wilson_interval_matches_the_closed_form() -> None:
    low, high = wilson_interval(8, 10)
    assert low == pytest.approx(0.4902, abs=1e-4) and high == pytest.approx(0.9433, abs=1e-4)
    low, high = wilson_interval(0, 20)
    assert low == 0.0 and high == pytest.approx(0.1611, abs=1e-4)
    low, high = wilson_interval(20, 20)
    assert high == 1.0 and low == pytest.approx(0.8389, abs=1e-4)
    assert all(np.isnan(wilson_interval(0, 0)))


def test_mean_interval_is_students_t() -> None:
    mean, half = mean_interval(np.array([1.0, 2.0, 3.0]))
    assert mean == 2.0 and half == pytest.approx(4.302653 / np.sqrt(3), rel=1e-6)
    assert mean_interval(np.array([5.0])) == (5.0, 0.0)


def _row(method: str, moves: np.ndarray) -> object:
    n = moves.size
    return summarise(np.arange(n) % 2 == 0, np.linspace(0.2, 0.8, n), moves, moves * 0.3,
                     moves * 0.35, np.zeros(n, dtype=bool), method)


def test_rows_and_markdown() -> None:
    static = _row("static", np.zeros(10, dtype=int))
    ra = _row("ra", np.arange(10))
    assert ra.accuracy == 0.5 and ra.episodes == 10
    assert ra.means["moves"] == 4.5 and ra.means["energy"] == pytest.approx(4.5 * 0.35)
    text = table1_markdown([static, ra])
    lines = text.strip().splitlines()
    assert lines[2].startswith("| Static | 0.500 [") and lines[2].count("—") == 3
    assert lines[3].startswith("| RA-POMDP | 0.500 [0.237, 0.763] | 0.500 ± ")
    assert "4.500 ± " in lines[3]
    csv = rows_csv([static, ra]).splitlines()
    assert csv[0].startswith("method,episodes,accuracy,accuracy_low") and len(csv) == 3
    assert rows_csv([ra], ["cup"]).splitlines()[1].startswith("cup,ra,10,0.5,")


def _episodes(correct: dict[str, np.ndarray], starts: int) -> SimpleNamespace:
    """Episodes of methods over models x starts: ``correct[m]`` is (models, starts)."""
    method, model, start, right = [], [], [], []
    for key, grid in correct.items():
        for i, row in enumerate(grid):
            for s in range(starts):
                method.append(key)
                model.append(f"m{i}.npz")
                start.append(10 * s + i % 3)
                right.append(bool(row[s]))
    # the episodes in another order for one method: pairs are matched by (model, start)
    return SimpleNamespace(method=np.array(method), model=np.array(model), start=np.array(start),
                           correct=np.array(right))


def test_paired_difference_is_exact_when_every_model_gains_the_same() -> None:
    ra = np.zeros((6, 5), dtype=bool)
    static = np.zeros((6, 5), dtype=bool)
    ra[:, :3] = True  # RA-POMDP right from 3 of 5 starts of every model
    static[:, :1] = True  # Static from 1 of 5
    table = _episodes({"static": static, "ra": ra}, 5)
    d = paired_accuracy_difference(table, "static", "ra", resamples=500)
    assert d.difference == pytest.approx(-0.4)
    assert d.low == pytest.approx(-0.4) and d.high == pytest.approx(-0.4)  # no spread to resample
    assert (d.pairs, d.models) == (30, 6)
    paired = paired_against(table, ["static", "ra"])
    assert list(paired) == ["static"]
    assert paired_csv(paired).splitlines()[1].startswith("static,ra,-0.4,")
    assert paired_against(table, ["static"]) == {}


def test_cluster_bootstrap_matches_the_normal_interval_over_models() -> None:
    # 400 models: half gain 1 on every start, half 0; the models, not the 5 starts, are the draws
    sums = np.repeat([5.0, 0.0], 200)
    pairs = np.full(400, 5.0)
    estimate, low, high = cluster_bootstrap_difference(sums, pairs, resamples=4000, seed=1)
    half = 1.96 * np.sqrt(0.25 / 400)  # 0.049: the interval of 400 draws, not of 2000
    assert estimate == pytest.approx(0.5)
    assert low == pytest.approx(0.5 - half, abs=0.008)
    assert high == pytest.approx(0.5 + half, abs=0.008)
    with pytest.raises(ValueError, match="positive pair count"):
        cluster_bootstrap_difference(np.ones(2), np.array([1.0, 0.0]))


def test_paired_difference_needs_the_same_pairs() -> None:
    grid = np.ones((3, 2), dtype=bool)
    table = _episodes({"static": grid, "ra": grid}, 2)
    table.start[0] += 1  # one Static episode from another start
    with pytest.raises(ValueError, match="did not run from the same"):
        paired_accuracy_difference(table, "static", "ra")
    with pytest.raises(ValueError, match="no episodes of method 'random'"):
        paired_accuracy_difference(table, "random", "ra")


def test_a_method_pairs_with_itself_in_another_table_of_the_same_pairs() -> None:
    """Two configurations of one seed: the same method's episodes, matched by (model, start)."""
    base = np.zeros((4, 3), dtype=bool)
    variant = base.copy()
    variant[0, :] = True  # the variant is right from every start of model 0, and nothing else
    models, sums, pairs = paired_model_sums(_episodes({"ra": variant}, 3), "ra", "ra",
                                            _episodes({"ra": base}, 3))
    assert list(models) == ["m0.npz", "m1.npz", "m2.npz", "m3.npz"]
    np.testing.assert_array_equal(sums, [3.0, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(pairs, [3.0, 3.0, 3.0, 3.0])
    shifted = _episodes({"ra": base}, 3)
    shifted.start[0] += 1
    with pytest.raises(ValueError, match="did not run from the same"):
        paired_model_sums(_episodes({"ra": variant}, 3), "ra", "ra", shifted)


def test_a_method_pairs_with_itself_where_the_other_table_holds_more_methods() -> None:
    """The base configuration evaluated a method the variant did not: each table's own rows
    are paired (the same method name on both sides must not share one row selection)."""
    base = np.zeros((4, 3), dtype=bool)
    variant = base.copy()
    variant[1, :2] = True
    wider = _episodes({"static": np.ones((4, 3), dtype=bool), "ra": base}, 3)
    models, sums, pairs = paired_model_sums(_episodes({"ra": variant}, 3), "ra", "ra", wider)
    np.testing.assert_array_equal(sums, [0.0, 2.0, 0.0, 0.0])
    np.testing.assert_array_equal(pairs, [3.0, 3.0, 3.0, 3.0])
    models, sums, _ = paired_model_sums(wider, "ra", "ra", _episodes({"ra": variant}, 3))
    np.testing.assert_array_equal(sums, [0.0, -2.0, 0.0, 0.0])


def test_markdown_has_the_paired_column() -> None:
    ra = np.zeros((4, 5), dtype=bool)
    ra[:, :2] = True
    table = _episodes({"static": np.zeros((4, 5), dtype=bool), "ra": ra}, 5)
    rows = [_row("static", np.zeros(20, dtype=int)), _row("ra", np.arange(20))]
    text = table1_markdown(rows, paired_against(table, ["static", "ra"], resamples=200))
    lines = text.splitlines()
    assert "Δ accuracy vs RA-POMDP [95 % CI]" in lines[0]
    assert "| -0.400 [-0.400, -0.400] |" in lines[2]
    assert lines[3].count("| — |") >= 1  # RA-POMDP itself
    assert "resampling the 4 test models" in text


def _summary(method: str, accuracy: float, energy: float, moves: float) -> MethodSummary:
    return MethodSummary(method, 100, accuracy, accuracy - 0.05, accuracy + 0.05,
                         {"belief": 0.5, "moves": moves, "distance_m": 0.1, "energy": energy},
                         {"belief": 0.01, "moves": 0.1, "distance_m": 0.01, "energy": 0.02}, 0)


def test_the_story_is_written_from_the_numbers() -> None:
    rows = [_summary("static", 0.557, 0.0, 0.0), _summary("random", 0.679, 1.18, 2.5),
            _summary("classifier", 0.530, 0.06, 0.2), _summary("ra", 0.534, 0.21, 0.4)]
    paired = {"static": PairedDifference("static", "ra", 0.023, -0.011, 0.057, 560, 140),
              "random": PairedDifference("random", "ra", 0.145, 0.075, 0.216, 560, 140),
              "classifier": PairedDifference("classifier", "ra", -0.1, -0.15, -0.02, 560, 140)}
    points = [TradeoffPoint("ra", "lambda", 8.0, False, _summary("ra", 0.6, 1.03, 3.0)),
              TradeoffPoint("random", "threshold", 0.97, False, _summary("random", 0.695, 1.49,
                                                                         3.1))]
    story = table1_story(rows, paired, points)
    assert story.startswith("On this run Random is the most accurate method (0.679 of 100 "
                            "episodes); Static, one view, reaches 0.557.")
    assert ("RA-POMDP is more accurate than Classifier (by 0.100); less accurate than Random "
            "(by 0.145); not distinguishable from Static.") in story
    assert "Mean movement energy per episode: Random 1.18 m, Classifier 0.06 m, RA-POMDP 0.21 m."\
        in story
    assert story.endswith("the highest accuracy is Random at stop belief 0.97 (0.695 for 1.49 m).")


def test_the_tradeoff_csv_reads_back() -> None:
    points = [TradeoffPoint("ra", "lambda", 0.5, True, _summary("ra", 0.61, 0.25, 1.0)),
              TradeoffPoint("static", "none", 0.0, True, _summary("static", 0.5, 0.0, 0.0))]
    back = read_tradeoff_csv(tradeoff_csv(points))
    assert [(p.method, p.parameter, p.value, p.configured) for p in back] == [
        ("ra", "lambda", 0.5, True), ("static", "none", 0.0, True)]
    assert [p.summary.accuracy for p in back] == [0.61, 0.5]
    assert back[0].summary.means["energy"] == 0.25
    with pytest.raises(ValueError, match="not an accuracy-energy table"):
        read_tradeoff_csv("method,accuracy\nra,x\n")


@pytest.mark.parametrize(("successes", "n"), [(0, 3), (0, 6), (0, 7), (10, 10), (1, 1), (5, 9)])
def test_wilson_interval_holds_the_proportion_at_0_and_100_percent(successes: int,
                                                                    n: int) -> None:
    low, high = wilson_interval(successes, n)
    p = successes / n
    assert 0.0 <= low <= p <= high <= 1.0
    assert (low == 0.0) == (successes == 0) and (high == 1.0) == (successes == n)


def test_the_reported_belief_note_says_what_each_method_reports() -> None:
    assert REPORTED_BELIEF_NOTE.startswith("Random, the POMDP methods and the learned baseline "
                                           "report their belief raised to a declared-")
    assert "the others' where their own held-out closed loop stops" in REPORTED_BELIEF_NOTE
    assert "evaluate." not in REPORTED_BELIEF_NOTE  # no option left to name
