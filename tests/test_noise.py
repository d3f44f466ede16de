"""Sparse convolution noise: parity with the slow reference, statistics, and where it fails."""

import numpy as np
import pytest

import noise
from tests.reference.scn_reference import scn as scn_reference


@pytest.mark.parametrize("mode", ["hash", "frisvad"])
def test_matches_slow_reference(mode):
    rng = np.random.default_rng(3)
    pts = rng.uniform(-20, 20, size=(40, 3))
    fast = noise.sparse_convolution(pts, seed=11, impulses=8, cell_seed=mode)
    slow = np.array([scn_reference(tuple(p), seed=11, n_impulses=8, mode=mode) for p in pts])
    np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-12)
    assert np.std(fast) > 0.01


def test_statistics_of_values():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-500, 500, size=(200_000, 3))
    v = noise.sparse_convolution(pts, seed=5)
    # mean 0 within 5 standard errors; values bounded; the spread is stable across seeds.
    assert abs(v.mean()) < 5 * v.std() / np.sqrt(v.size)  # samples ~17 cells apart: independent
    assert np.all(np.abs(v) <= 1.0)
    other = noise.sparse_convolution(pts, seed=6)
    assert abs(v.std() / other.std() - 1) < 0.02
    assert abs(np.corrcoef(v, other)[0, 1]) < 0.01


def test_frisvad_mode_repeats_along_lattice_vectors_and_hash_mode_does_not():
    rng = np.random.default_rng(1)
    pts = rng.uniform(0, 5, size=(500, 3))
    shift = np.array([1000.0, -1.0, 0.0])  # q.a is unchanged by this lattice vector
    a = noise.sparse_convolution(pts, cell_seed="frisvad")
    b = noise.sparse_convolution(pts + shift, cell_seed="frisvad")
    # Equal up to the rounding of p + shift: the same impulses, not merely similar ones.
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)
    assert np.std(a) > 0.05
    h_a = noise.sparse_convolution(pts, cell_seed="hash")
    h_b = noise.sparse_convolution(pts + shift, cell_seed="hash")
    assert abs(np.corrcoef(h_a, h_b)[0, 1]) < 0.2


def test_large_coordinates_stay_finite_and_varied():
    rng = np.random.default_rng(2)
    pts = 1e7 + rng.uniform(0, 10, size=(5000, 3))
    v = noise.sparse_convolution(pts)
    assert np.all(np.isfinite(v))
    assert 0.5 < v.std() / noise.sparse_convolution(pts - 1e7).std() < 2.0


def test_two_d_points_lie_at_z_zero():
    pts = np.random.default_rng(4).uniform(0, 9, size=(100, 2))
    np.testing.assert_array_equal(
        noise.sparse_convolution(pts), noise.sparse_convolution(np.column_stack([pts, np.zeros(100)]))
    )


def test_fbm_is_the_weighted_octave_sum():
    pts = np.random.default_rng(5).uniform(0, 9, size=(200, 3))
    expected = sum(2.0 ** (-0.7 * i) * noise.sparse_convolution(pts * 2.0**i, seed=3) for i in range(3))
    np.testing.assert_allclose(noise.fbm(pts, octaves=3, H=0.7, seed=3), expected, atol=1e-12)


def test_turbulence_is_the_sum_of_absolute_octaves():
    pts = np.random.default_rng(6).uniform(0, 9, size=(200, 3))
    expected = sum(np.abs(noise.sparse_convolution(pts * 2.0**i, seed=2)) / 2.0**i for i in range(1, 4))
    np.testing.assert_allclose(noise.turbulence(pts, low=1, high=3, seed=2), expected, atol=1e-12)


def test_octave_cap_follows_the_pitch():
    assert noise.octaves_for_pitch(8, 2.0, pitch=0.1) == 3  # 1, 1/2, 1/4 >= 0.2; 1/8 is not
    assert noise.octaves_for_pitch(8, 2.0, pitch=10.0) == 1


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: noise.sparse_convolution(np.array([[np.nan, 0, 0]])), "points"),
        (lambda: noise.sparse_convolution(np.zeros((3, 4))), "points"),
        (lambda: noise.sparse_convolution(np.zeros((3, 3)), impulses=0), "impulses"),
        (lambda: noise.sparse_convolution(np.zeros((3, 3)), cell_seed="x"), "cell_seed"),
        (lambda: noise.fbm(np.zeros((3, 3)), octaves=0), "octaves"),
        (lambda: noise.fbm(np.zeros((3, 3)), octaves=2, lacunarity=1.0), "lacunarity"),
        (lambda: noise.fbm(np.zeros((3, 3)), octaves=2, H=0.0), "H"),
        (lambda: noise.turbulence(np.zeros((3, 3)), low=3, high=2), "high"),
    ],
)
def test_bad_arguments_name_themselves(call, name):
    with pytest.raises(ValueError, match=rf"^{name}:"):
        call()
