"""The compact model with the relief's own facet distribution (render.tabulated_ndf) against the tracer.

The model's error against a traced table is held to twice the table's own noise on a
Gaussian relief, an anisotropic (grooved) Gaussian relief and a brushed relief; its masking
against Beckmann's closed form; energy (white furnace), reciprocity, and its Mitsuba plugin
(evaluation against numpy, Mitsuba's chi-square test of sampling against pdf). Fixed seeds.
"""

import dataclasses
import math

import numpy as np
import pytest

from render.brdf_fit import table_noise
from render.brdf_model import smith_lambda
from render.fresnel import fresnel_dielectric
from render.gonio import direction_from_angles, estimate_brdf, lit_window, projected_solid_angle
from render.tabulated_bins import model_bins, table_error
from render.tabulated_ndf import (
    MS_NODES,
    MS_PHI,
    MS_THETA,
    direction_grid,
    evaluate,
    grid_lookup,
    ndf_from_slopes,
    scattering_energies,
    tabulate_ndf,
    tabulated_model,
)

INCIDENT_DEG = ((0, 0), (20, 0), (40, 0), (60, 0), (75, 0), (40, 90), (60, 90))


def spectral_relief(n, along_px, across_px, angle_deg, across_slope, seed=0):
    """Periodic Gaussian relief (unit pitch): white noise filtered by an anisotropic Gaussian."""
    rng = np.random.default_rng(seed)
    w = np.fft.fft2(rng.normal(size=(n, n)))
    k = 2 * math.pi * np.fft.fftfreq(n)
    ky, kx = np.meshgrid(k, k, indexing="ij")
    a = math.radians(angle_deg)
    ku, kv = kx * math.cos(a) + ky * math.sin(a), -kx * math.sin(a) + ky * math.cos(a)
    spectrum = w * np.exp(-0.5 * ((ku * along_px) ** 2 + (kv * across_px) ** 2))
    slope = np.real(np.fft.ifft2(1j * kv * spectrum)).std()
    return np.real(np.fft.ifft2(spectrum)) * (across_slope / slope)


def traced(h, *, periodic=True, rays=150_000, body=0.0, incident_deg=INCIDENT_DEG):
    wi = direction_from_angles(*np.radians(np.array(incident_deg, dtype=float)).T)
    t = estimate_brdf(h, 1.0, 1.0, wi, rays=rays, body_albedo=body, n_theta=45, n_phi=90, seed=1,
                      periodic=periodic)  # fmt: skip
    window = None if periodic else lit_window(h, 1.0, 1.0, wi[:1], False)[0]
    model = tabulated_model(tabulate_ndf(h, 1.0, 1.0, periodic=periodic, window=window), body, 1.5)
    error, _ = table_error(model, wi, t.f, t.stderr, t.theta_o_edges, t.phi_o_edges)
    return error, table_noise(t.f, projected_solid_angle(t.theta_o_edges, t.phi_o_edges), t.stderr), model


# --- the table ------------------------------------------------------------------------------


def test_the_table_integrates_to_one_and_holds_the_facets():
    rng = np.random.default_rng(0)
    gx, gy = rng.normal(0.0, 0.2, 400_000), rng.normal(0.0, 0.05, 400_000)
    gx[:100_000] = gy[:100_000] = 0.0  # a quarter of the area exactly flat: the spike
    ndf = ndf_from_slopes(gx, gy)
    assert ndf.spike_weight == pytest.approx(0.25)
    assert np.sum(ndf.density) * ndf.step**2 == pytest.approx(1.0, rel=1e-12)
    # Moments of (m_x, m_y) from the table against the facets' own (the flat ones aside).
    x = np.linspace(-ndf.extent, ndf.extent, ndf.density.shape[0])
    mx, my = np.meshgrid(x, x)
    w = ndf.density * ndf.step**2
    inv = 1.0 / np.sqrt(1.0 + gx[100_000:] ** 2 + gy[100_000:] ** 2)
    assert np.sum(w * mx * mx) == pytest.approx(np.mean((gx[100_000:] * inv) ** 2), rel=0.02)
    assert np.sum(w * my * my) == pytest.approx(np.mean((gy[100_000:] * inv) ** 2), rel=0.03)
    assert ndf.alpha_u == pytest.approx(math.sqrt(2) * 0.2, rel=0.01)
    assert math.degrees(ndf.azimuth_rad) % 180 == pytest.approx(0.0, abs=1.0) or math.degrees(
        ndf.azimuth_rad
    ) == pytest.approx(180.0, abs=1.0)


@pytest.mark.parametrize("theta_deg", [30.0, 60.0, 75.0, 85.0])
def test_masking_from_the_table_is_beckmanns_closed_form_for_gaussian_slopes(theta_deg):
    alpha = 0.3  # Beckmann: slopes of standard deviation alpha / sqrt(2) per axis (Heitz 2014, eq. 86)
    rng = np.random.default_rng(1)
    ndf = ndf_from_slopes(*rng.normal(0.0, alpha / math.sqrt(2), (2, 1_000_000)))
    for phi in (0.0, 1.0):
        w = direction_from_angles(math.radians(theta_deg), phi)
        expected = float(smith_lambda("beckmann", w[0, 0], w[0, 1], w[0, 2], alpha, alpha))
        assert float(ndf.smith_lambda(w)[0]) == pytest.approx(expected, rel=0.03, abs=2e-4)


# --- against the tracer -------------------------------------------------------------------


@pytest.mark.slow
def test_model_fits_a_gaussian_relief_within_twice_the_tables_noise():
    h = spectral_relief(192, 2.5, 2.5, 0.0, 0.25, seed=2)  # isotropic, slopes 0.25
    error, noise, model = traced(h, rays=400_000)  # measured: 7.2 % against 5.6 % noise
    assert model.spike_weight == 0.0
    assert error <= 2.0 * noise, (error, noise)


@pytest.mark.slow
def test_model_fits_a_grooved_gaussian_relief_within_twice_the_tables_noise():
    # Grooves along 30 degrees, slopes 0.25 across and 0.036 along: the analytic fit misses this
    # table by 12 % against 2.8 % noise at 512^2 (docs/benchmarks.md); the tabulated model, 3.4 %.
    h = spectral_relief(192, 4.0 * 0.25 / 0.036, 4.0, 30.0, 0.25, seed=3)
    error, noise, model = traced(h)
    assert model.alpha_u > 5 * model.alpha_v
    assert error <= 2.0 * noise, (error, noise)
    # The pigmented body through the rough interface, facet by facet (its bins are noisy: the
    # directions where the body's shape differs most from a smooth interface's, more rays).
    error, noise, _ = traced(h, body=0.8, rays=400_000, incident_deg=((0, 0), (60, 90), (75, 0)))
    assert error <= 2.0 * noise, (error, noise)


def test_model_fits_a_brushed_relief_within_twice_the_tables_noise():
    # The brushed example's relief as designed (sparse convolution noise stretched 8x along 30
    # degrees), a patch that does not tile: the model takes the facets of the window the tracer
    # lights.
    from printapp.design_io import load_design
    from printapp.relief import build_relief

    patch = build_relief(load_design("examples/brushed_tile.toml")).patch
    h = patch.heights_mm[80:240, 120:360] / patch.pitch_x_mm  # unit pitch
    error, noise, _ = traced(h, periodic=False, rays=200_000)
    assert error <= 2.0 * noise, (error, noise)


# --- energy and reciprocity ---------------------------------------------------------------


def albedo(model, wi):
    theta = np.linspace(0.0, math.pi / 2, 46)
    phi = np.linspace(0.0, 2 * math.pi, 91)
    return (model_bins(model, wi, theta, phi) * projected_solid_angle(theta, phi)).sum(axis=(1, 2))


def test_white_furnace_mirror_facets_return_what_they_do_not_send_into_the_surface():
    wi = direction_from_angles(np.radians([0.0, 30.0, 60.0, 80.0]), np.radians([0.0, 45.0, 90.0, 10.0]))
    flat = tabulated_model(tabulate_ndf(np.zeros((8, 8)), 1.0, 1.0), 0.0, None)
    np.testing.assert_allclose(albedo(flat, wi), 1.0, rtol=1e-12)  # a flat mirror returns all of it
    h = spectral_relief(128, 2.5, 2.5, 0.0, 0.25)
    ndf = tabulate_ndf(h, 1.0, 1.0)
    single = albedo(tabulated_model(ndf, 0.0, None, multiple_scattering=False), wi)
    both = albedo(tabulated_model(ndf, 0.0, None), wi)
    e_ss, _, e_2 = scattering_energies(ndf, None)
    assert np.all(e_ss + e_2 <= 1.0 + 1e-9)
    assert np.all(single <= 1.0) and np.all(both <= 1.0 + 2e-3)
    # The tracer's perfect reflector returns everything; the model, everything but the third
    # and later bounces, within a percent up to 60 degrees, and gains on single scattering.
    t = estimate_brdf(h, 1.0, 1.0, wi, rays=20_000, perfect_reflector=True, n_theta=9, n_phi=12)
    np.testing.assert_allclose(t.albedo, 1.0, rtol=1e-12)
    assert np.all(both[:3] > 0.99) and np.all(both > single)


def test_the_factor_weights_spread_each_facet_over_its_cell():
    """The multiple-scattering iteration weights a factor table by one matrix (render._energies):
    each facet's share goes to the four nodes of its outgoing direction's cell, so a factor of
    ones gives back the single-scattering albedo, and a factor of c gives c times it."""
    ndf = tabulate_ndf(spectral_relief(128, 4.0, 2.5, 20.0, 0.3), 1.0, 1.0)
    for ior in (None, 1.5):
        e_ss, ones, _ = scattering_energies(ndf, ior)
        np.testing.assert_allclose(ones, e_ss, rtol=1e-12, atol=1e-15)
        _, scaled, _ = scattering_energies(ndf, ior, np.full(e_ss.shape, 0.37))
        np.testing.assert_allclose(scaled, 0.37 * e_ss, rtol=1e-12, atol=1e-15)
        assert e_ss.min() > 0.0
        # Against the integral summed facet by facet in numpy, for a factor that varies.
        theta, phi = np.meshgrid(np.linspace(0, 1, MS_THETA), np.arange(MS_PHI) / MS_PHI, indexing="ij")
        factor = 1.0 + 0.5 * theta * np.cos(2 * math.pi * phi + 0.3)
        _, weighted, _ = scattering_energies(ndf, ior, factor)
        m, w = ndf.nodes(coarse=MS_NODES)
        directions = direction_grid(MS_THETA, MS_PHI, math.pi / 2)
        for j in (0, 37, 200, MS_THETA * MS_PHI - 5):
            wi = directions[j]
            a_i = grid_lookup(ndf.area, math.pi / 2, wi)
            c = m @ wi
            wo = 2.0 * c[:, None] * m - wi
            keep = (c > 0) & (wo[:, 2] > 0)
            c, wo, mz, wk = c[keep], wo[keep], m[keep, 2], w[keep]
            fr = np.ones_like(c) if ior is None else fresnel_dielectric(np.minimum(c, 1.0), ior)
            a_o = grid_lookup(ndf.area, math.pi / 2, wo)
            escape = (wi[2] + a_i) * wo[:, 2] / ((wi[2] + a_i) * wo[:, 2] + a_o * wi[2])
            share = wk * c / mz / (wi[2] + a_i) * fr * escape
            want = np.sum(share * grid_lookup(factor, math.pi / 2, wo))
            assert weighted.ravel()[j] == pytest.approx(want, rel=1e-9)


def test_pigmented_model_conserves_energy_and_is_reciprocal():
    h = spectral_relief(128, 8.0, 2.5, 30.0, 0.3)
    h[::7] = np.round(h[::7], 1)  # some flat facets too
    model = tabulated_model(tabulate_ndf(h, 1.0, 1.0), 1.0, 1.5)  # a white body absorbs nothing
    wi = direction_from_angles(np.radians([0.0, 40.0, 70.0]), np.radians([0.0, 100.0, 250.0]))
    assert np.all(albedo(model, wi) <= 1.01)
    rng = np.random.default_rng(4)
    a, b = rng.normal(size=(2, 5000, 3))
    a[:, 2], b[:, 2] = np.abs(a[:, 2]), np.abs(b[:, 2])
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    np.testing.assert_allclose(evaluate(model, a, b), evaluate(model, b, a), rtol=1e-12, atol=1e-15)


# --- the Mitsuba plugin ---------------------------------------------------------------------


def plugin_surface(h, spike_alpha=None):
    from render.representation import compact_surface

    model = tabulated_model(tabulate_ndf(h, 1.0, 1.0), 0.5, 1.5)
    surface = compact_surface(model, (0.5, 0.5, 0.5), 0.5)
    if spike_alpha is not None:  # a spike wide enough for the chi-square test's integration
        model = dataclasses.replace(model, spike_alpha=spike_alpha)
        surface = dataclasses.replace(surface, spike_alpha=spike_alpha)
    return model, surface


def test_plugin_evaluates_the_model():
    from render.mitsuba_adapter import choose_variant

    choose_variant()
    import drjit as dr
    import mitsuba as mi

    from render.mitsuba_bsdfs import surface_bsdf

    h = spectral_relief(96, 8.0, 2.5, 30.0, 0.3)
    h = np.where(h > 0.5, 0.5, h)  # plateaus: a spike
    model, surface = plugin_surface(h)
    assert model.spike_weight > 0.1
    bsdf = surface_bsdf(surface)
    rng = np.random.default_rng(5)
    wi, wo = rng.normal(size=(2, 4000, 3))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]), np.abs(wo[:, 2])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    si = dr.zeros(mi.SurfaceInteraction3f, len(wi))
    si.wi = mi.Vector3f(*[wi[:, c].astype(np.float32) for c in range(3)])
    value = np.asarray(
        bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(*[wo[:, c].astype(np.float32) for c in range(3)]))
    )
    value = value[:, 0] if value.shape[-1] == 3 else value[0]
    expected = evaluate(model, wi, wo) * wo[:, 2]
    np.testing.assert_allclose(value, expected, rtol=2e-4, atol=1e-6)


@pytest.mark.parametrize(
    ("plateau", "wi"),
    [(None, (0.0, 0.0, 1.0)), (None, (0.9, 0.1, math.sqrt(1 - 0.82))), (0.5, (0.6, 0.2, math.sqrt(1 - 0.4)))],
)
def test_plugin_samples_the_density_it_reports(plateau, wi):
    # Mitsuba's own chi-square test of sample() against pdf(), finer pdf integration (ires 16)
    # for the narrow lobes; the spike widened to 0.05 where there is one.
    from render.mitsuba_adapter import choose_variant

    choose_variant()
    from mitsuba.chi2 import BSDFAdapter, ChiSquareTest, SphericalDomain

    from render.mitsuba_tabulated import tabulated_plugin_dict

    h = spectral_relief(128, 8.0, 2.5, 30.0, 0.3)
    if plateau is not None:
        h = np.where(h > plateau, plateau, h)
    _, surface = plugin_surface(h, spike_alpha=0.05 if plateau is not None else None)
    sample, pdf = BSDFAdapter("printapp_tabulated", tabulated_plugin_dict(surface), wi=list(wi))
    test = ChiSquareTest(domain=SphericalDomain(), sample_func=sample, pdf_func=pdf, sample_dim=3, seed=3,
                         ires=16)  # fmt: skip
    assert test.run()
