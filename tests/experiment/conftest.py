"""Fixtures of the closed-loop tests."""

from __future__ import annotations

import pytest

from rapomdp.experiment.episode import Motion
from tests.experiment.scripted import scripted_motion


@pytest.fixture
def motion() -> Motion:
    return scripted_motion()
