"""The stage list: what each stage needs, and unknown names refused."""

import pytest

from rapomdp.config import Config
from rapomdp.pipeline import run_pipeline, stages_up_to
from rapomdp.workspace import Workspace
from tests.conftest import TEST_CONTEXT


def test_stages_up_to_and_unknown_stage_names() -> None:
    assert [s.name for s in stages_up_to("render")] == ["dataset", "render"]
    with pytest.raises(KeyError, match="unknown stage 'rendr'"):
        stages_up_to("rendr")
    with pytest.raises(KeyError, match="unknown stage"):
        run_pipeline(Config(), Workspace("/nonexistent"), force=["nope"], context=TEST_CONTEXT)


def test_the_stages_run_in_an_order_that_honours_their_inputs() -> None:
    from rapomdp.pipeline import STAGES

    seen: set[str] = set()
    for stage in STAGES:
        assert set(stage.inputs) <= seen, stage.name
        seen.add(stage.name)
    assert len(seen) == len(STAGES)
