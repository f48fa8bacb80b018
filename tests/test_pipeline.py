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


def test_unknown_stage_names_get_a_did_you_mean() -> None:
    from rapomdp.pipeline import unknown_stages_message

    assert unknown_stages_message(["evalute"]).startswith(
        "unknown stage 'evalute' (did you mean 'evaluate'?); stages are: dataset, render")
    assert unknown_stages_message(["zzz", "rendr"]).startswith(
        "unknown stages 'zzz', 'rendr' (did you mean 'render'?); stages are:")
    with pytest.raises(KeyError, match="did you mean 'observe'"):
        stages_up_to("obsreve")


def test_the_stage_graph_loads_no_stage_code() -> None:
    """Reading the graph (``rapomdp status``, staleness, keys) imports no torch, arm, renderer or
    plotting: each stage's code is imported when it runs."""
    from tests.test_architecture import loaded_modules

    modules = loaded_modules("import rapomdp.pipeline")
    assert [m for m in ("torch", "roboticstoolbox", "trimesh", "matplotlib", "sklearn")
            if m in modules] == []
    assert not [m for m in modules if m.endswith((".stage", ".vptree_stage", ".evaluation",
                                                  ".report"))]
