"""The solve stage and `pomdp export --workspace` on synthetic observe and robot artefacts."""

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from rapomdp.config import SolveConfig, config_from_dict
from rapomdp.geometry.viewsphere import geodesic_distance_matrix, viewpoints
from rapomdp.io import read_json, save_npz
from rapomdp.planning.cli import pomdp_app
from rapomdp.planning.policy import ActiveRecognitionPolicy
from rapomdp.planning.stage import run_solve_stage, workspace_arrays, workspace_problem
from rapomdp.workspace import Stage, StageError, StageInputs, Workspace
from tests.conftest import TEST_CONTEXT

V, C = 10, 3
UNREACHABLE = 6


def _observation_model(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    right = rng.uniform(0.4, 0.95, size=(V, C))
    P = np.repeat(((1 - right) / (C - 1))[:, :, None], C, axis=2)
    P[:, np.arange(C), np.arange(C)] = right
    return P


def _write_observe(config, inputs, out: Path, context) -> None:  # noqa: ANN001
    save_npz(out / "observation_models.npz", models=np.array(["ra", "classifier"]),
             classes=np.array(["cup", "mug", "bottle"]), ra=_observation_model(0),
             classifier=_observation_model(1))


def _write_vptree(config, inputs, out: Path, context) -> None:  # noqa: ANN001
    save_npz(out / "observation_model.npz", classes=np.array(["cup", "mug", "bottle"]),
             vptree=_observation_model(2))


def _write_robot(config, inputs, out: Path, context) -> None:  # noqa: ANN001
    distance = geodesic_distance_matrix(viewpoints(V, 0.6, hemisphere=True), 0.6)
    reachable = np.ones(V, dtype=bool)
    reachable[UNREACHABLE] = False
    energy = distance + 0.05
    np.fill_diagonal(energy, 0.0)
    energy[UNREACHABLE, :] = np.inf
    energy[:, UNREACHABLE] = np.inf
    energy[UNREACHABLE, UNREACHABLE] = 0.0
    save_npz(out / "robot.npz", energy=energy, reachable=reachable, distance_m=distance)


@pytest.fixture
def workspace(tmp_path: Path) -> Workspace:
    ws = Workspace(tmp_path / "ws")
    cfg = config_from_dict({})
    ws.run(Stage("observe", _write_observe), cfg, context=TEST_CONTEXT)
    ws.run(Stage("vptree", _write_vptree), cfg, context=TEST_CONTEXT)
    ws.run(Stage("robot", _write_robot), cfg, context=TEST_CONTEXT)
    return ws


def test_solve_stage_writes_one_policy_per_model(workspace: Workspace, tmp_path: Path) -> None:
    cfg = config_from_dict({"solve": {"timeout_s": 3, "wrong_declaration_cost_m": 3.0}})
    out = tmp_path / "solve"
    out.mkdir()
    run_solve_stage(cfg, StageInputs("solve", observe_dir=workspace.stage_dir("observe"),
                                     vptree_dir=workspace.stage_dir("vptree"),
                                     robot_dir=workspace.stage_dir("robot")), out, TEST_CONTEXT)
    summary = read_json(out / "solve_summary.json")
    assert set(summary) == {"ra", "classifier", "vptree"}  # the default solve.models
    for name, bounds in summary.items():
        assert bounds["lower"] <= bounds["upper"] + 1e-9
        # declaring at once costs lambda (C - 1) / C; the policy can only do better
        assert bounds["lower"] >= -3.0 * (C - 1) / C - 1e-9
        policy = ActiveRecognitionPolicy.load(out / f"policy_{name}.npz")
        for start in (0, 3):
            action = policy.act(start, np.full(C, 1 / C))
            assert action.kind in ("move", "declare")
            if action.kind == "move":
                assert action.target != UNREACHABLE and action.target != start
        # a certain belief is declared at once
        certain = policy.act(0, np.array([0.0, 1.0, 0.0]))
        assert (certain.kind, certain.target) == ("declare", 1)


def test_solve_stage_errors_name_the_model_and_the_mismatch(workspace: Workspace) -> None:
    observe, robot, vptree = (workspace.stage_dir(n) for n in ("observe", "robot", "vptree"))
    cfg = config_from_dict({"solve": {"models": ["ra", "blackbox"]}})
    with pytest.raises(StageError, match="solve.models names blackbox; the workspace offers "
                                         "ra, classifier, vptree$"):
        workspace_problem(observe, robot, "ra", vptree, cfg.solve)
    with pytest.raises(StageError, match="names vptree; the workspace offers ra, classifier "
                                         r"\(the vptree stage makes 'vptree'"):
        workspace_problem(observe, robot, "ra", solve=config_from_dict({}).solve)
    everything = config_from_dict({"solve": {"models": None}})
    assert workspace_problem(observe, robot, "vptree", vptree, everything.solve).class_names == [
        "cup", "mug", "bottle"]
    save_npz(vptree / "observation_model.npz", classes=np.array(["cup", "bottle", "mug"]),
             vptree=_observation_model(2))
    with pytest.raises(StageError, match=r"observation_model\.npz: the VP-tree's classes "
                                         r"\['cup', 'bottle', 'mug'\] differ"):
        workspace_problem(observe, robot, "ra", vptree, everything.solve)
    save_npz(vptree / "observation_model.npz", classes=np.array(["cup", "mug", "bottle"]),
             vptree=_observation_model(2)[:4])
    with pytest.raises(StageError, match="the VP-tree model covers 4 viewpoints, the observe "
                                         "stage's 10"):
        workspace_problem(observe, robot, "ra", vptree, everything.solve)
    save_npz(robot / "robot.npz", energy=np.zeros((4, 4)),
             reachable=np.ones(4, dtype=bool), distance_m=np.zeros((4, 4)))
    with pytest.raises(StageError, match="covers 10 viewpoints, the robot stage 4"):
        workspace_problem(observe, robot, "ra", solve=everything.solve)


def test_workspace_problem_uses_the_robot_and_solve_section(workspace: Workspace) -> None:
    cfg = config_from_dict({"solve": {"wrong_declaration_cost_m": 4.0}})
    problem = workspace_problem(workspace.stage_dir("observe"), workspace.stage_dir("robot"),
                                "classifier", workspace.stage_dir("vptree"), cfg.solve)
    assert problem.lambda_ == 4.0
    # the section alone, without a pipeline configuration, builds the same problem
    alone = workspace_problem(workspace.stage_dir("observe"), workspace.stage_dir("robot"),
                              "classifier", workspace.stage_dir("vptree"),
                              SolveConfig(wrong_declaration_cost_m=4.0))
    np.testing.assert_array_equal(alone.move_energy, problem.move_energy)
    assert alone.lambda_ == 4.0 and alone.discount == problem.discount == 0.95
    models, energy, reachable, classes = workspace_arrays(
        workspace.stage_dir("observe"), workspace.stage_dir("robot"), models=["classifier"])
    assert list(models) == ["classifier"] and classes == ["cup", "mug", "bottle"]
    assert models["classifier"].shape == (reachable.size, 3, 3) == (10, 3, 3)
    assert energy.shape == (10, 10)
    assert problem.class_names == ["cup", "mug", "bottle"]
    assert UNREACHABLE not in problem.targets
    assert np.all(np.isfinite(problem.move_energy))


def test_export_workspace_problem(workspace: Workspace, tmp_path: Path) -> None:
    out = tmp_path / "ra.pomdpx"
    result = CliRunner().invoke(pomdp_app, ["export", "--workspace", str(workspace.root),
                                            "--model", "ra", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert f"{V} viewpoints x {C} classes" in result.output
    assert out.read_text().lstrip().startswith("<?xml")
    vptree = CliRunner().invoke(pomdp_app, ["export", "--workspace", str(workspace.root),
                                            "--model", "vptree", "--out", str(out)])
    assert vptree.exit_code == 0, vptree.output
    missing = CliRunner().invoke(pomdp_app, ["export", "--workspace", str(tmp_path / "none"),
                                             "--out", str(out)])
    assert missing.exit_code == 2
    assert "has not been run here" in missing.output


def test_a_stage_given_no_required_upstream_names_it(workspace: Workspace,
                                                    tmp_path: Path) -> None:
    """vptree is optional to the solve stage; robot is not: the error names the stage to run."""
    inputs = StageInputs("solve", observe_dir=workspace.stage_dir("observe"))
    with pytest.raises(StageError, match=r"^stage 'solve' needs the folder of stage 'robot', "
                                         r"which it was not given: run `rapomdp robot -w "
                                         r"WORKSPACE` first"):
        run_solve_stage(config_from_dict({}), inputs, tmp_path / "solve", TEST_CONTEXT)
    assert not (tmp_path / "solve").exists()  # nothing solved, nothing written


def test_solve_stage_records_the_memory_note_and_refuses_what_cannot_fit(
        workspace: Workspace, tmp_path: Path) -> None:
    inputs = StageInputs("solve", observe_dir=workspace.stage_dir("observe"),
                         robot_dir=workspace.stage_dir("robot"))  # no vptree: optional
    out = tmp_path / "solve"
    out.mkdir()
    cfg = config_from_dict({"solve": {"models": ["ra"], "iterations": 3}})
    run_solve_stage(cfg, inputs, out, TEST_CONTEXT)
    assert read_json(out / "solve_summary.json")["ra"]["note"].startswith(
        "upper bound: grid up to resolution")
    tiny = config_from_dict({"solve": {"models": ["ra"], "memory_gb": 0.001}})
    with pytest.raises(StageError, match=r"^solve: the active-recognition problem \(10 "
                                         r"viewpoints x 3 classes, 9 move targets\) needs about "
                                         r"[\d.]+ MB, over the memory cap of 1 MB"):
        run_solve_stage(tiny, inputs, out, TEST_CONTEXT)
    with pytest.raises(ValueError, match="memory_gb"):
        config_from_dict({"solve": {"memory_gb": float("nan")}})


def test_declared_temperatures_are_read_per_model_and_default_to_one(tmp_path) -> None:
    from rapomdp.awareness.artefacts import (
        DECLARED_PREFIX,
        DECLARED_THRESHOLD_PREFIX,
        DECLARED_THRESHOLDS,
        OBSERVATION_FILE,
    )
    from rapomdp.planning.stage import declared_temperatures
    from rapomdp.recognition.artefacts import VPTREE_OBSERVATION_FILE

    (tmp_path / "observe").mkdir()
    (tmp_path / "vptree").mkdir()
    model = np.full((2, 2, 2), 0.5)
    save_npz(tmp_path / "observe" / OBSERVATION_FILE, ra=model, classifier=model,
             **{f"{DECLARED_PREFIX}ra": np.array(0.4),
                f"{DECLARED_THRESHOLD_PREFIX}ra": np.array([0.6, 0.5, 0.3]),
                DECLARED_THRESHOLDS: np.array([0.5, 0.8, 0.9])})
    save_npz(tmp_path / "vptree" / VPTREE_OBSERVATION_FILE, vptree=model,
             declared_temperature=np.array(0.7))
    offered = {"ra": model, "classifier": model, "vptree": model}
    assert declared_temperatures(tmp_path / "observe", offered, tmp_path / "vptree") == {
        "ra": 0.4, "classifier": 1.0, "vptree": 0.7}
    assert declared_temperatures(tmp_path / "observe", {"ra": model}) == {"ra": 0.4}
    # a policy stopping at a threshold: that threshold's a, interpolated, the ends held; the
    # pooled a where a stage fitted no thresholds (the VP-tree here), 1 where it fitted none
    at = declared_temperatures(tmp_path / "observe", offered, tmp_path / "vptree", 0.85)
    assert at == pytest.approx({"ra": 0.4, "classifier": 1.0, "vptree": 0.7})
    assert declared_temperatures(tmp_path / "observe", {"ra": model}, None, 0.99)["ra"] == \
        pytest.approx(0.3)
    assert declared_temperatures(tmp_path / "observe", {"ra": model}, None, 0.8)["ra"] == \
        pytest.approx(0.5)
