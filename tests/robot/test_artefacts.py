"""The robot stage's artefacts read back: arrays checked for shape, the summary line."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rapomdp.io import load_npz, write_json_atomic
from rapomdp.robot.artefacts import ROBOT_ARRAYS, describe, load_robot, load_robot_summary


def test_load_robot_refuses_a_wrong_file(tmp_path: Path) -> None:
    from rapomdp.io import ArtefactError, save_npz

    save_npz(tmp_path / ROBOT_ARRAYS, reachable=np.ones(3, dtype=bool))
    with pytest.raises(ArtefactError, match="missing arrays"):
        load_robot(tmp_path)
    assert set(load_npz(tmp_path / ROBOT_ARRAYS)) == {"reachable"}


def test_the_summary_reads_back_and_describes_itself(tmp_path: Path) -> None:
    summary = {"viewpoints": 16, "reachable": 9, "reachable_fraction": 0.5625,
               "ik_seconds": 1.25, "manipulability": {"min": 0.02, "median": 0.08, "max": 0.11}}
    write_json_atomic(tmp_path / "robot.json", summary)
    assert load_robot_summary(tmp_path) == summary
    assert describe(summary) == ("9/16 viewpoints reachable (56 %), IK 1.25 s, manipulability "
                                 "0.020-0.110 (median 0.080)")
