"""Slope statistics to Beckmann roughness, against closed forms."""

import math

import numpy as np
import pytest

from noise.heightfield import HeightField
from render.microfacet import slope_roughness


def sampled(h_fn, n=801, pitch=0.01):
    x = np.arange(n) * pitch
    xx, yy = np.meshgrid(x, x)
    return HeightField(h_fn(xx, yy), pitch, pitch)


def test_sinusoid_along_x_has_alpha_a_k():
    a, k = 0.02, 2 * math.pi / 0.5
    r = slope_roughness(*sampled(lambda x, y: a * np.sin(k * x)).slopes())
    # slope a k cos(k x): variance a^2 k^2 / 2, so alpha = sqrt(2) sigma = a k
    assert r.alpha_major == pytest.approx(a * k, rel=0.01)
    assert r.alpha_minor == pytest.approx(0.0, abs=1e-9)
    assert r.major_azimuth_rad == pytest.approx(0.0, abs=1e-6) or r.major_azimuth_rad == pytest.approx(
        math.pi
    )


def test_rotated_plane_waves_give_principal_axes_and_ratio():
    a, k, theta = 0.01, 2 * math.pi / 0.4, math.radians(30)

    def h(x, y):
        u = math.cos(theta) * x + math.sin(theta) * y
        v = -math.sin(theta) * x + math.cos(theta) * y
        return a * np.sin(k * u) + (a / 3) * np.sin(k * v + 0.3)

    r = slope_roughness(*sampled(h).slopes())
    assert r.major_azimuth_rad == pytest.approx(theta, abs=0.02)
    assert r.anisotropy == pytest.approx(3.0, rel=0.05)


def test_gaussian_slopes_recover_alpha():
    rng = np.random.default_rng(0)
    sx = rng.normal(0, 0.1, 100_000)
    sy = rng.normal(0, 0.05, 100_000)
    r = slope_roughness(sx, sy)
    assert r.alpha_major == pytest.approx(math.sqrt(2) * 0.1, rel=0.01)
    assert r.alpha_minor == pytest.approx(math.sqrt(2) * 0.05, rel=0.01)


def test_bad_slopes():
    with pytest.raises(ValueError, match="slopes"):
        slope_roughness(np.zeros(3), np.zeros(4))
    with pytest.raises(ValueError, match="slopes"):
        slope_roughness(np.array([np.nan, 1.0]), np.zeros(2))
