"""Seeds and configurations share exactly the stages whose keys match; a killed study resumes
where it stopped."""

from __future__ import annotations

from pathlib import Path

from rapomdp.pipeline import STAGE_NAMES, planned_keys
from rapomdp.study.runner import run_study, seed_workspace, shared_across, shared_stages
from rapomdp.study.spec import StudyDataset, StudySpec
from rapomdp.workspace import Workspace
from tests.conftest import TEST_CONTEXT
from tests.study.conftest import TINY_STUDY, TinyStudy

#: What a classifier's seed does not reach: the meshes, renders, the robot, the VP-tree.
UNTRAINED = {"dataset", "render", "xrho", "robot", "vptree"}


def test_vary_train_shares_the_stages_the_classifier_does_not_reach() -> None:
    spec = StudySpec((StudyDataset("tiny", TINY_STUDY),), seeds=(0, 1, 2), vary="train")
    dataset = spec.datasets[0]
    keys = {s: planned_keys(spec.config(dataset, s)) for s in spec.seeds}
    equal = {name for name in STAGE_NAMES if keys[0][name] == keys[1][name] == keys[2][name]}
    assert equal == UNTRAINED
    assert shared_stages(spec, dataset) == {0: {}, 1: dict.fromkeys(sorted(UNTRAINED), 0),
                                            2: dict.fromkeys(sorted(UNTRAINED), 0)}


def test_vary_all_shares_nothing() -> None:
    spec = StudySpec((StudyDataset("tiny", TINY_STUDY),), seeds=(0, 1), vary="all")
    assert shared_stages(spec, spec.datasets[0]) == {0: {}, 1: {}}
    assert spec.config(spec.datasets[0], 1).seed == 1
    assert spec.config(spec.datasets[0], 1).train.seed is None


def test_seeds_hold_shared_stages_under_the_same_keys(tiny_study: TinyStudy) -> None:
    first = Workspace(tiny_study.root / "tiny" / "seed-0").manifest()["stages"]
    second = Workspace(tiny_study.root / "tiny" / "seed-1").manifest()["stages"]
    assert set(first) == set(second) == set(STAGE_NAMES)
    for name in second:
        same = first[name]["key"] == second[name]["key"]
        assert same == (name in UNTRAINED), name
        assert bool(second[name].get("shared_from")) == (name in UNTRAINED), name
        assert not first[name].get("shared_from")
    for name in UNTRAINED:  # hard links: the very same files
        ws0 = seed_workspace(tiny_study.root, "tiny", 0).stage_dir(name)
        ws1 = seed_workspace(tiny_study.root, "tiny", 1).stage_dir(name)
        some = next(p for p in sorted(ws0.rglob("*")) if p.is_file() and p.name != "stage.json")
        assert (ws1 / some.relative_to(ws0)).samefile(some)
    # and the trained classifiers differ
    assert first["train"]["config"]["train"]["seed"] == 0
    assert second["train"]["config"]["train"]["seed"] == 1


def test_a_killed_study_resumes_without_redoing_finished_work(tiny_study: TinyStudy) -> None:
    assert "solve" not in tiny_study.interrupted and "observe" in tiny_study.interrupted
    by_seed = {run.seed: run for run in tiny_study.resumed}
    assert all(r.cached for r in by_seed[0].results)  # the finished seed: nothing redone
    ran = {r.name for r in by_seed[1].results if not r.cached}
    assert ran == {"solve", "learn", "evaluate", "report"}  # learn: a no-op without 'learned'
    assert tiny_study.spec == StudySpec.from_yaml(
        (tiny_study.root / "study.yaml").read_text())


def test_on_a_dask_scheduler_each_seed_is_one_task(tiny_study: TinyStudy) -> None:
    """The finished tiny study through a local Dask cluster: one task per seed, each seed's
    stages as the local run recorded them (all current, so nothing is redone)."""
    import dataclasses

    import distributed

    from rapomdp.study.runner import run_study
    from tests.conftest import TEST_CONTEXT

    before = {s: Workspace(tiny_study.root / "tiny" / f"seed-{s}").manifest() for s in (0, 1)}
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        context = dataclasses.replace(TEST_CONTEXT, scheduler=cluster.scheduler_address)
        runs = run_study(tiny_study.spec, tiny_study.root, context)
    assert [(r.dataset, r.seed) for r in runs] == [("tiny", 0), ("tiny", 1)]
    assert all(result.cached for run in runs for result in run.results)
    assert [r.name for r in runs[1].results] == STAGE_NAMES
    for s in (0, 1):
        assert Workspace(tiny_study.root / "tiny" / f"seed-{s}").manifest() == before[s]


def test_a_folder_that_is_no_study_is_refused_before_anything_is_written(tmp_path) -> None:
    import pytest

    from rapomdp.config import ConfigError
    from rapomdp.study.runner import run_study

    (tmp_path / "notes.txt").write_text("mine")
    spec = StudySpec((StudyDataset("tiny", TINY_STUDY),), seeds=(0,), vary="all")
    with pytest.raises(ConfigError, match="not a rapomdp study .no study.yaml. and not empty"):
        run_study(spec, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.txt"]


def test_configurations_that_differ_from_the_train_stage_on_share_what_comes_before() -> None:
    longer = {**TINY_STUDY, "train": {**TINY_STUDY["train"], "epochs": 3}}
    spec = StudySpec((StudyDataset("tiny", TINY_STUDY), StudyDataset("longer", longer)),
                     seeds=(0, 1), vary="all")
    plan = shared_across(spec)
    assert plan[("tiny", 0)] == {} and plan[("tiny", 1)] == {}  # vary all: seeds share nothing
    assert plan[("longer", 0)] == dict.fromkeys(UNTRAINED, ("tiny", 0))
    assert plan[("longer", 1)] == dict.fromkeys(UNTRAINED, ("tiny", 1))
    # within one configuration, the seeds' plan is the one shared_stages gives
    assert shared_stages(spec, spec.datasets[1]) == {0: {}, 1: {}}


def test_a_study_of_two_configurations_makes_their_common_stages_once(tmp_path) -> None:
    longer = {**TINY_STUDY, "train": {**TINY_STUDY["train"], "epochs": 3}}
    spec = StudySpec((StudyDataset("tiny", TINY_STUDY), StudyDataset("longer", longer)),
                     seeds=(0,), vary="all")
    runs = run_study(spec, tmp_path, TEST_CONTEXT)
    adopted = {r.name: r.shared_from for r in runs[1].results if r.shared_from}
    assert set(adopted) == UNTRAINED
    assert all(Path(source).name == "seed-0" and Path(source).parent.name == "tiny"
               for source in adopted.values())
    for name in UNTRAINED:  # hard links: the very same files
        mine = seed_workspace(tmp_path, "longer", 0).stage_dir(name)
        theirs = seed_workspace(tmp_path, "tiny", 0).stage_dir(name)
        some = next(p for p in sorted(theirs.rglob("*"))
                    if p.is_file() and p.name != "stage.json")
        assert (mine / some.relative_to(theirs)).samefile(some)
    first, second = (Workspace(tmp_path / d / "seed-0").manifest()["stages"]
                     for d in ("tiny", "longer"))
    assert first["train"]["key"] != second["train"]["key"]
