"""`rapomdp pomdp solve` and `rapomdp pomdp export`."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest
from typer.testing import CliRunner

from rapomdp.planning.cli import pomdp_app
from rapomdp.planning.io_pomdp import read_pomdp
from rapomdp.planning.policy import AlphaVectorPolicy
from tests.planning.planning_fixtures import small_arrays

runner = CliRunner()


def test_cli_solve_prints_bounds_and_policy_size(tmp_path, benchmarks):
    out = tmp_path / "tiger.npz"
    res = runner.invoke(
        pomdp_app,
        ["solve", str(benchmarks / "Tiger.pomdp"), "--precision", "0.01", "--timeout", "30",
         "--out", str(out)],
    )
    assert res.exit_code == 0, res.output
    assert "lower=" in res.output and "upper=" in res.output
    assert "converged" in res.output and "alpha vectors" in res.output
    policy = AlphaVectorPolicy.load(out)
    assert policy.value(np.array([0.5, 0.5])) == pytest.approx(19.37, abs=0.02)


def test_cli_solve_reports_parse_errors_with_line(tmp_path):
    bad = tmp_path / "bad.pomdp"
    bad.write_text("discount: 0.9\nstates: 2\nactions: 2\nobservations: 2\nT: 7 : 0 : 0 1\n")
    res = runner.invoke(pomdp_app, ["solve", str(bad)])
    assert res.exit_code == 2
    assert "bad.pomdp:5" in res.output.replace("\n", "") and "out of range" in res.output


def test_cli_export_pomdpx_and_flat(tmp_path):
    P, E = small_arrays()
    arrays = tmp_path / "problem.npz"
    np.savez(arrays, observation_model=P, move_energy=E, reachable=np.ones(3, dtype=bool))
    res = runner.invoke(pomdp_app, ["export", "--problem", str(arrays), "--out",
                                    str(tmp_path / "ar.pomdpx")])
    assert res.exit_code == 0, res.output
    assert ET.parse(tmp_path / "ar.pomdpx").getroot().tag == "pomdpx"
    res = runner.invoke(pomdp_app, ["export", "--benchmark", "3x2", "--out",
                                    str(tmp_path / "ar.pomdp")])
    assert res.exit_code == 0, res.output
    flat = read_pomdp(tmp_path / "ar.pomdp")
    assert flat.n_states == 3 * 2 + 1 and flat.n_actions == 3 + 2
    res = runner.invoke(pomdp_app, ["export", "--out", str(tmp_path / "x.pomdpx")])
    assert res.exit_code == 2
    assert "exactly one of --problem, --benchmark and --workspace" in res.output


def _one_error_line(res) -> str:
    """The single ``error:`` line a refused command writes on stderr (stdout holds none)."""
    assert res.exit_code == 2, res.output
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    assert "error:" not in res.stdout
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), res.stderr
    return lines[0]


def test_cli_errors_are_one_line_on_stderr(tmp_path):
    bad = tmp_path / "bad.pomdp"
    bad.write_text("discount: 0.9\nstates: 2\nactions: 2\nobservations: 2\nT: 7 : 0 : 0 1\n")
    assert "bad.pomdp:5" in _one_error_line(runner.invoke(pomdp_app, ["solve", str(bad)]))
    line = _one_error_line(runner.invoke(pomdp_app, ["export", "--benchmark", "3x", "--out",
                                                     str(tmp_path / "a.pomdp")]))
    assert "expected VIEWPOINTSxCLASSES" in line


def test_cli_export_to_a_folder_is_refused_and_the_folder_kept(tmp_path):
    folder = tmp_path / "out.pomdp"
    (folder / "inside").mkdir(parents=True)
    line = _one_error_line(runner.invoke(pomdp_app, ["export", "--benchmark", "3x2", "--out",
                                                     str(folder)]))
    assert str(folder) in line
    assert (folder / "inside").is_dir()


def test_cli_export_on_a_full_disk_names_the_file(tmp_path, monkeypatch):
    import errno

    import rapomdp.planning.cli as cli

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "a.pomdp"))

    monkeypatch.setattr(cli, "write_pomdp", full)
    line = _one_error_line(runner.invoke(pomdp_app, ["export", "--benchmark", "3x2", "--out",
                                                     str(tmp_path / "a.pomdp")]))
    assert "a.pomdp" in line and "no space left" in line


def test_cli_export_applies_the_memory_cap_before_allocating(tmp_path):
    import resource

    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    line = _one_error_line(runner.invoke(pomdp_app, ["export", "--benchmark", "100000x3",
                                                     "--out", str(tmp_path / "a.pomdp")]))
    assert "the benchmark problem 100000x3 needs about 320 GB" in line
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 500_000  # kB
    line = _one_error_line(runner.invoke(pomdp_app, ["export", "--benchmark", "1000x10",
                                                     "--out", str(tmp_path / "a.pomdp")]))
    assert "the flat POMDP of 1000 viewpoints x 10 classes" in line
    assert not (tmp_path / "a.pomdp").exists()


def test_cli_solve_of_a_device_reads_no_further_than_the_cap():
    line = _one_error_line(runner.invoke(pomdp_app, ["solve", "/dev/zero", "--memory-gb",
                                                     "0.01"]))
    assert "/dev/zero: not a regular file" in line
