"""One tiny two-seed study (``vary: train``), killed in seed 1's solve stage and resumed."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

from rapomdp.study.runner import SeedRun, run_study
from rapomdp.study.spec import StudyDataset, StudySpec
from rapomdp.workspace import Workspace
from tests.conftest import TEST_CONTEXT
from tests.experiment.conftest import TINY

#: The tiny closed loop with fewer methods and settings: enough to pool and pair.
TINY_STUDY: dict = {**TINY, "evaluate": {**TINY["evaluate"], "lambdas": [2.0, 6.0]}}


@dataclass
class TinyStudy:
    root: Path
    spec: StudySpec
    interrupted: list[str]   # the stages seed 1 had finished when it was killed
    resumed: list[SeedRun]   # what the second run_study did


@pytest.fixture(scope="session")
def tiny_study(tmp_path_factory: pytest.TempPathFactory) -> TinyStudy:
    root = tmp_path_factory.mktemp("study")
    spec = StudySpec((StudyDataset("tiny", TINY_STUDY),), seeds=(0, 1), vary="train")
    original = Workspace.run

    def killed_in_seed_1_solve(self: Workspace, stage, config, force=False, context=None):
        if self.root.name == "seed-1" and stage.name == "solve":
            raise KeyboardInterrupt
        return original(self, stage, config, force=force, context=context)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(Workspace, "run", killed_in_seed_1_solve)
        with pytest.raises(KeyboardInterrupt):
            run_study(spec, root, TEST_CONTEXT)
    finished = sorted(Workspace(root / "tiny" / "seed-1").manifest()["stages"])
    resumed = run_study(spec, root, TEST_CONTEXT)
    return TinyStudy(root, spec, finished, resumed)
