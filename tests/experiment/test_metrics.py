"""Table 1's statistics: Wilson and Student intervals, the rows and their markdown."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.experiment.metrics import (
    mean_interval,
    rows_csv,
    summarise,
    table1_markdown,
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
