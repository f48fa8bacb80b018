"""The robot stage's artefacts, its configuration section and its errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rapomdp.config import Config, ConfigError, RobotConfig, ViewpointsConfig, config_from_dict
from rapomdp.geometry.viewsphere import fibonacci_directions, geodesic_distance_matrix
from rapomdp.io import read_json
from rapomdp.robot.artefacts import ROBOT_ARRAYS, ROBOT_FIGURE, ROBOT_SUMMARY, describe, load_robot
from rapomdp.robot.energy import movement_energy
from rapomdp.robot.stage import (
    UnreachableError,
    ik_settings,
    plot_result,
    run_robot_stage,
    solve_robot,
)
from rapomdp.workspace import StageError, StageInputs
from tests.conftest import TEST_CONTEXT


def test_stage_writes_arrays_summary_and_figure(tmp_path: Path) -> None:
    config = Config(viewpoints={"count": 24})
    run_robot_stage(config, StageInputs("robot"), tmp_path, TEST_CONTEXT)
    arrays = load_robot(tmp_path)
    n = 24
    assert arrays["reachable"].shape == (n,) and arrays["reachable"].dtype == bool
    assert arrays["q_rad"].shape == (n, 7)
    assert arrays["energy"].shape == (n, n) and arrays["distance_m"].shape == (n, n)
    summary = read_json(tmp_path / ROBOT_SUMMARY)
    assert summary["reachable"] == int(arrays["reachable"].sum()) > 0
    assert summary["unreachable_indices"] == np.flatnonzero(~arrays["reachable"]).tolist()
    assert summary["max_position_error_m"] <= 1e-3
    assert describe(summary).startswith(f"{summary['reachable']}/24 viewpoints reachable")
    recomputed = movement_energy(
        arrays["distance_m"], arrays["manipulability"], arrays["reachable"], kappa_m=0.1
    )
    np.testing.assert_array_equal(arrays["energy"], recomputed)
    png = (tmp_path / ROBOT_FIGURE).read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [ROBOT_ARRAYS, ROBOT_SUMMARY, ROBOT_FIGURE]
    )


def test_solved_default_scene(solved) -> None:
    reach = solved.reachable
    assert solved.energy.shape == (128, 128)
    assert np.all(np.diag(solved.energy) == 0) and np.all(solved.energy >= 0)
    assert np.isinf(solved.penalty[~reach]).all() and np.all(solved.penalty[reach] >= 0)
    assert solved.penalty[reach].min() == 0.0  # at the most manipulable viewpoint
    m = solved.solutions.manipulability[reach]
    assert np.all(m > 0)
    assert solved.summary["manipulability"]["max"] == pytest.approx(m.max())


def test_ik_settings_read_the_robot_section_alone() -> None:
    settings = ik_settings(RobotConfig(restarts=2, angle_tolerance_deg=2.0,
                                       floor_clearance_m=None), seed=7)
    assert settings.restarts == 2 and settings.seed == 7 and settings.floor_clearance_m is None
    assert settings.angle_tolerance_rad == pytest.approx(np.pi / 90)
    assert ik_settings(RobotConfig()).seed == 0 and ik_settings(RobotConfig()).roll_samples == 8


def test_solve_robot_and_its_figure_without_a_pipeline_configuration(tmp_path: Path) -> None:
    result = solve_robot(RobotConfig(), ViewpointsConfig(count=8, radius_m=0.5), progress=False)
    assert result.summary["viewpoints"] == 8 and result.summary["radius_m"] == 0.5
    assert result.reachable.tolist() == [True, True, True, False, True, False, True, True]
    assert result.summary["unreachable_indices"] == [3, 5]
    assert result.summary["centroid_in_base_m"] == [0.4, 0.0, 0.0]
    np.testing.assert_array_equal(result.directions, fibonacci_directions(8, hemisphere=True))
    np.testing.assert_array_equal(result.distance_m,
                                  geodesic_distance_matrix(result.directions, 0.5))
    assert np.all(np.diag(result.energy) == 0) and np.isinf(np.delete(result.energy[:, 3], 3)).all()
    # the same section and seed give what the stage computes from a whole configuration
    config = Config(viewpoints={"count": 8, "radius_m": 0.5})
    staged = solve_robot(config.robot, config.viewpoints, config.seed, progress=False)
    np.testing.assert_array_equal(staged.energy, result.energy)
    plot_result(result, RobotConfig(), tmp_path / "robot.png", arms=2)
    assert (tmp_path / "robot.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_no_reachable_viewpoint_is_a_clear_error() -> None:
    config = Config(robot={"base_xyz_m": (5.0, 0.0, 0.0)})
    with pytest.raises(UnreachableError, match=r"none of the 128 viewpoints.*base_xyz_m"):
        solve_robot(config.robot, config.viewpoints, config.seed, progress=False)
    assert issubclass(UnreachableError, StageError)


def test_robot_section_is_validated() -> None:
    config = config_from_dict({"robot": {"base_xyz_m": [-0.5, 0.1, 0.0],
                                         "energy": {"penalty": "log"}}})
    assert config.robot.base_xyz_m == (-0.5, 0.1, 0.0)
    assert config.robot.energy.penalty == "log"
    with pytest.raises(ConfigError, match="robot.roll_sample: unknown key"):
        config_from_dict({"robot": {"roll_sample": 4}})
    with pytest.raises(ConfigError, match="robot.energy.penalty"):
        config_from_dict({"robot": {"energy": {"penalty": "cubic"}}})
    with pytest.raises(ConfigError, match="robot.restarts"):
        config_from_dict({"robot": {"restarts": 0}})


def test_config_yaml_round_trip_keeps_the_robot_section() -> None:
    import yaml

    config = Config(robot={"base_yaw_deg": 30.0, "floor_clearance_m": None})
    again = config_from_dict(yaml.safe_load(config.to_yaml()))
    assert again.robot == config.robot
    assert again.section("robot")["base_xyz_m"] == [-0.4, 0.0, 0.2]


def test_stage_in_a_workspace_is_cached_and_survives_a_failed_rerun(tmp_path: Path) -> None:
    from rapomdp.workspace import Stage, Workspace

    stage = Stage(name="robot", run=run_robot_stage, sections=("seed", "viewpoints", "robot"))
    workspace = Workspace(tmp_path)
    config = Config(viewpoints={"count": 16})
    first = workspace.run(stage, config, context=TEST_CONTEXT)
    assert not first.cached and ROBOT_ARRAYS in first.files
    assert workspace.run(stage, config, context=TEST_CONTEXT).cached
    before = (tmp_path / "robot" / ROBOT_ARRAYS).read_bytes()
    with pytest.raises(UnreachableError):
        workspace.run(stage, Config(viewpoints={"count": 16}, robot={"base_xyz_m": (5, 0, 0)}),
                      context=TEST_CONTEXT)
    assert (tmp_path / "robot" / ROBOT_ARRAYS).read_bytes() == before
    assert load_robot(tmp_path / "robot")["reachable"].shape == (16,)
