"""Lorenz–Mie kernels: published values, a high-precision reference, miepython, and the limits."""

import math

import numpy as np
import pytest

from render import mie


def reference():
    """The 40-digit mpmath reference (mpmath is in the dev extra)."""
    pytest.importorskip("mpmath")
    from printapp.bench.reference import mie_mpmath

    return mie_mpmath


def rel(a, b):
    return np.abs(np.asarray(a) / np.asarray(b) - 1.0)


def test_bohren_huffman_sphere():
    # Bohren & Huffman 1983, appendix A (BHMIE's sample output): water droplet-like sphere.
    q_ext, q_sca, q_back, g = mie.efficiencies(1.55, 2 * math.pi * 0.525 / 0.6328)
    assert q_ext == pytest.approx(3.10543, abs=5e-6)
    assert q_sca == pytest.approx(3.10543, abs=5e-6)
    assert q_back == pytest.approx(2.92534, abs=5e-6)
    assert g == pytest.approx(0.63314, abs=5e-6)


# Wiscombe's MIEV0 test cases (MVTstNew.f): m (n - i kappa), x, Q_ext, Q_sca, g Q_sca, 7 digits.
WISCOMBE = [
    (0.75, 0.099, 7.417859e-06, 7.417859e-06, 1.074279e-08),
    (0.75, 0.101, 8.033542e-06, 8.033542e-06, 1.211000e-08),
    (0.75, 10.0, 2.232265, 2.232265, 2.001164),
    (0.75, 1000.0, 1.997908, 1.997908, 1.688121),
    (1.33 - 1e-5j, 1.0, 9.395198e-02, 9.392330e-02, 1.733048e-02),
    (1.33 - 1e-5j, 100.0, 2.101321, 2.096594, 1.821854),
    (1.33 - 1e-5j, 10000.0, 2.004089, 1.723857, 1.564987),
    (1.5 - 1j, 0.055, 1.014910e-01, 1.131687e-05, 5.558541e-09),
    (1.5 - 1j, 0.056, 1.033467e-01, 1.216311e-05, 6.193255e-09),
    (1.5 - 1j, 1.0, 2.336321, 6.634538e-01, 1.274736e-01),
    (1.5 - 1j, 100.0, 2.097502, 1.283697, 1.091466),
    (1.5 - 1j, 10000.0, 2.004368, 1.236574, 1.046525),
    (10 - 10j, 1.0, 2.532993, 2.049405, -2.267961e-01),
    (10 - 10j, 100.0, 2.071124, 1.836785, 1.021648),
    (10 - 10j, 10000.0, 2.005914, 1.795393, 9.842238e-01),
]


@pytest.mark.parametrize("m, x, q_ext, q_sca, gq", WISCOMBE)
def test_wiscombe_cases(m, x, q_ext, q_sca, gq):
    e, s, _, g = mie.efficiencies(m, x)
    # Seven significant digits: half a unit in the last one is at most 5e-7 relative; the
    # 0.101 case differs by that much between Wiscombe's and Du's (2004) tables.
    assert rel(e, q_ext) < 1.5e-6
    assert rel(s, q_sca) < 1.5e-6
    assert abs(g * s - gq) <= 1.5e-6 * abs(gq) + 1e-13


def test_arrays_broadcast_and_scalars_stay_scalars():
    q = mie.efficiencies(np.array([[1.5], [1.2 - 0.1j]]), np.array([0.5, 5.0, 50.0]))
    assert all(part.shape == (2, 3) for part in q)
    assert isinstance(mie.efficiencies(1.5, 2.0)[0], float)
    single = mie.efficiencies(1.2 - 0.1j, 5.0)
    assert np.allclose([part[1, 1] for part in q], single, rtol=0, atol=0)


REFERENCE_CASES = [
    (1.8 - 0.001j, 0.3),
    (1.8 - 0.001j, 3.0),
    (1.05 - 1e-4j, 20.0),
    (0.75, 7.0),
    (1.5 - 1j, 25.0),
    (10 - 10j, 12.0),
    (1.5, 0.05),
]


@pytest.mark.parametrize("m, x", REFERENCE_CASES)
def test_against_high_precision_reference(m, x):
    # mpmath's Bessel functions at 40 digits, no recurrences: an independent check.
    expected = reference().efficiencies(complex(m).conjugate(), x)
    got = mie.efficiencies(m, x)
    assert np.all(rel(got[:2], expected[:2]) < 1e-10)
    assert rel(got[3], expected[3]) < 1e-10
    # The back sum alternates in sign; the talk's truncation (error 1e-8) shows there first.
    assert rel(got[2], expected[2]) < 3e-8


@pytest.mark.parametrize("m, x, host_k", [(1.5, 2.0, 1e-3), (1.5 - 0.1j, 20.0, 1e-2), (1.1, 0.5, 0.05)])
def test_absorbing_host_against_reference(m, x, host_k):
    # FCJ07's generalisation, computed by the reference from mpmath Bessel functions of the
    # complex size parameter.
    expected = reference().efficiencies(complex(m).conjugate(), x, host_k)
    got = mie.efficiencies(m, x, 1.33 - 1.33j * host_k)
    assert np.all(rel(got, expected) < 1e-8)


@pytest.mark.parametrize("m", [1.5, 1.5 - 0.01j, 0.8, 1.5 - 1j])
@pytest.mark.parametrize("x", [0.5, 2.0, 30.0, 300.0])
def test_absorbing_host_reduces_to_classic_theory(m, x):
    # Two different algorithms (Yang's ratio recurrences vs Bohren & Huffman's); the
    # absorbing-host result converges linearly in the host's absorption to the classic one.
    # The difference is the host's absorption at work, so it shrinks in proportion to it: its
    # slope measured at 1e-8 predicts it at 1e-12, where what is left is rounding.
    classic = np.array(mie.efficiencies(m, x))

    def difference(k):
        return rel(np.array(mie.efficiencies(m, x, 1.4 - 1.4j * k)), classic)

    slope = difference(1e-8) / 1e-8
    assert np.all(difference(1e-12) <= 1.01 * slope * 1e-12 + 2e-12)
    assert np.all(difference(1e-10) <= 1.01 * slope * 1e-10 + 2e-12)


def test_agrees_with_miepython_across_a_sweep():
    miepython = pytest.importorskip("miepython")
    ms = [1.05, 1.33, 1.5, 2.0, 0.75, 1.5 - 0.01j, 1.5 - 1j, 2.5 - 0.5j, 10 - 10j]
    xs = np.geomspace(0.2, 1000.0, 12)
    worst = 0.0
    for m in ms:
        for x in xs:
            theirs = miepython.efficiencies_mx(m, float(x))
            ours = mie.efficiencies(m, float(x))
            for k in (0, 1, 3):  # q_ext, q_sca, g
                worst = max(worst, float(rel(ours[k], theirs[k])))
            if x < 500:  # above, miepython's shorter series leaves q_back off by 2e-6 (next test)
                assert rel(ours[2], theirs[2]) < 1e-6
    assert worst < 1e-6


def test_back_scattering_converged_where_a_shorter_series_is_not():
    # The alternating back sum converges last: summing 60 more terms than the talk's M changes
    # ours by < 1e-8, while miepython (M = x + 4.05 x^(1/3) + 2) is 1.7e-6 away at x = 1000.
    x = 1000.0
    assert rel(mie.efficiencies(1.33, x)[2], mie.back_efficiency_longer_series(1.33, x, 60)) < 1e-8


def test_amplitudes_match_miepython_and_the_reference():
    mu = np.array([0.9, 0.5, -0.3, -0.95])
    s1, s2 = mie.amplitudes(1.5 - 0.01j, 2.0, mu)
    r1, r2 = reference().amplitudes(1.5 + 0.01j, 2.0, list(mu))
    # ours are in the n - i kappa convention, the reference in Bohren & Huffman's
    assert np.allclose(s1, np.conj(r1), rtol=1e-9, atol=0)
    assert np.allclose(s2, np.conj(r2), rtol=1e-9, atol=0)
    miepython = pytest.importorskip("miepython")
    t1, t2 = miepython.S1_S2(1.5 - 0.01j, 2.0, mu, norm="wiscombe")
    assert np.allclose(s1, t1, rtol=1e-9) and np.allclose(s2, t2, rtol=1e-9)


@pytest.mark.parametrize("m, x", [(1.33, 0.5), (1.5 - 0.2j, 8.0), (2.0, 60.0)])
def test_optical_theorem_and_forward_amplitudes(m, x):
    s1, s2 = mie.amplitudes(m, x, np.array([1.0]))
    assert s1[0] == pytest.approx(s2[0], rel=1e-12)
    # Bohren & Huffman 4.76: Q_ext = 4 Re S(0) / x^2
    assert 4 * s1[0].real / x**2 == pytest.approx(mie.efficiencies(m, x)[0], rel=1e-10)


@pytest.mark.parametrize("n_med", [1.0, 1.33 - 1e-3j])
def test_phase_function_is_normalised_and_its_mean_cosine_is_g(n_med):
    mu = np.cos(np.linspace(0, np.pi, 40001))[::-1]
    p = mie.phase_function(1.5 - 0.01j, 6.0, mu, n_med)
    assert 2 * np.pi * np.trapezoid(p, mu) == pytest.approx(1.0, abs=1e-5)
    g = mie.efficiencies(1.5 - 0.01j, 6.0, n_med)[3]
    assert 2 * np.pi * np.trapezoid(p * mu, mu) == pytest.approx(g, abs=1e-5)


def test_weighted_phase_function_is_the_mixture():
    mu = np.linspace(-1, 1, 7)
    p1 = mie.phase_function(1.5, 1.0, mu)
    p2 = mie.phase_function(1.5, 4.0, mu)
    mix = mie.phase_function(np.array([1.5, 1.5]), np.array([1.0, 4.0]), mu, weights=np.array([1.0, 3.0]))
    assert np.allclose(mix, (p1 + 3 * p2) / 4, rtol=1e-12)


def test_phase_function_compiles_once_whatever_arrays_it_is_given():
    # Read-only, broadcast or strided inputs are other types to numba: each was a compilation.
    from render._mie_kernels import _phase_mix_kernel

    mu = np.linspace(-1, 1, 14)
    frozen = mu.copy()
    frozen.setflags(write=False)
    plain = mie.phase_function(np.array([1.5, 1.5]), np.array([1.0, 4.0]), mu, weights=np.array([1.0, 3.0]))
    odd = mie.phase_function(1.5, np.array([1.0, 4.0]), frozen[::1], weights=np.array([1.0, 3.0]))
    strided = mie.phase_function(1.5, np.array([1.0, 4.0]), np.repeat(mu, 2)[::2], weights=[1.0, 3.0])
    assert np.array_equal(plain, odd) and np.array_equal(plain, strided)
    assert len(_phase_mix_kernel.signatures) == 1


@pytest.mark.parametrize("x", [1e-3, 1e-5, 1e-8, 1e-12, 1e-40])
@pytest.mark.parametrize("m", [1.5, 1.5 - 0.1j, 0.7, 3 - 2j])
def test_rayleigh_limit(m, x):
    # Bohren & Huffman 5.8-5.9 with K = (m^2 - 1)/(m^2 + 2); corrections are O(x^2) relative.
    k = (complex(m) ** 2 - 1) / (complex(m) ** 2 + 2)
    q_ext, q_sca, q_back, g = mie.efficiencies(m, x)
    tol = max(10 * x * x * max(1.0, abs(m) ** 2), 1e-9)
    assert q_sca == pytest.approx(8 / 3 * x**4 * abs(k) ** 2, rel=tol)
    assert q_back == pytest.approx(4 * x**4 * abs(k) ** 2, rel=tol)
    q_abs = -4 * x * k.imag  # n - i kappa: Im K < 0 absorbs
    assert q_ext - q_sca == pytest.approx(q_abs, rel=tol, abs=1e-300)
    assert abs(g) < 10 * x * x
    assert all(math.isfinite(v) for v in (q_ext, q_sca, q_back, g))


@pytest.mark.parametrize(
    "m, x",
    [(1.5, 1e4), (1.5, 1e5), (1.33 - 1e-5j, 3e4), (100 - 100j, 50.0), (2 - 50j, 2000.0), (1 + 1e-9, 300.0)],
)
def test_no_overflow_or_nan_where_methods_struggle(m, x):
    q = mie.efficiencies(m, x)
    assert all(math.isfinite(v) for v in q)
    assert 0 <= q[1] <= q[0] + 1e-12 and -1 <= q[3] <= 1
    if x >= 1e4:
        assert q[0] == pytest.approx(2.0, abs=0.01)  # the extinction paradox


def test_m_close_to_one_scales_as_the_square_of_the_contrast():
    # Rayleigh–Gans: Q_sca is proportional to |m - 1|^2 as m -> 1, at any size.
    for x in (0.5, 5.0, 50.0):
        q1 = mie.efficiencies(1 + 1e-7, x)[1]
        q2 = mie.efficiencies(1 + 2e-7, x)[1]
        assert q2 / q1 == pytest.approx(4.0, rel=1e-5)
    assert mie.efficiencies(1.0, 5.0)[1] < 1e-28


def test_zero_size_scatters_nothing():
    assert mie.efficiencies(1.5, 0.0) == (0.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"m": 1.5, "x": -1.0}, "x: expected size parameters >= 0"),
        ({"m": 1.5 + 0.1j, "x": 1.0}, "kappa >= 0"),
        ({"m": -1.5, "x": 1.0}, "m: expected a positive real part"),
        ({"m": 1.5, "x": math.nan}, "expected finite values"),
        ({"m": 1.5, "x": 1.0, "n_med": 1.33 + 0.1j}, "n_med: expected n - i*kappa"),
        ({"m": 1.5, "x": 1e5, "n_med": 1.33 - 0.1j}, "the host absorbs"),
        ({"m": np.ones(2), "x": np.ones(3)}, "broadcast"),
    ],
)
def test_bad_input_is_a_clear_error(kwargs, message):
    with pytest.raises(ValueError, match=message.replace("*", r"\*").replace("(", r"\(")):
        mie.efficiencies(**kwargs)


def test_bad_angles():
    with pytest.raises(ValueError, match=r"mu: expected cosines in \[-1, 1\]"):
        mie.amplitudes(1.5, 1.0, np.array([0.0, 1.5]))
