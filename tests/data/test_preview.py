"""The contact sheet refuses a camera that would draw blank tiles (NaN angles, |elevation| > 90)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rapomdp.data.preview import contact_sheet
from rapomdp.geometry.camera import xtion_intrinsics


@pytest.mark.parametrize(("options", "fragment"), [
    ({"elevation_deg": float("nan")}, "elevation_deg must be finite"),
    ({"azimuth_deg": float("inf")}, "azimuth_deg must be finite"),
    ({"elevation_deg": 91.0}, "in [-90, 90] degrees"),
    ({"radius_m": 0.0}, "must be positive")])
def test_a_camera_that_draws_nothing_is_refused(options: dict, fragment: str,
                                                tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=fragment.replace("[", r"\[").replace("]", r"\]")):
        contact_sheet(None, xtion_intrinsics(32, 24), tmp_path / "s.png",  # type: ignore[arg-type]
                      **options)
    assert not (tmp_path / "s.png").exists()
