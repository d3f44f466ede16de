"""The noise kernels that ``printapp fit`` builds its vein models and measures on, each against a slow
reference written from its definition (``printapp.bench.reference``), and statistically."""

import math

import numpy as np
import pytest
import scipy.ndimage as ndi

import noise
from noise.cellular import cellular, feature_points
from noise.line_filters import hessian_eigenvalues, line_field, line_strengths
from noise.ridged import NOISE_STD, domain_warp, fbm_sampled, ridged_cascade, vein_network
from noise.tables import NoiseTable, Sampler, stream_seed
from printapp.bench.reference import ridged_reference as ref


@pytest.mark.parametrize("jitter", [1.0, 0.5, 0.0])
def test_cellular_f1_f2_match_brute_force(jitter):
    rng = np.random.default_rng(1)
    points = rng.uniform(-6.0, 6.0, (1500, 2))
    f1, f2 = cellular(points, seed=7, jitter=jitter)
    features = feature_points(-10, 10, -10, 10, seed=7, jitter=jitter)
    d = np.sort(np.sqrt(((points[:, None, :] - features[None]) ** 2).sum(-1)), axis=1)
    np.testing.assert_allclose(f1, d[:, 0], atol=1e-12)
    np.testing.assert_allclose(f2, d[:, 1], atol=1e-12)
    # The plain-Python reference draws the same feature points from the hash.
    for k in range(0, 1500, 150):
        assert cellular_point_close(points[k], 7, jitter, f1[k], f2[k])


def cellular_point_close(p, seed, jitter, f1, f2):
    r1, r2 = ref.cellular_point(float(p[0]), float(p[1]), seed, jitter)
    return math.isclose(r1, f1, abs_tol=1e-12) and math.isclose(r2, f2, abs_tol=1e-12)


def test_cellular_refuses_bad_input():
    with pytest.raises(ValueError, match="jitter"):
        cellular(np.zeros((3, 2)), jitter=1.5)
    with pytest.raises(ValueError, match="points"):
        cellular(np.zeros((3, 3)))


@pytest.mark.parametrize("basis", ["noise", "cells"])
def test_vein_network_matches_the_reference_loop(basis):
    rng = np.random.default_rng(2)
    points = rng.uniform(0.0, 3.0, (120, 2))
    options = {
        "octaves": 4,
        "lacunarity": 2.0,
        "H": 0.8,
        "gain": 2.5,
        "width": 0.6 if basis == "noise" else 0.15,
        "sharpness": 2.0,
        "seed": 11,
    }
    fast = vein_network(points, basis=basis, warp=0.4, warp_H=1.0, **options)
    slow = ref.vein_network(points, basis=basis, warp_amount=0.4, warp_H=1.0, **options)
    np.testing.assert_allclose(fast, slow, atol=1e-9)
    assert fast.min() >= 0.0 and fast.max() <= 1.0 and fast.max() > 0.3


def test_ridged_cascade_is_musgraves_loop_and_skips_what_it_may():
    rng = np.random.default_rng(3)
    d = rng.uniform(0.0, 1.0, (5, 400))
    weights = 2.0 ** (-0.9 * np.arange(5))
    calls = []

    def basis(i, index):
        calls.append(index.size)
        return d[i, index]

    fast = ridged_cascade(basis, 400, octaves=5, width=0.4, sharpness=3.0, gain=1.5, weights=weights)
    slow = [ref.ridged(list(d[:, k]), 0.4, 3.0, 1.5, list(weights)) for k in range(400)]
    np.testing.assert_allclose(fast, slow, atol=1e-12)
    assert calls[0] == 400 and calls[1] < 200  # the finer octaves only where a ridge lets them through


def test_domain_warp_moves_points_by_the_asked_standard_deviation():
    rng = np.random.default_rng(4)
    points = rng.uniform(0.0, 200.0, (20000, 2))
    moved = domain_warp(points, warp=0.7, octaves=4, H=1.0, seed=5)
    shift = moved - points
    assert np.std(shift[:, 0]) == pytest.approx(0.7, rel=0.1) and np.std(shift[:, 1]) == pytest.approx(
        0.7, rel=0.1
    )
    assert abs(np.corrcoef(shift[:, 0], shift[:, 1])[0, 1]) < 0.05  # independent streams
    np.testing.assert_allclose(moved[:50], ref.warp(points[:50], 0.7, 4, 1.0, 5, (1, 2)), atol=1e-12)
    np.testing.assert_array_equal(domain_warp(points[:10], warp=0.0), points[:10])


def test_fbm_sampled_is_the_octave_sum_with_unit_variance():
    x = np.linspace(0.0, 60.0, 220)
    xx, yy = np.meshgrid(x, x)
    points = np.column_stack([xx.ravel(), yy.ravel()])
    values = fbm_sampled(points, octaves=3, H=0.5, stream=5, seed=9)
    by_hand = sum(
        2.0 ** (-0.5 * i) * noise.sparse_convolution(points * 2.0**i, seed=stream_seed(9, 5))
        for i in range(3)
    )
    np.testing.assert_allclose(values, by_hand / (NOISE_STD * math.sqrt(1 + 0.5 + 0.25)), atol=1e-12)
    assert np.std(values) == pytest.approx(1.0, rel=0.08)
    grain = fbm_sampled(points, octaves=4, H=-1.0, stream=5, seed=9)  # H < 0: the fine octaves dominate
    assert np.std(grain) == pytest.approx(1.0, rel=0.08)


def test_noise_table_is_periodic_with_the_noises_spectrum_and_sums_octaves_like_calls():
    table = NoiseTable(16.0, seed=3)
    rng = np.random.default_rng(5)
    points = rng.uniform(-20.0, 20.0, (500, 2))
    np.testing.assert_allclose(table(points), table(points + [table.extent, -2 * table.extent]), atol=1e-6)
    x = np.arange(256) * 0.125
    xx, yy = np.meshgrid(x, x)
    grid = np.column_stack([xx.ravel(), yy.ravel()])
    tabled = table(grid).reshape(256, 256)
    exact = noise.sparse_convolution_grid(x, x, seed=3)
    assert np.std(tabled) == pytest.approx(np.std(exact), rel=0.15)
    f, p_table = noise.spectra.radial_spectrum(tabled)
    _, p_exact = noise.spectra.radial_spectrum(exact)
    ok = (f > 0.06) & (f < 0.3)  # bins of many samples: one realisation each scatters by < 0.1 decades
    assert np.max(np.abs(np.log10(p_table[ok] / p_exact[ok]))) < 0.15
    scales, weights = np.array([1.0, 2.0, 4.0]), np.array([1.0, 0.5, 0.25])
    shifts = np.array([[0.0, 0.0], [0.3, 0.1], [0.7, 0.2]])
    summed = table.octave_sum(points, 2, scales, weights, shifts, absolute=True)
    by_calls = sum(
        w * np.abs(table(points, 2, s, tuple(sh))) for s, w, sh in zip(scales, weights, shifts, strict=True)
    )
    np.testing.assert_allclose(summed, by_calls, atol=1e-9)
    exact_sampler = Sampler(3)
    np.testing.assert_allclose(exact_sampler(grid[:100], 0), exact.ravel()[:100], atol=1e-12)


@pytest.mark.parametrize("sigma", [2.0, 4.0])
def test_hessian_matches_gaussian_derivatives_of_scipy(sigma):
    rng = np.random.default_rng(6)
    image = ndi.gaussian_filter(rng.standard_normal((90, 120)), 1.5)
    h = [
        ndi.gaussian_filter(image, sigma, order=o, mode="reflect", truncate=6) * sigma**2
        for o in ((0, 2), (2, 0), (1, 1))
    ]
    half_trace = 0.5 * (h[0] + h[1])
    root = np.sqrt(0.25 * (h[0] - h[1]) ** 2 + h[2] ** 2)
    a, b = half_trace + root, half_trace - root
    big = np.where(np.abs(a) >= np.abs(b), a, b)
    ours = hessian_eigenvalues(image, (sigma,))[0, 0]
    assert np.max(np.abs(ours - big)) < 2e-3 * np.max(np.abs(big))


def test_line_filters_find_a_dark_line_its_direction_and_not_a_blob():
    y, x = np.mgrid[0:96, 0:96].astype(float)
    angle = math.radians(30.0)
    across = -math.sin(angle) * (x - 48) + math.cos(angle) * (y - 48)
    line = 1.0 - np.exp(-(across**2) / 2.0)  # a dark line of width about 2 px
    strengths, along = line_field(line, (1.0, 2.0))
    # Dark; its flanks read as weaker bright lines (the second derivative changes sign there).
    assert strengths[1, 1].max() > 2 * strengths[1, 0].max()
    on = strengths[1, 1] > 0.5 * strengths[1, 1].max()
    assert np.degrees(np.median(along[1][on])) == pytest.approx(30.0, abs=1.0)
    blob = np.exp(-((x - 48) ** 2 + (y - 48) ** 2) / 18.0)
    s = line_strengths(blob, (2.0,))
    assert s[0, 0, 48, 48] < 0.05 * np.abs(hessian_eigenvalues(blob, (2.0,))[0, 0, 48, 48])
