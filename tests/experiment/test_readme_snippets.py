"""The README's Python snippets run as written (issue 15: a library that works as documented).

Each ```python block of README.md is executed in a folder where ``runs/exp1`` is the tiny
pipeline workspace of the closed-loop tests and ``Tiger.pomdp`` is the classic problem; the
planning block's free names (the arrays of your own problem, a viewpoint, a belief, a label) are
given a small problem first, as a reader's own code would."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest

from rapomdp.awareness.variants import RA_VARIANTS
from tests.planning.planning_fixtures import TIGER

README = Path(__file__).resolve().parents[2] / "README.md"


def python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


@pytest.fixture
def reader_folder(pipeline_workspace, tmp_path: Path):
    ws, _ = pipeline_workspace
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "exp1").symlink_to(ws.root)
    (tmp_path / "Tiger.pomdp").write_text(TIGER)
    before = Path.cwd()
    os.chdir(tmp_path)
    yield tmp_path
    os.chdir(before)


def test_the_readme_has_its_three_python_snippets() -> None:
    blocks = python_blocks(README.read_text())
    assert len(blocks) == 3
    assert "DepthRenderer" in blocks[0] and "solve_pomdp" in blocks[1] and "gym.make" in blocks[2]


def test_rendering_and_classifying_as_written(reader_folder) -> None:
    namespace: dict = {}
    exec(python_blocks(README.read_text())[0], namespace)
    assert namespace["depth"].shape == (128, 120, 160)
    assert namespace["points"].shape[1] == 3 and len(namespace["points"]) > 1000
    probabilities = namespace["probabilities"]
    assert probabilities.shape == (128, 3)  # the tiny workspace's three classes
    np.testing.assert_allclose(probabilities.sum(axis=1), 1.0, atol=1e-5)


def test_planning_as_written(reader_folder) -> None:
    from rapomdp.planning import benchmark_problem

    given = benchmark_problem(12, 3, seed=1)
    namespace: dict = {"P": given.observation_model, "E": given.move_energy,
                       "reachable": given.reachable, "viewpoint": 0,
                       "belief": np.full(3, 1 / 3), "label": 1}
    block = python_blocks(README.read_text())[1]
    exec(block.replace("timeout=10", "timeout=2").replace("timeout=30", "timeout=2"), namespace)
    tiger = namespace["tiger"]
    assert tiger.lower <= tiger.upper + 1e-9
    assert namespace["action"].kind in ("move", "declare")
    assert namespace["belief"].shape == (3,) and abs(namespace["belief"].sum() - 1) < 1e-9
    assert (reader_folder / "ar.pomdpx").read_text().startswith("<?xml")


def test_the_environment_as_written(reader_folder) -> None:
    namespace: dict = {}
    exec(python_blocks(README.read_text())[2], namespace)
    obs, info = namespace["obs"], namespace["info"]
    assert set(obs) == {"depth", "viewpoint"} and obs["depth"].ndim == 2
    assert "action_mask" in info and "invalid" in info


DOCS = README.parent / "docs"


def test_the_planning_docs_run_as_written(reader_folder) -> None:
    from rapomdp.planning import benchmark_problem

    given = benchmark_problem(10, 3, seed=2)
    namespace: dict = {"P": given.observation_model, "E": given.move_energy,
                       "reach": given.reachable, "viewpoint": 0, "belief": np.full(3, 1 / 3),
                       "label": 2, "flat_belief": np.array([0.5, 0.5])}
    block, = python_blocks((DOCS / "planning.md").read_text())
    exec(block.replace("timeout=30", "timeout=2").replace("timeout=10", "timeout=2"), namespace)
    assert namespace["flat"].lower <= namespace["flat"].upper + 1e-9
    assert (reader_folder / "policy_ra.npz").exists() and (reader_folder / "ar.pomdpx").exists()
    assert namespace["a"].kind in ("move", "declare")


def test_the_recognition_docs_run_as_written(reader_folder) -> None:
    from rapomdp.data.meshes import normalise_mesh
    from rapomdp.data.procedural import generate_model
    from rapomdp.data.renderer import DepthRenderer
    from rapomdp.geometry import look_at_many, viewpoints, xtion_intrinsics

    mesh = normalise_mesh(generate_model("cup", seed=0, index=0), radius_m=0.2)
    centre = np.array([0.0, 0.0, mesh.bounds[1, 2] / 2])
    poses = look_at_many(viewpoints(4, 0.6, hemisphere=True, centre=centre), centre)
    namespace: dict = {"depth_images": DepthRenderer(mesh, xtion_intrinsics(80, 60)).render(poses)}
    block, = python_blocks((DOCS / "recognition.md").read_text())
    exec(block, namespace)
    assert namespace["probs"].shape == (4, len(namespace["clf"].classes))
    assert namespace["logits"].shape == (4, len(namespace["clf"].classes))


def test_the_robot_docs_run_as_written(reader_folder) -> None:
    namespace: dict = {}
    block, = python_blocks((DOCS / "robot.md").read_text())
    exec(block, namespace)
    assert namespace["result"].reachable.shape == (128,)
    assert namespace["arrays"]["reachable"].dtype == bool or namespace["arrays"]["reachable"].size


def test_the_awareness_docs_run_as_written(reader_folder) -> None:
    namespace: dict = {}
    block, choices = python_blocks((DOCS / "awareness.md").read_text())
    exec(block, namespace)
    assert namespace["pixels"].shape == namespace["depth"].shape
    assert namespace["score"].shape == (16,) and np.nanmax(namespace["score"]) <= 1.0
    assert namespace["likelihood"].shape == (3,) and (namespace["likelihood"] > 0).all()
    similarity = namespace["similarity"]  # ra_transfer's kernel: 1 on the diagonal
    assert similarity.shape[1] == similarity.shape[2]
    assert np.allclose(np.diagonal(similarity, 0, 1, 2), 1.0, atol=1e-5)
    # the held-out choices remade on one fold's evidence
    exec(choices, namespace)
    part, chosen, groups = namespace["part"], namespace["chosen"], namespace["groups"]
    assert len(part.labels) > 0 and (len(groups) == 1 or groups[-1] not in part.groups)
    assert chosen.variant in RA_VARIANTS and chosen.choice.reason
    assert chosen.single_view["ra"] is chosen.single_view[f"ra_{chosen.variant}"]
    assert chosen.temperatures["ra"] > 0


def test_the_cluster_snippets_are_valid_python_for_their_libraries() -> None:
    """docs/scale-out.md's two snippets need a Slurm or Kubernetes cluster (dask-jobqueue,
    dask-kubernetes), which no test machine has: they are compiled, and their imports named."""
    blocks = python_blocks((DOCS / "scale-out.md").read_text())
    assert len(blocks) == 2
    for block in blocks:
        compile(block, "scale-out.md", "exec")
    assert "from dask_jobqueue import SLURMCluster" in blocks[0]
    assert "from dask_kubernetes.operator import KubeCluster" in blocks[1]
    assert all("cluster.scheduler_address" in block for block in blocks)


def test_every_python_snippet_of_the_docs_is_covered() -> None:
    counts = {p.name: len(python_blocks(p.read_text())) for p in sorted(DOCS.glob("*.md"))}
    covered = {"awareness.md": 2, "experiment.md": 3, "planning.md": 1, "recognition.md": 1,
               "robot.md": 1, "scale-out.md": 2}
    assert {name: n for name, n in counts.items() if n} == covered
