"""Sparse convolution noise: parity with the slow reference, statistics, and where it fails."""

import numpy as np
import pytest

import noise
from printapp.bench.reference.scn_reference import scn as scn_reference


@pytest.mark.parametrize("mode", ["hash", "frisvad"])
def test_matches_slow_reference(mode):
    rng = np.random.default_rng(3)
    pts = rng.uniform(-20, 20, size=(40, 3))
    fast = noise.sparse_convolution(pts, seed=11, impulses=8, cell_seed=mode)
    slow = np.array([scn_reference(tuple(p), seed=11, n_impulses=8, mode=mode) for p in pts])
    np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-12)
    assert np.std(fast) > 0.01


@pytest.mark.slow
def test_statistics_of_values():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-500, 500, size=(1_000_000, 3))
    v = noise.sparse_convolution(pts, seed=5)
    # Samples ~10 cells apart are independent: the mean is 0 within 5 standard errors.
    assert abs(v.mean()) < 5 * v.std() / np.sqrt(v.size)
    # The talk's normalisation keeps values in [-1, 1] in practice, not as a bound:
    # about one sample in a million (a 7-sigma excursion) overshoots, by a few percent.
    assert np.mean(np.abs(v) > 1.0) < 1e-5
    assert np.abs(v).max() < 1.1
    assert v.std() == pytest.approx(0.148, abs=0.002)
    other = noise.sparse_convolution(pts, seed=6)
    assert abs(v.std() / other.std() - 1) < 0.01
    assert abs(np.corrcoef(v, other)[0, 1]) < 0.005


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


# --- fast paths against the plain per-point kernel -------------------------------------------


@pytest.fixture(scope="module")
def plain():
    from printapp.bench.reference.scn_plain_numba import plain_sparse_convolution

    return plain_sparse_convolution


@pytest.mark.parametrize("mode", ["hash", "frisvad"])
@pytest.mark.parametrize(("side", "n"), [(3.0, 60_000), (200.0, 20_000), (40.0, 60_000)])
def test_binned_kernel_matches_the_plain_kernel(plain, mode, side, n):
    # dense cells (thousands of points), lone points, and a mix of both paths
    pts = np.random.default_rng(int(side)).uniform(-side / 2, side / 2, size=(n, 3))
    fast = noise.sparse_convolution(pts, seed=9, cell_seed=mode)
    np.testing.assert_allclose(fast, plain(pts, seed=9, cell_seed=mode), rtol=0, atol=1e-12)


def test_dense_cells_match_the_python_reference():
    pts = np.random.default_rng(8).uniform(0, 2, size=(400, 3))
    fast = noise.sparse_convolution(pts, seed=4, impulses=5)
    slow = np.array([scn_reference(tuple(p), seed=4, n_impulses=5) for p in pts[:25]])
    np.testing.assert_allclose(fast[:25], slow, rtol=0, atol=1e-12)


def test_grid_paths_equal_the_point_paths(plain):
    x = np.linspace(-3.0, 4.0, 57)
    y = np.linspace(10.0, 12.5, 31)
    z = np.array([-0.3, 0.0, 0.71])
    xx, yy = np.meshgrid(x, y)
    flat = np.column_stack([xx.ravel(), yy.ravel(), np.zeros(xx.size)])
    np.testing.assert_allclose(noise.sparse_convolution_grid(x, y).ravel(), plain(flat), atol=1e-12)
    zz, yy3, xx3 = np.meshgrid(z, y, x, indexing="ij")
    vol = np.column_stack([xx3.ravel(), yy3.ravel(), zz.ravel()])
    np.testing.assert_allclose(noise.sparse_convolution_grid(x, y, z).ravel(), plain(vol), atol=1e-12)
    np.testing.assert_allclose(
        noise.fbm_grid(x, y, octaves=3, H=0.6).ravel(), noise.fbm(flat, octaves=3, H=0.6), atol=1e-12
    )
    np.testing.assert_allclose(
        noise.turbulence_grid(x, y, low=1, high=3).ravel(), noise.turbulence(flat, low=1, high=3), atol=1e-12
    )


@pytest.mark.slow
def test_thread_count_does_not_change_a_single_bit(tmp_path):
    import subprocess
    import sys

    code = (
        "import numpy as np, noise, sys;"
        "r = np.random.default_rng(0);"
        "a = noise.sparse_convolution(r.uniform(0, 6, (50000, 3)));"
        "b = noise.sparse_convolution(r.uniform(0, 300, (5000, 3)));"
        "x = np.arange(300) * 0.05; c = noise.fbm_grid(x, x, octaves=4);"
        "np.save(sys.argv[1], np.concatenate([a, b, c.ravel()]))"
    )
    results = []
    for threads in ("1", "2"):
        out = tmp_path / f"t{threads}.npy"
        env = {**__import__("os").environ, "NUMBA_NUM_THREADS": threads}
        subprocess.run([sys.executable, "-c", code, str(out)], env=env, check=True)
        results.append(out.read_bytes())
    assert results[0] == results[1]


# --- statistics ----------------------------------------------------------------------------


def test_spread_is_the_same_in_distant_regions():
    rng = np.random.default_rng(11)
    stds = [
        noise.sparse_convolution(rng.uniform(0, 50, (100_000, 3)) + offset).std() for offset in (0, 1e4, -3e6)
    ]
    assert max(stds) / min(stds) < 1.03


@pytest.fixture(scope="module")
def slice_spectrum():
    spacing = 0.125
    axis = np.arange(512) * spacing
    power = np.zeros((512, 512))
    for seed in range(4):
        values = noise.sparse_convolution_grid(axis, axis, seed=seed)
        power += np.abs(np.fft.fft2(values - values.mean())) ** 2
    f = np.fft.fftfreq(512, d=spacing)
    return power, f[None, :], f[:, None]


def test_power_spectrum_is_isotropic(slice_spectrum):
    power, fx, fy = slice_spectrum
    radius = np.hypot(fx, fy)
    band = (radius > 0.2) & (radius < 2.0)
    along_axes = band & ((np.abs(fx) > 2 * np.abs(fy)) | (np.abs(fy) > 2 * np.abs(fx)))
    diagonal = band & ~along_axes
    horizontal = band & (np.abs(fx) > np.abs(fy))
    vertical = band & (np.abs(fy) > np.abs(fx))
    assert power[horizontal].mean() / power[vertical].mean() == pytest.approx(1.0, abs=0.05)
    assert power[along_axes].mean() / power[diagonal].mean() == pytest.approx(1.0, abs=0.1)


def test_no_peaks_at_integer_frequencies(slice_spectrum):
    power, fx, fy = slice_spectrum
    radius = np.hypot(fx, fy)
    for k in (1.0, 2.0):
        # the lattice's frequencies: on the axes at k cycles per unit
        spot = ((np.abs(np.abs(fx) - k) < 0.01) & (np.abs(fy) < 0.01)) | (
            (np.abs(np.abs(fy) - k) < 0.01) & (np.abs(fx) < 0.01)
        )
        ring = (np.abs(radius - k) < 0.1) & ~spot
        assert power[spot].mean() < 3.0 * power[ring].mean()


def test_grid_path_at_large_coordinates():
    x = 1e7 + np.arange(200) * 0.1
    values = noise.sparse_convolution_grid(x, x)
    assert np.all(np.isfinite(values))
    assert 0.7 < values.std() / noise.sparse_convolution_grid(x - 1e7, x - 1e7).std() < 1.4


def test_unit_noise_is_the_talks_mapping_to_0_1():
    pts = np.random.default_rng(3).uniform(0, 20, (20_000, 3))
    m = noise.unit_noise(pts, A=1.0, B=2.0, seed=1)
    np.testing.assert_allclose(m, 0.5 * (noise.sparse_convolution(2.0 * pts, seed=1) + 1), atol=1e-12)
    assert m.min() >= 0.0 and m.max() <= 1.0


def test_fbm_pitch_cap_drops_unprintable_octaves():
    pts = np.random.default_rng(5).uniform(0, 9, size=(300, 3))
    capped = noise.fbm(pts, octaves=8, min_pitch=0.1)
    np.testing.assert_allclose(capped, noise.fbm(pts, octaves=3), atol=1e-15)


def test_grid_axes_are_validated():
    with pytest.raises(ValueError, match="^x: expected coordinates in ascending order"):
        noise.sparse_convolution_grid(np.array([1.0, 0.0]), np.array([0.0]))
    with pytest.raises(ValueError, match="^y: expected finite"):
        noise.sparse_convolution_grid(np.array([0.0]), np.array([np.inf]))
    with pytest.raises(ValueError, match="^z: expected a non-empty 1-D array"):
        noise.sparse_convolution_grid(np.array([0.0]), np.array([0.0]), np.zeros((2, 2)))
