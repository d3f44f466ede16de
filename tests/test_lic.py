"""2-D line integral convolution: orientation, agreement of the three methods, where it fails."""

import numpy as np
import pytest

from noise.lic import METHODS, _build_step_maps, _pad_inputs, _step, lic2d


def structure_orientation(image: np.ndarray) -> float:
    """Dominant orientation of the image's streaks (radians, mod pi).

    From the second moments of the power spectrum inside the disc |f| < 1/2: the
    spectrum of streaks is a line through the origin perpendicular to them. (A
    structure tensor from finite differences is biased towards the diagonals for
    detail at the pixel scale.)
    """
    power = np.abs(np.fft.fft2(image - image.mean())) ** 2
    fy = np.fft.fftfreq(image.shape[0])[:, None]
    fx = np.fft.fftfreq(image.shape[1])[None, :]
    power = power * (np.hypot(fx, fy) < 0.5)
    jxx, jyy, jxy = (power * fx * fx).sum(), (power * fy * fy).sum(), (power * fx * fy).sum()
    spectral_angle = 0.5 * np.arctan2(2 * jxy, jxx - jyy)
    return (spectral_angle + np.pi / 2) % np.pi


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, 90.0, 135.0])
@pytest.mark.parametrize("method", METHODS)
def test_constant_field_gives_streaks_along_it(angle_deg, method):
    rng = np.random.default_rng(0)
    tex = rng.random((128, 128))
    a = np.radians(angle_deg)
    u = np.full_like(tex, np.cos(a))
    v = np.full_like(tex, np.sin(a))
    out = lic2d(u, v, tex, length=12, method=method)
    got = structure_orientation(out[16:-16, 16:-16])
    diff = abs((got - a + np.pi / 2) % np.pi - np.pi / 2)
    assert np.degrees(diff) < 3.0
    assert out.std() < 0.5 * tex.std()  # averaging along lines smooths the noise


def vortex(n: int) -> tuple[np.ndarray, np.ndarray]:
    y, x = np.mgrid[0:n, 0:n].astype(float)
    return -(y - n / 2 + 0.3), (x - n / 2 + 0.2) + 0.25 * n * np.sin(y / 13.0)


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.corrcoef(a.ravel(), b.ravel())[0, 1])


@pytest.fixture(scope="module")
def vortex_case():
    rng = np.random.default_rng(1)
    tex = rng.random((192, 192))
    u, v = vortex(192)
    reference = lic2d(u, v, tex, length=10, method="exact", step=0.1)
    return u, v, tex, reference


def test_flow_map_matches_the_exact_reference(vortex_case):
    u, v, tex, reference = vortex_case
    assert correlation(lic2d(u, v, tex, length=10), reference) > 0.99
    assert correlation(lic2d(u, v, tex, length=10, method="exact", step=0.5), reference) > 0.995
    # Stalling & Hege trades accuracy for reuse: a sample stands for pixels up to
    # max_offset away from it.
    assert correlation(lic2d(u, v, tex, length=10, method="stalling-hege", step=0.5), reference) > 0.98


def test_flow_map_hann_kernel_matches_the_exact_one(vortex_case):
    u, v, tex, _ = vortex_case
    exact = lic2d(u, v, tex, length=10, kernel="hann", method="exact", step=0.1)
    assert correlation(lic2d(u, v, tex, length=10, kernel="hann"), exact) > 0.99


@pytest.mark.parametrize("rk4", [False, True])
def test_step_map_holds_the_exact_runge_kutta_steps(rk4):
    """The map's steps (float32, rows of stages) equal ``_step`` (float64, one pixel at a time)."""
    n = 48
    u, v = vortex(n)
    u[5:9, 30:40] = np.nan
    tex = np.zeros((n, n))
    field = np.empty((n + 2, n + 2, 2), np.float32)
    _pad_inputs(u, v, 1.0 / 64, tex, 0.0, field, np.empty((n + 2, n + 2), np.float32))
    maps = np.empty((2, n + 2, n + 2, 2), np.float32)
    _build_step_maps(field.reshape(-1), 0.8, rk4, maps)
    for d, h in ((0, 0.8), (1, -0.8)):
        expected = np.full((n, n, 2), np.nan)
        for j in range(n):
            for i in range(n):
                x1, y1, ok = _step(u, v, float(i), float(j), h, rk4)
                if ok and -0.5 <= x1 <= n - 0.5 and -0.5 <= y1 <= n - 0.5:
                    expected[j, i] = x1 - i, y1 - j
        got = maps[d, 1:-1, 1:-1]
        np.testing.assert_array_equal(np.isnan(got), np.isnan(expected))
        np.testing.assert_allclose(got, expected, atol=2e-6)
        assert np.all(np.isnan(maps[d, 0])) and np.all(np.isnan(maps[d, :, -1]))  # border cells stop


def test_texture_offset_and_field_scale_do_not_matter(vortex_case):
    u, v, tex, _ = vortex_case
    base = lic2d(u, v, tex, length=10)
    # float32 about the texture's mean keeps detail on a large offset
    np.testing.assert_allclose(lic2d(u, v, tex + 1e6, length=10) - 1e6, base, atol=1e-5)
    for scale in (2.0**-60, 1e-30, 1e30):
        np.testing.assert_allclose(lic2d(u * scale, v * scale, tex, length=10), base, atol=1e-5)


def test_infinite_field_values_stop_streamlines_like_nan(vortex_case):
    u, v, tex, _ = vortex_case
    with_inf = u.copy()
    with_nan = u.copy()
    with_inf[40:50, 60:90] = np.inf
    with_nan[40:50, 60:90] = np.nan
    for method in METHODS:
        inf_out = lic2d(with_inf, v, tex, length=10, method=method)
        np.testing.assert_array_equal(inf_out, lic2d(with_nan, v, tex, length=10, method=method))


def test_streamlines_end_at_a_sink_alike_in_every_method():
    """Into a sink, unit-speed streamlines would oscillate about it and average its texel;
    every method ends them there instead, so they agree about the sink too."""
    n = 96
    y, x = np.mgrid[0:n, 0:n].astype(float)
    u, v = -(x - 40.3) - 0.5 * (y - 50.6), -(y - 50.6) + 0.5 * (x - 40.3)  # a spiral sink
    tex = np.random.default_rng(3).random((n, n))
    reference = lic2d(u, v, tex, length=30, method="exact", step=0.1)
    near = np.hypot(x - 40.3, y - 50.6) < 12
    for method in ("flowmap", "exact"):
        out = lic2d(u, v, tex, length=30, method=method)
        # (the flow map without its stops: 0.975 near the sink, 0.969 overall)
        assert correlation(out[near], reference[near]) > 0.98
        assert correlation(out, reference) > 0.99


def test_critical_points_borders_and_nan_fields_give_finite_output():
    n = 64
    y, x = np.mgrid[0:n, 0:n].astype(float)
    u, v = x - 32.0, y - 32.0  # a source: zero vector exactly at (32, 32)
    u[5:9, 40:50] = np.nan
    tex = np.random.default_rng(2).random((n, n))
    cases = ({}, {"method": "exact"}, {"method": "stalling-hege"}, {"kernel": "hann"}, {"integrator": "rk4"})
    for kwargs in cases:
        out = lic2d(u, v, tex, length=20, **kwargs)
        assert np.all(np.isfinite(out))
        if kwargs.get("method") != "stalling-hege":
            # per pixel, the streamline from the critical point cannot start: the pixel itself
            assert out[32, 32] == pytest.approx(tex[32, 32], abs=1e-6)
    for method in METHODS:
        zero = lic2d(np.zeros((n, n)), np.zeros((n, n)), tex, length=5, method=method)
        np.testing.assert_allclose(zero, tex, atol=1e-6)


@pytest.mark.slow
def test_results_do_not_depend_on_the_thread_count(tmp_path):
    import os
    import subprocess
    import sys

    code = (
        "import numpy as np, sys; from noise.lic import lic2d;"
        "r = np.random.default_rng(0); t = r.random((96, 96));"
        "y, x = np.mgrid[0:96, 0:96].astype(float);"
        "np.save(sys.argv[1], lic2d(-(y - 48), x - 48, t, length=15))"
    )
    outputs = []
    for threads in ("1", "2"):
        path = tmp_path / f"{threads}.npy"
        subprocess.run(
            [sys.executable, "-c", code, str(path)],
            env={**os.environ, "NUMBA_NUM_THREADS": threads},
            check=True,
        )
        outputs.append(path.read_bytes())
    assert outputs[0] == outputs[1]


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"length": 0}, "length"),
        ({"length": 5, "kernel": "gauss"}, "kernel"),
        ({"length": 5, "integrator": "euler"}, "integrator"),
        ({"length": 5, "step": 3.0}, "step"),
        ({"length": 5, "method": "fast"}, "method"),
        ({"length": 5, "kernel": "hann", "method": "stalling-hege"}, "method"),
        ({"length": 5, "max_offset": 0.0}, "max_offset"),
    ],
)
def test_bad_arguments(kwargs, name):
    tex = np.zeros((8, 8))
    with pytest.raises(ValueError, match=f"^{name}:"):
        lic2d(tex, tex, tex, **kwargs)


def test_bad_arrays():
    tex = np.zeros((8, 8))
    with pytest.raises(ValueError, match="^u: expected shape"):
        lic2d(np.zeros((8, 9)), tex, tex, length=3)
    with pytest.raises(ValueError, match="^texture: expected finite"):
        lic2d(tex, tex, np.full((8, 8), np.nan), length=3)
