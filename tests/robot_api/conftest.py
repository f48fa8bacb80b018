"""Fixtures of the robot API's tests: the closed-loop tests' tiny finished workspace (every stage
run once per session) and one recogniser of its RA-POMDP per module."""

from __future__ import annotations

import pytest

from rapomdp.robot_api.recognizer import ActiveRecognizer
from tests.experiment.conftest import pipeline_workspace  # noqa: F401  (the shared fixture)


@pytest.fixture(scope="module")
def recognizer(pipeline_workspace) -> ActiveRecognizer:  # noqa: F811
    """The tiny workspace's RA-POMDP, loaded once per module."""
    ws, _ = pipeline_workspace
    return ActiveRecognizer.load(ws.root, "ra")
