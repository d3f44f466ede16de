"""The dipole (render.bssrdf) against a Monte Carlo random walk in a half-space (printapp/bench/reference)."""

import math

import numpy as np
import pytest
from scipy.integrate import quad

from printapp.bench.reference.slab_walk import exit_radii, slab_exit_radii
from render.bssrdf import (
    dipole_profile,
    dipole_total_reflectance,
    fresnel_diffuse_reflectance_fit,
    slab_profiles,
    slab_totals,
)


def _annulus(a, b, *args):
    return quad(lambda r: dipole_profile(r, *args) * 2.0 * math.pi * r, a, b, limit=200)[0]


@pytest.mark.parametrize(("albedo", "eta"), [(0.99, 1.0), (0.99, 1.3)])
def test_dipole_against_a_random_walk(albedo, eta):
    # sigma_t' = 1/mm: lengths in transport mean free paths
    args = (albedo, 1.0 - albedo, 0.0, eta)
    photons = 60_000
    radii = exit_radii(photons, *args, seed=2)
    total_mc = radii.size / photons
    # the closed form is the profile's integral
    assert dipole_total_reflectance(*args) == pytest.approx(_annulus(0, np.inf, *args), rel=1e-4)
    # total diffuse reflectance: within 3 % of the walk's (0.747 vs 0.754; 0.645 vs 0.658 measured)
    assert dipole_total_reflectance(*args) == pytest.approx(total_mc, rel=0.03)
    # far from the entry point, where diffusion holds: within 20 % from 4 to 8 mean free paths
    far = np.count_nonzero((radii >= 4.0) & (radii < 8.0)) / photons
    assert _annulus(4.0, 8.0, *args) == pytest.approx(far, rel=0.2)
    # near it the walk's single and low-order scattering, which the dipole leaves out, dominate
    near = np.count_nonzero(radii < 0.5) / photons
    assert near > 1.8 * _annulus(0.0, 0.5, *args)


def test_dipole_limits_and_published_values():
    # Egan & Hilgeman's F_dr: about 0 for a matched boundary, 0.445 inside an index of 1.3
    assert fresnel_diffuse_reflectance_fit(1.0) == pytest.approx(0.0, abs=2e-3)
    assert fresnel_diffuse_reflectance_fit(1.3) == pytest.approx(0.4448, abs=1e-3)
    # no absorption: everything that enters comes back out of a half-space
    assert dipole_total_reflectance(1.0, 0.0) == pytest.approx(1.0)
    # more absorption, less light back, and a profile that falls with distance
    assert dipole_total_reflectance(0.9, 0.1) < dipole_total_reflectance(0.99, 0.01)
    profile = dipole_profile(np.array([0.0, 0.5, 1.0, 3.0]), 0.99, 0.01)
    assert np.all(np.diff(profile) < 0)
    with pytest.raises(ValueError):
        dipole_profile(1.0, 0.0, 0.0)


def test_slab_multipole_against_a_random_walk_in_a_slab():
    # no absorption, 3 transport mean free paths thick: all light leaves by one face or the other
    args = (1.0, 0.0, 0.0, 1.3)
    photons = 40_000
    top, bottom = slab_exit_radii(photons, *args, thickness_mm=3.0, seed=3)
    r = np.linspace(0.0, 80.0, 80_001)
    reflect, transmit = slab_profiles(r, *args, 3.0)

    def annulus(profile, a, b):
        m = (r >= a) & (r < b)
        return np.trapezoid((profile * 2.0 * np.pi * r)[m], r[m])

    # totals: 0.621 / 0.379 against the walk's 0.570 / 0.430 (diffusion's error at 3 mfp)
    assert annulus(reflect, 0, 80) + annulus(transmit, 0, 80) == pytest.approx(1.0, abs=2e-3)
    assert annulus(reflect, 0, 80) == pytest.approx(top.size / photons, rel=0.12)
    assert annulus(transmit, 0, 80) == pytest.approx(bottom.size / photons, rel=0.15)
    # away from the entry point the profiles follow the walk within 15 %
    for a, b in [(3.0, 6.0), (6.0, 12.0)]:
        assert annulus(reflect, a, b) == pytest.approx(
            np.count_nonzero((top >= a) & (top < b)) / photons, rel=0.15
        )
        assert annulus(transmit, a, b) == pytest.approx(
            np.count_nonzero((bottom >= a) & (bottom < b)) / photons, rel=0.15
        )


@pytest.mark.slow
def test_thick_slab_is_the_dipole_and_totals_are_the_profiles_integrals():
    r = np.array([0.0, 0.5, 1.0, 3.0])
    reflect, transmit = slab_profiles(r, 0.99, 0.01, 0.0, 1.3, 300.0)
    np.testing.assert_allclose(reflect, dipole_profile(r, 0.99, 0.01, 0.0, 1.3), rtol=1e-12)
    assert np.all(transmit < 1e-20)
    # with absorption the series converges: the closed-form totals are the integrals
    rr = np.linspace(0.0, 200.0, 400_001)
    ref, tra = slab_profiles(rr, 0.9, 0.1, 0.0, 1.4, 2.0)
    total_r, total_t = slab_totals(0.9, 0.1, 0.0, 1.4, 2.0)
    assert total_r == pytest.approx(np.trapezoid(ref * 2 * np.pi * rr, rr), rel=1e-3)
    assert total_t == pytest.approx(np.trapezoid(tra * 2 * np.pi * rr, rr), rel=1e-3)
    with pytest.raises(ValueError):
        slab_profiles(1.0, 1.0, 0.0, 0.0, 1.3, 0.0)
