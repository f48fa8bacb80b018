"""The gymnasium environment on a tiny real workspace (procedural dataset + Panda robot stage)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from rapomdp.config import Config
from rapomdp.data.dataset import load_dataset
from rapomdp.data.renderer import DepthRenderer
from rapomdp.data.test_views import TestViews
from rapomdp.data.training_views import model_poses
from rapomdp.experiment.env import ActiveRecognitionEnv
from rapomdp.experiment.episode import Motion
from rapomdp.geometry.camera import xtion_intrinsics
from rapomdp.pipeline import run_pipeline
from rapomdp.robot.artefacts import load_robot
from rapomdp.workspace import StageError, Workspace
from tests.conftest import TEST_CONTEXT, tiny_config


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> tuple[Workspace, Config]:
    """Dataset and robot stages of the tiny configuration (40x30 camera, 16 viewpoints)."""
    config = tiny_config(solve={"wrong_declaration_cost_m": 1.5})
    ws = Workspace(tmp_path_factory.mktemp("ws"))
    run_pipeline(config, ws, until="dataset", context=TEST_CONTEXT)
    run_pipeline(config, ws, until="robot", context=TEST_CONTEXT)
    (ws.root / "config.yaml").write_text(config.to_yaml())
    return ws, config


@pytest.fixture
def env(tiny: tuple[Workspace, Config]) -> ActiveRecognitionEnv:
    return ActiveRecognitionEnv.from_workspace(tiny[0].root, max_moves=3, seed=7)


def _first_valid_move(env: ActiveRecognitionEnv, mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask[: env.viewpoints])[0])


def test_from_workspace_builds_the_test_models_and_the_robot_motion(tiny, env) -> None:
    ws, config = tiny
    dataset = load_dataset(ws.require("dataset"))
    robot = load_robot(ws.require("robot"))
    tests = dataset.with_role("test")
    assert len(env.scenes) == len(tests) == 3
    assert env.true_classes == [dataset.label(m) for m in tests]
    assert env.class_names == ["cup", "mug", "bicycle"]
    assert env.lambda_ == 1.5
    assert env.action_space.n == 16 + 3
    assert env.observation_space["depth"].shape == (30, 40)
    assert env.observation_space["viewpoint"].n == 16
    np.testing.assert_array_equal(env.motion.reachable, robot["reachable"].astype(bool))
    # moves to or from unreachable viewpoints keep E_M = inf (and are invalid)
    off_diagonal = ~np.eye(16, dtype=bool)
    to_unreachable = off_diagonal & ~env.motion.reachable[None, :]
    assert np.all(np.isinf(env.motion.energy[to_unreachable]))
    assert np.all(np.isfinite(env.motion.energy[np.ix_(env.motion.reachable,
                                                       env.motion.reachable)]))


def test_check_env_passes_for_20_seeds_with_unreachable_viewpoints(tiny) -> None:
    """gymnasium's checker samples actions blindly: with some viewpoints unreachable, the
    no-op rule for actions outside the mask keeps every sample legal."""
    import warnings

    import gymnasium

    for seed in range(20):
        env = gymnasium.make("rapomdp/ActiveRecognition-v0", workspace=tiny[0].root,
                             max_moves=5, seed=seed, render_mode="rgb_array").unwrapped
        assert not env.motion.reachable.all()
        env.action_space.seed(seed)
        with warnings.catch_warnings():
            warnings.filterwarnings("error")  # any checker warning fails the test
            check_env(env)
        assert np.isfinite(env.observation_space["depth"].high).all()


def test_gym_make_builds_the_registered_environment(tiny) -> None:
    import gymnasium

    from rapomdp.experiment.env import ENV_ID

    assert ENV_ID == "rapomdp/ActiveRecognition-v0" and ENV_ID in gymnasium.registry
    env = gymnasium.make(ENV_ID, workspace=tiny[0].root, max_moves=4, render_mode="rgb_array")
    # the module:id form imports the module itself
    again = gymnasium.make(f"rapomdp.experiment.env:{ENV_ID}", workspace=tiny[0].root)
    assert isinstance(again.unwrapped, ActiveRecognitionEnv)
    assert isinstance(env.unwrapped, ActiveRecognitionEnv)
    assert env.unwrapped.max_moves == 4 and env.render_mode == "rgb_array"
    obs, _ = env.reset(seed=0)
    assert obs["depth"].shape == (30, 40)
    with pytest.raises(ValueError, match="render_mode 'human' is not one of"):
        ActiveRecognitionEnv.from_workspace(tiny[0].root, render_mode="human")


def test_sampled_actions_never_raise_and_invalid_ones_are_penalised_no_ops(env) -> None:
    env.action_space.seed(3)
    invalid_seen = 0
    for episode in range(15):
        obs, info = env.reset(seed=episode)
        while True:
            action = int(env.action_space.sample())
            before, mask = obs, info["action_mask"]
            obs, reward, terminated, truncated, info = env.step(action)
            assert info["invalid"] == (not mask[action])
            if info["invalid"]:
                invalid_seen += 1
                assert reward == -env.invalid_penalty and not terminated
                assert obs["viewpoint"] == before["viewpoint"]
                np.testing.assert_array_equal(obs["depth"], before["depth"])
                assert "cannot reach it" in info["invalid_reason"] or \
                    "already there" in info["invalid_reason"]
            if terminated or truncated:
                break
        assert info["steps"] <= 3 and "true_class" in info
    assert invalid_seen > 0
    # the default penalty is the most a valid move costs: an invalid action never pays
    reach = env.motion.reachable
    assert env.invalid_penalty == pytest.approx(
        np.max(env.motion.energy[np.ix_(reach, reach)][np.isfinite(
            env.motion.energy[np.ix_(reach, reach)])]))


def test_render_shows_the_depth_image_and_the_current_viewpoint(tiny) -> None:
    env = ActiveRecognitionEnv.from_workspace(tiny[0].root, seed=0, render_mode="rgb_array")
    obs, info = env.reset(seed=0, options={"model": 0})
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.shape == (120, 160 + 120, 3)  # 40x30 scaled x4
    hit = np.repeat(np.repeat(obs["depth"] > 0, 4, axis=0), 4, axis=1)
    depth_part = frame[:, :160]
    assert (depth_part[~hit] == 255).all() and (depth_part[hit] != 255).any(axis=-1).all()
    orange = np.array([230, 159, 0], dtype=np.uint8)
    assert (frame[:, 160:] == orange).all(axis=-1).any()  # the current viewpoint is drawn
    move = int(np.flatnonzero(info["action_mask"][: env.viewpoints])[0])
    env.step(move)
    blue = np.array([0, 114, 178], dtype=np.uint8)
    assert (env.render()[:, 160:] == blue).all(axis=-1).any()  # the start, now visited
    assert ActiveRecognitionEnv.from_workspace(tiny[0].root).render() is None


def test_seeded_reset_is_reproducible_and_draws_a_reachable_start(env) -> None:
    first, info_a = env.reset(seed=11)
    second, info_b = env.reset(seed=11)
    np.testing.assert_array_equal(first["depth"], second["depth"])
    assert first["viewpoint"] == second["viewpoint"] == info_a["viewpoint"]
    assert env.motion.reachable[first["viewpoint"]]
    assert first["depth"].dtype == np.float32 and first["depth"].shape == (30, 40)
    assert info_a["moves"] == 0 and info_a["energy"] == 0.0 and info_a["distance_m"] == 0.0
    starts = {env.reset(seed=s)[0]["viewpoint"] for s in range(20)}
    assert len(starts) > 1 and all(env.motion.reachable[v] for v in starts)


def test_depth_is_the_scene_render_at_the_viewpoint(tiny, env) -> None:
    ws, config = tiny
    dataset = load_dataset(ws.require("dataset"))
    model = dataset.with_role("test")[1]
    start = int(np.flatnonzero(env.motion.reachable)[2])
    obs, _ = env.reset(seed=0, options={"model": 1, "start": start})
    scene = env.scenes[1]
    np.testing.assert_array_equal(obs["depth"], scene.look(start, np.random.default_rng(5)))
    renderer = DepthRenderer(dataset.mesh(model), xtion_intrinsics(40, 30))
    poses = model_poses(model, 16, config.viewpoints.radius_m, hemisphere=True)
    expected = renderer.render(poses[start])
    np.testing.assert_array_equal(obs["depth"], expected)
    assert (expected > 0).any()


def test_a_move_costs_the_energy_and_renders_the_target(env) -> None:
    obs, info = env.reset(seed=3, options={"model": 0})
    v = obs["viewpoint"]
    j = _first_valid_move(env, info["action_mask"])
    obs2, reward, terminated, truncated, info2 = env.step(j)
    assert reward == -env.motion.energy[v, j] and reward < 0
    assert not terminated and not truncated
    assert obs2["viewpoint"] == info2["viewpoint"] == j
    np.testing.assert_array_equal(obs2["depth"], env.scenes[0].look(j, np.random.default_rng()))
    assert info2["moves"] == 1
    assert info2["energy"] == pytest.approx(env.motion.energy[v, j])
    assert info2["distance_m"] == pytest.approx(env.motion.distance_m[v, j])
    assert "true_class" not in info2 and "correct" not in info2


def test_right_declaration_gives_zero_and_a_wrong_one_minus_lambda(env) -> None:
    truth = env.true_classes[2]
    obs, _ = env.reset(seed=0, options={"model": 2})
    obs2, reward, terminated, truncated, info = env.step(env.viewpoints + truth)
    assert (reward, terminated, truncated) == (0.0, True, False)
    assert info["declared"] == truth and info["correct"] is True and info["true_class"] == truth
    assert info["steps"] == 1 and info["invalid"] is False
    np.testing.assert_array_equal(obs2["depth"], obs["depth"])
    assert not info["action_mask"].any()
    with pytest.raises(RuntimeError, match="episode is over"):
        env.step(env.viewpoints + truth)
    env.reset(seed=0, options={"model": 2})
    wrong = (truth + 1) % env.classes
    _, reward, terminated, _, info = env.step(env.viewpoints + wrong)
    assert reward == -1.5 and terminated and info["correct"] is False
    assert info["declared"] == wrong and info["true_class"] == truth


def test_actions_outside_the_space_raise(env) -> None:
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"action 19 is not in \[0, 19\)"):
        env.step(19)
    with pytest.raises(ValueError, match="action -1"):
        env.step(-1)


def test_action_mask_excludes_unreachable_and_current_viewpoints(env) -> None:
    obs, info = env.reset(seed=4)
    mask = info["action_mask"]
    expected = np.concatenate([env.motion.reachable, np.ones(3, dtype=bool)])
    expected[obs["viewpoint"]] = False
    np.testing.assert_array_equal(mask, expected)
    unreachable = int(np.flatnonzero(~env.motion.reachable)[0])
    _, _, _, _, info = env.step(unreachable)
    assert info["invalid"] and info["invalid_reason"] == (
        f"move to viewpoint {unreachable}: the arm cannot reach it")
    _, _, _, _, info = env.step(obs["viewpoint"])
    assert info["invalid"] and "the camera is already there" in info["invalid_reason"]
    assert info["moves"] == 0 and info["steps"] == 2 and info["energy"] == 0.0


def test_depth_is_bounded_by_the_farthest_corner_seen_and_lies_within_it(tiny, env) -> None:
    from rapomdp.experiment.env import DEPTH_NOISE_MARGIN

    high = env.observation_space["depth"].high
    assert np.all(high == np.float32(env.max_depth_m))
    # the bound: the farthest bounding-box corner from any camera, plus the noise margin
    corners = []
    for scene in env.scenes:
        (x0, y0, z0), (x1, y1, z1) = scene.renderer.mesh.bounds
        box = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)])
        corners.append(np.linalg.norm(scene.poses[:, None, :3, 3] - box[None], axis=2).max())
    assert env.max_depth_m == pytest.approx(max(corners) * (1 + DEPTH_NOISE_MARGIN))
    # about rho + the object's size: far below a sensor's range, above every hit
    assert 0.6 < env.max_depth_m < 1.2
    for seed in range(5):
        obs, _ = env.reset(seed=seed)
        assert env.observation_space.contains(obs) and obs["depth"].max() < env.max_depth_m


def test_action_masks_is_the_mask_and_revisit_off_masks_visited_viewpoints(tiny) -> None:
    env = ActiveRecognitionEnv.from_workspace(tiny[0].root, max_moves=5, seed=2, revisit=False)
    obs, info = env.reset(seed=2)
    start = obs["viewpoint"]
    np.testing.assert_array_equal(env.action_masks(), info["action_mask"])
    target = _first_valid_move(env, info["action_mask"])
    _, _, _, _, info = env.step(target)
    assert not info["action_mask"][start] and not info["action_mask"][target]
    np.testing.assert_array_equal(env.action_masks(), info["action_mask"])
    _, reward, _, _, info = env.step(start)
    assert info["invalid"] and reward == -env.invalid_penalty
    assert info["invalid_reason"] == (f"move to viewpoint {start}: already visited (revisit "
                                      "is off)")
    # the default keeps revisits valid
    again = ActiveRecognitionEnv.from_workspace(tiny[0].root, max_moves=5, seed=2)
    again.reset(seed=2)
    again.step(target)
    assert again.action_masks()[start]


def test_planner_actions_convert_both_ways(env) -> None:
    from rapomdp.planning.policy import ARAction

    assert env.action_index(ARAction("move", 5)) == 5
    assert env.action_index(ARAction("declare", 2)) == 16 + 2
    assert env.ar_action(18) == ARAction("declare", 2) and env.ar_action(3) == ARAction("move", 3)


def test_truncated_after_max_moves(env) -> None:
    obs, info = env.reset(seed=1)
    total = 0.0
    for move in range(1, 4):
        obs, reward, terminated, truncated, info = env.step(
            _first_valid_move(env, info["action_mask"]))
        total -= reward
        assert not terminated and truncated == (move == 3)
        assert ("true_class" in info) == truncated  # the truth only once the episode ends
    assert info["moves"] == 3 and info["energy"] == pytest.approx(total)
    assert info["true_class"] == env.true_classes[info["model"]]
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(env.viewpoints)


def test_reset_options_are_validated(env) -> None:
    unreachable = int(np.flatnonzero(~env.motion.reachable)[0])
    with pytest.raises(ValueError, match="start viewpoint .* is not reachable"):
        env.reset(options={"start": unreachable})
    with pytest.raises(ValueError, match=r"model 3 is not a scene index in \[0, 3\)"):
        env.reset(options={"model": 3})
    with pytest.raises(ValueError, match=r"start viewpoint 16 is not in \[0, 16\)"):
        env.reset(options={"start": 16})
    with pytest.raises(ValueError, match="unknown option"):
        env.reset(options={"class": 0})


def test_noise_draws_from_the_env_rng(tiny) -> None:
    ws, config = tiny
    base = ActiveRecognitionEnv.from_workspace(ws.root, seed=0)
    noisy = config.render.noise.model_copy(update={"enabled": True})
    scenes = [TestViews(s.renderer, s.poses, noisy) for s in base.scenes]
    env = ActiveRecognitionEnv(scenes, base.true_classes, base.class_names, base.motion, 2.0)
    a, _ = env.reset(seed=5, options={"model": 0})
    b, _ = env.reset(seed=5, options={"model": 0})
    c, _ = env.reset(seed=6, options={"model": 0, "start": a["viewpoint"]})
    np.testing.assert_array_equal(a["depth"], b["depth"])
    assert not np.array_equal(a["depth"], c["depth"])


def test_constructor_rejects_inconsistent_inputs(env) -> None:
    motion = Motion(env.motion.energy[:4, :4], env.motion.distance_m[:4, :4],
                    env.motion.reachable[:4])
    with pytest.raises(ValueError, match="16 viewpoint poses, the motion 4"):
        ActiveRecognitionEnv(env.scenes, env.true_classes, env.class_names, motion, 1.0)
    with pytest.raises(ValueError, match=r"true classes \[5\]"):
        ActiveRecognitionEnv(env.scenes, [0, 1, 5], env.class_names, env.motion, 1.0)


def test_from_workspace_needs_the_robot_stage(tmp_path: Path) -> None:
    config = tiny_config()
    ws = Workspace(tmp_path / "ws")
    run_pipeline(config, ws, until="dataset", context=TEST_CONTEXT)
    (ws.root / "config.yaml").write_text(config.to_yaml())
    with pytest.raises(StageError, match="stage 'robot' has not been run"):
        ActiveRecognitionEnv.from_workspace(ws.root)


def _docs_env_blocks() -> list[str]:
    """The python code blocks of docs/experiment.md's environment section."""
    text = (Path(__file__).parents[2] / "docs" / "experiment.md").read_text()
    section = text.split("## Gymnasium environment", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```python\n(.*?)```", section, flags=re.S)


def test_the_docs_loops_run_as_written(pipeline_workspace, capsys) -> None:
    """The random-agent and the policy-driven loops of the docs, on a whole tiny workspace
    (its Panda reaches only some viewpoints)."""
    ws, _ = pipeline_workspace
    blocks = _docs_env_blocks()
    assert len(blocks) == 3 and "action_space.sample()" in blocks[0]
    assert "forbidden=visited" in blocks[1] and "policy.lookahead_act(" in blocks[1]
    for block in blocks[:2]:
        assert block.count('"runs/exp1"') == 1
        namespace: dict = {}
        exec(compile(block.replace('"runs/exp1"', repr(str(ws.root))), "docs", "exec"),
             namespace)
        printed = capsys.readouterr().out.split()
        env = namespace["env"].unwrapped
        assert namespace["terminated"] or namespace["truncated"]
        assert namespace["info"]["true_class"] in range(env.classes)
        assert len(printed) == (5 if block is blocks[0] else 4)
    # the policy loop never revisited a viewpoint and moved only where the arm reaches
    path = env._path
    assert len(set(path)) == len(path) and env.motion.reachable[path].all()
    assert printed[0] in env.class_names


def test_the_docs_maskable_ppo_example_trains_and_acts_within_the_mask(pipeline_workspace,
                                                                       capsys) -> None:
    """docs/experiment.md's MaskablePPO example: a few hundred steps on the tiny workspace."""
    ws, _ = pipeline_workspace
    block = _docs_env_blocks()[2]
    assert "MaskablePPO(" in block and "model.learn(total_timesteps=256)" in block
    namespace: dict = {}
    exec(compile(block.replace('"runs/exp1"', repr(str(ws.root))), "docs", "exec"), namespace)
    action, valid = capsys.readouterr().out.split()
    assert valid == "True" and 0 <= int(action) < namespace["env"].action_space.n
    assert namespace["model"].num_timesteps == 256


def test_actions_are_taken_as_action_space_contains_takes_them(env) -> None:
    for action in (np.array(3), np.int64(3), np.array(3, dtype=np.uint8)):
        env.reset(seed=0)
        assert env.action_space.contains(action)
        env.step(action)
    env.reset(seed=0)
    for action in (True, 3.0, np.array([3]), np.array(3.0), "3"):
        with pytest.raises(ValueError, match="is not in"):
            env.step(action)  # type: ignore[arg-type]


@pytest.mark.parametrize("options", [{"start": True}, {"start": 2.0}, {"model": True},
                                     {"model": np.array(0.5)}])
def test_reset_refuses_booleans_and_fractions_by_name(env, options: dict) -> None:
    name = "start viewpoint" if "start" in options else "model"
    with pytest.raises(ValueError, match=f"reset: {name} .* \\(a whole number\\)"):
        env.reset(options=options)
    env.reset(options={"model": np.array(1)})


@pytest.mark.parametrize("max_moves", [float("inf"), float("nan"), 2.7, True, 0])
def test_max_moves_must_be_a_whole_number(tiny, max_moves: object) -> None:
    with pytest.raises(ValueError, match="max_moves must be a whole number of at least 1"):
        ActiveRecognitionEnv.from_workspace(tiny[0].root, max_moves=max_moves)  # type: ignore[arg-type]
