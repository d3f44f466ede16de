"""2-D line integral convolution: orientation, agreement of the two methods, where it fails."""

import numpy as np
import pytest

from noise.lic import lic2d


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
@pytest.mark.parametrize("fast", [True, False])
def test_constant_field_gives_streaks_along_it(angle_deg, fast):
    rng = np.random.default_rng(0)
    tex = rng.random((128, 128))
    a = np.radians(angle_deg)
    u = np.full_like(tex, np.cos(a))
    v = np.full_like(tex, np.sin(a))
    out = lic2d(u, v, tex, length=12, fast=fast)
    got = structure_orientation(out[16:-16, 16:-16])
    diff = abs((got - a + np.pi / 2) % np.pi - np.pi / 2)
    assert np.degrees(diff) < 3.0
    assert out.std() < 0.5 * tex.std()  # averaging along lines smooths the noise


def vortex(n: int) -> tuple[np.ndarray, np.ndarray]:
    y, x = np.mgrid[0:n, 0:n].astype(float)
    return -(y - n / 2 + 0.3), (x - n / 2 + 0.2) + 0.25 * n * np.sin(y / 13.0)


def test_fast_method_matches_the_per_pixel_reference():
    rng = np.random.default_rng(1)
    tex = rng.random((192, 192))
    u, v = vortex(192)
    reference = lic2d(u, v, tex, length=10, fast=False, step=0.1, integrator="rk4")
    fast = lic2d(u, v, tex, length=10)
    assert np.corrcoef(fast.ravel(), reference.ravel())[0, 1] > 0.99
    per_pixel = lic2d(u, v, tex, length=10, fast=False)
    assert np.corrcoef(per_pixel.ravel(), reference.ravel())[0, 1] > 0.995


def test_critical_points_borders_and_nan_fields_give_finite_output():
    n = 64
    y, x = np.mgrid[0:n, 0:n].astype(float)
    u, v = x - 32.0, y - 32.0  # a source: zero vector exactly at (32, 32)
    u[5:9, 40:50] = np.nan
    tex = np.random.default_rng(2).random((n, n))
    for kwargs in ({}, {"fast": False}, {"kernel": "hann"}, {"integrator": "rk4"}):
        out = lic2d(u, v, tex, length=20, **kwargs)
        assert np.all(np.isfinite(out))
        if kwargs.get("fast") is False or "kernel" in kwargs:
            # per pixel, the streamline from the critical point cannot start: the pixel itself
            assert out[32, 32] == pytest.approx(tex[32, 32])
    zero = lic2d(np.zeros((n, n)), np.zeros((n, n)), tex, length=5)
    np.testing.assert_allclose(zero, tex)


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
        ({"length": 5, "kernel": "hann", "fast": True}, "fast"),
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
