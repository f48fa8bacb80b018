"""The Asus Xtion Pro Live's depth noise, for simulations that want a real sensor's flaws.

* axial noise (Nguyen, Izadi & Lovell 2012): sigma_z(z) = 0.0012 + 0.0019 (z - 0.4)^2 m for
  surface angles theta <= 60 deg, plus 0.0001 theta^2 / (sqrt(z) (pi/2 - theta)^2) above;
* disparity quantisation of a structured-light sensor: disparity f b / z is rounded to
  1/``subpixel`` pixel at the native 640x480 focal length (whatever the render resolution);
* missing returns at grazing angles: a pixel is dropped with a probability rising linearly from
  0 at ``missing_start_deg`` to 1 at ``missing_full_deg``.

Lateral noise is left out: at the default 160x120 it is below a pixel. Noise is applied in that
order; missing pixels become 0, like the sensor's holes.
"""

from __future__ import annotations

import numpy as np

from rapomdp.config import NoiseConfig
from rapomdp.geometry.camera import xtion_intrinsics


def axial_sigma_m(depth_m: np.ndarray, angle_rad: np.ndarray) -> np.ndarray:
    """Standard deviation (m) of the Xtion's axial noise at depth z and surface angle theta."""
    z = np.asarray(depth_m, dtype=np.float64)
    theta = np.asarray(angle_rad, dtype=np.float64)
    sigma = 0.0012 + 0.0019 * (z - 0.4) ** 2
    steep = theta > np.radians(60.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        extra = 0.0001 * theta**2 / (np.sqrt(np.maximum(z, 1e-9)) * (np.pi / 2 - theta) ** 2)
    return np.where(steep, sigma + np.nan_to_num(extra, posinf=1.0), sigma)


def quantise_depth(depth_m: np.ndarray, baseline_m: float, subpixel: int) -> np.ndarray:
    """Depth after rounding the disparity to 1/``subpixel`` pixel (0 stays 0)."""
    focal = xtion_intrinsics().fx
    depth = np.asarray(depth_m, dtype=np.float64)
    valid = depth > 0
    disparity = np.where(valid, focal * baseline_m / np.where(valid, depth, 1.0), 0.0)
    steps = np.maximum(np.round(disparity * subpixel), 1.0)
    return np.where(valid, focal * baseline_m * subpixel / steps, 0.0)


def apply_sensor_noise(
    depth_m: np.ndarray,
    angle_rad: np.ndarray,
    noise: NoiseConfig,
    rng: np.random.Generator,
) -> np.ndarray:
    """A noisy copy of clean depth images (float32), given each pixel's surface angle."""
    depth = np.asarray(depth_m, dtype=np.float64)
    valid = depth > 0
    out = depth.copy()
    if noise.axial:
        out += rng.standard_normal(depth.shape) * axial_sigma_m(depth, angle_rad)
    if noise.quantisation:
        out = quantise_depth(np.where(valid, np.maximum(out, 1e-3), 0.0), noise.baseline_m,
                             noise.subpixel)
    if noise.missing:
        start, full = np.radians(noise.missing_start_deg), np.radians(noise.missing_full_deg)
        span = max(full - start, 1e-9)
        p_missing = np.clip((np.asarray(angle_rad) - start) / span, 0.0, 1.0)
        valid &= rng.random(depth.shape) >= p_missing
    return np.where(valid, out, 0.0).astype(np.float32)
