import numpy as np
import pytest

from rapomdp.config import NoiseConfig
from rapomdp.data.noise import apply_sensor_noise, axial_sigma_m, quantise_depth
from rapomdp.geometry.camera import xtion_intrinsics


def test_axial_sigma_follows_nguyen_et_al() -> None:
    assert axial_sigma_m(np.array(0.4), np.array(0.0)) == pytest.approx(0.0012)
    assert axial_sigma_m(np.array(1.0), np.array(0.5)) == pytest.approx(0.0012 + 0.0019 * 0.36)
    theta = np.radians(70.0)
    expected = 0.0012 + 0.0019 * 0.04 + 0.0001 * theta**2 / (np.sqrt(0.6) *
                                                             (np.pi / 2 - theta) ** 2)
    assert axial_sigma_m(np.array(0.6), np.array(theta)) == pytest.approx(expected)


def test_quantisation_is_on_eighth_pixel_disparity_steps() -> None:
    depth = np.linspace(0.3, 1.5, 500)
    q = quantise_depth(depth, 0.075, 8)
    fb = xtion_intrinsics().fx * 0.075
    steps = fb * 8 / q
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)
    np.testing.assert_allclose(quantise_depth(q, 0.075, 8), q)
    # the error is at most half a step: dz = z^2 / (f b 8) / 2
    assert np.all(np.abs(q - depth) <= depth**2 / (fb * 8) / 2 + 1e-12)
    assert quantise_depth(np.zeros(3), 0.075, 8).tolist() == [0, 0, 0]


def test_noise_statistics_dropouts_and_background() -> None:
    rng = np.random.default_rng(0)
    depth = np.full((200, 200), 0.6, dtype=np.float32)
    depth[:, :10] = 0.0
    angles = np.zeros_like(depth, dtype=np.float64)
    angles[:, 100:] = np.radians(88.0)
    cfg = NoiseConfig(enabled=True, quantisation=False)
    noisy = apply_sensor_noise(depth, angles, cfg, rng)
    assert np.all(noisy[:, :10] == 0)
    assert np.all(noisy[:, 100:] == 0), "grazing pixels beyond missing_full_deg are dropped"
    facing = noisy[:, 10:100]
    assert np.all(facing > 0)
    assert facing.std() == pytest.approx(0.0012 + 0.0019 * 0.04, rel=0.05)
    assert facing.mean() == pytest.approx(0.6, abs=1e-4)


def test_everything_off_returns_the_clean_depth() -> None:
    depth = np.random.default_rng(1).uniform(0.4, 0.8, (8, 8)).astype(np.float32)
    cfg = NoiseConfig(enabled=True, axial=False, quantisation=False, missing=False)
    out = apply_sensor_noise(depth, np.zeros((8, 8)), cfg, np.random.default_rng(2))
    np.testing.assert_array_equal(out, depth)
