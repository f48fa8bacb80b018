"""The scene: frames and their transforms."""

from __future__ import annotations

import numpy as np

from rapomdp.robot.arm import FLANGE_LINK
from rapomdp.robot.scene import invert, transform


def test_transform_round_trip() -> None:
    pose = transform([0.1, -0.2, 0.3], [0.3, -0.7, 1.9])
    np.testing.assert_allclose(invert(pose) @ pose, np.eye(4), atol=1e-12)
    assert FLANGE_LINK == "panda_link8"
