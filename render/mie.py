"""Lorenz–Mie scattering by a homogeneous sphere in a clear or an absorbing host.

The formulas are the talk's ("Light-material interaction in a volume", slides "The Lorenz-Mie
coefficients", "Scattering by spherical particles", "Quantity of scattering" and "Computing
scattering properties"), which follow Frisvad, Christensen & Jensen 2007, "Computing the
scattering properties of participating media using Lorenz-Mie theory", ACM TOG 26(3), 60
(FCJ07 below):

- size parameters ``x = 2 pi r n_med / lambda`` and ``y = 2 pi r n_p / lambda``;
- number of terms ``M = ceil(|x| + p |x|^(1/3) + 1)`` with ``p = 4.3`` for a 1e-8 error
  (Wiscombe 1980; Cachorro & Salcedo 1991);
- the coefficients ``a_n``, ``b_n`` from Riccati–Bessel functions ``psi_n`` and ``zeta_n``;
- ``S_1``, ``S_2`` from ``pi_n``, ``tau_n``, the phase function
  ``p = (|S_1|^2 + |S_2|^2) / (2 |k|^2 C_s)``, and the cross sections ``C_t`` and ``C_s``
  (for an absorbing host with FCJ07's factor ``exp(-alpha) / gamma``).

Two kernels compute ``a_n`` and ``b_n``:

* clear host (real ``n_med``): Bohren & Huffman 1983 (BH, sec. 4.8) with the logarithmic
  derivative ``D_n(mx)`` by downward recurrence (Wiscombe 1980; started from Lentz's 1976
  continued fraction where that is cheaper, i.e. for large strongly absorbing spheres,
  else far enough above ``|mx|`` that the start value is forgotten), ``chi_n`` by upward
  recurrence and ``psi_n`` upwards while ``n < x`` and, above ``x``, from the ratio
  ``psi_(n-1) / psi_n = A_n(x) + n/x`` with ``A_n(x)`` by downward recurrence (Miller's
  idea: the decaying solution is never run upwards, so tiny ``x`` stays accurate).
  The absorption of each term is computed from the Wronskian
  ``psi_n chi_(n-1) - psi_(n-1) chi_n = -1``: ``Re a_n - |a_n|^2 = -Im(D_n/m) / |w_n|^2``
  with ``w_n`` the denominator of ``a_n`` (likewise ``b_n`` with ``m D_n``), so ``Q_ext``
  never loses digits to the cancellation ``Re a_n - |a_n|^2`` of weakly absorbing spheres.
* absorbing host (complex ``n_med``): FCJ07 sec. 3, with ``A_n`` for both size parameters
  by downward recurrence, ``psi_n zeta_n`` and ``R_n = psi_n / zeta_n`` by upward
  recurrence (Yang 2003, Appl. Opt. 42, 1710), ``B_n = A_n + i / (psi_n zeta_n)``.

Conventions: the public functions take indices written ``n - i kappa`` with ``kappa >= 0``
for an absorbing material (miepython's convention, time factor ``exp(+i omega t)``);
internally everything is Bohren & Huffman's ``n + i kappa`` (time factor
``exp(-i omega t)``), so the inputs are conjugated once here and the amplitudes conjugated
back. Size parameters are real: ``x = 2 pi r Re(n_med) / lambda``; with an absorbing host
the kernel uses the complex ``x n_med / Re(n_med)``. Efficiencies are cross sections over
``pi r^2``.
"""

from __future__ import annotations

import numpy as np

from render._mie_kernels import (
    _CHUNK,
    _ab_clear,
    _amplitudes_kernel,
    _efficiencies_chunk,
    _efficiencies_kernel,
    _n_terms,
    _phase_mix_kernel,
    _sums,
)

MAX_X = 1e6
MAX_ABS_M = 1e4
MAX_HOST_ALPHA = 100.0
"""Largest host absorption over a particle, ``alpha = 4 pi r Im(n_med) / lambda``."""


# ---------------------------------------------------------------------------------------------
# Public wrappers: validation, broadcasting, conventions.


def _prepare(m, x, n_med) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[int, ...]]:
    m_arr = np.asarray(m, dtype=np.complex128)
    x_arr = np.asarray(x, dtype=np.float64)
    h_arr = np.asarray(n_med, dtype=np.complex128)
    try:
        m_b, x_b, h_b = np.broadcast_arrays(m_arr, x_arr, h_arr)
    except ValueError:
        raise ValueError(
            f"m, x, n_med: expected shapes that broadcast together, got {m_arr.shape}, {x_arr.shape}, "
            f"{h_arr.shape}"
        ) from None
    if not (np.all(np.isfinite(m_b)) and np.all(np.isfinite(x_b)) and np.all(np.isfinite(h_b))):
        raise ValueError("m, x, n_med: expected finite values")
    if np.any(x_b < 0):
        raise ValueError(f"x: expected size parameters >= 0, got {x_b.min():g}")
    if np.any(x_b > MAX_X):
        raise ValueError(f"x: expected size parameters <= {MAX_X:g}, got {x_b.max():g}")
    if np.any(m_b.real <= 0):
        raise ValueError("m: expected a positive real part (the relative refractive index)")
    if np.any(h_b.real <= 0):
        raise ValueError("n_med: expected a positive real part")
    if np.any(h_b.imag > 0):
        raise ValueError("n_med: expected n - i*kappa with kappa >= 0 (miepython's sign convention)")
    # The particle's own index m n_med must not amplify; m itself may have either sign when
    # the host absorbs more than the particle.
    if np.any((m_b * h_b).imag > 1e-15 * np.abs(m_b * h_b)):
        raise ValueError(
            "m: expected the particle's index m * n_med as n - i*kappa with kappa >= 0 (miepython's sign "
            "convention)"
        )
    if np.any(np.abs(m_b) > MAX_ABS_M):
        raise ValueError(f"m: expected |m| <= {MAX_ABS_M:g}")
    host_k = -h_b.imag / h_b.real
    alpha = 2.0 * x_b * host_k
    if np.any(alpha > MAX_HOST_ALPHA):
        raise ValueError(
            f"n_med: the host absorbs exp(-{alpha.max():.3g}) across one particle; expected "
            f"4 pi r Im(n_med) / lambda <= {MAX_HOST_ALPHA:g} (the particle is invisible beyond that)"
        )
    shape = x_b.shape
    return (
        # Copies, contiguous and writable whatever was passed (a read-only array is another
        # type to numba, and another compilation of each kernel).
        np.array(np.conj(m_b).ravel(), order="C"),
        np.array(x_b.ravel(), order="C"),
        np.array(host_k.ravel(), order="C"),
        shape,
    )


def back_efficiency_longer_series(m: complex, x: float, extra_terms: int = 60) -> float:
    """``Q_back`` of one non-absorbing-host sphere, summed ``extra_terms`` beyond the talk's M.

    A convergence check, not a faster path: the alternating back-scattering series is the
    last to converge, so summing further shows how far :func:`efficiencies` is from the
    series' limit.
    """
    longer = _n_terms(x) + extra_terms
    a = np.zeros(longer + 2, complex)
    b = np.zeros(longer + 2, complex)
    _ab_clear(
        complex(m), float(x), a[:longer], b[:longer], np.zeros(longer), np.zeros(longer + 2, complex),
        np.zeros(longer + 2),
    )  # fmt: skip
    _, back, _ = _sums(a, b, longer)
    return float(abs(back) ** 2 / x**2)


def efficiencies(
    m: complex | np.ndarray, x: float | np.ndarray, n_med: complex | np.ndarray = 1.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Extinction, scattering and backscattering efficiencies and asymmetry of spheres.

    Parameters
    ----------
    m : complex or array
        Particle index relative to the host, ``n_p / n_med``, written ``n - i kappa``
        (``kappa >= 0`` absorbs) as miepython writes it. In an absorbing host the particle's
        own index ``m n_med`` must have ``kappa >= 0``; ``m`` itself may then have either sign.
    x : float or array
        Size parameter in the host, ``2 pi r Re(n_med) / lambda`` (dimensionless, >= 0).
    n_med : complex or array, optional
        The host's index ``n - i kappa``. A real host gives the classical theory (only ``m``
        and ``x`` matter); an absorbing one FCJ07's generalisation, where only
        ``kappa / n`` of the host matters.

    Returns
    -------
    q_ext, q_sca, q_back, g : arrays (floats for scalar input)
        ``C_t / (pi r^2)``, ``C_s / (pi r^2)`` (the talk's "Quantity of scattering" slide, with
        FCJ07's ``exp(-alpha) / gamma`` for an absorbing host), the backscattering efficiency
        ``4 pi p(180 deg) q_sca`` (BH 4.82 for a clear host) and the asymmetry parameter
        ``g = <cos theta>`` (BH 4.74). Shapes broadcast from the inputs.

    Raises
    ------
    ValueError
        On non-finite or negative size parameters, indices with a positive imaginary part, or a
        host that absorbs more than ``exp(-100)`` across one particle.
    """
    m_f, x_f, h_f, shape = _prepare(m, x, n_med)
    out = np.empty((x_f.size, 4), dtype=np.float64)
    if x_f.size > 4 * _CHUNK:
        _efficiencies_kernel(m_f, x_f, h_f, out)
    elif x_f.size:  # a few spheres are not worth waking the thread pool for
        _efficiencies_chunk(m_f, x_f, h_f, out, 0, x_f.size)
    parts = tuple(out[:, k].reshape(shape) for k in range(4))
    if shape == ():
        return tuple(float(p) for p in parts)  # type: ignore[return-value]
    return parts  # type: ignore[return-value]


def amplitudes(
    m: complex | np.ndarray,
    x: float | np.ndarray,
    mu: float | np.ndarray,
    n_med: complex | np.ndarray = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Scattering amplitudes ``S_1``, ``S_2`` of spheres at scattering-angle cosines ``mu``.

    The talk's "Scattering by spherical particles" slide (BH 4.74), unnormalised:
    ``|S_1|^2 + |S_2|^2`` integrates over ``mu`` in [-1, 1] to
    ``2 sum (2n+1)(|a_n|^2 + |b_n|^2)``. Returned in the ``n - i kappa`` convention (the
    complex conjugate of Bohren & Huffman's), as miepython does.

    Parameters
    ----------
    m, x, n_med : as for :func:`efficiencies` (broadcast together to a shape ``P``).
    mu : float or 1-D array
        Cosines of the scattering angle, in [-1, 1].

    Returns
    -------
    s1, s2 : complex arrays of shape ``P + mu.shape``.
    """
    # Copied (contiguous and writable whatever was passed): one compiled specialisation.
    mu_arr = np.array(mu, dtype=np.float64, ndmin=1, order="C")
    if mu_arr.ndim != 1 or not np.all(np.isfinite(mu_arr)) or np.any(np.abs(mu_arr) > 1.0):
        raise ValueError("mu: expected cosines in [-1, 1] as a number or a 1-D array")
    m_f, x_f, h_f, shape = _prepare(m, x, n_med)
    s1 = np.zeros((x_f.size, mu_arr.size), dtype=np.complex128)
    s2 = np.zeros_like(s1)
    norm = np.zeros(x_f.size)
    if x_f.size:
        _amplitudes_kernel(m_f, x_f, h_f, mu_arr, s1, s2, norm)
    out_shape = shape + ((mu_arr.size,) if np.ndim(mu) else ())
    return np.conj(s1).reshape(out_shape), np.conj(s2).reshape(out_shape)


def phase_function(
    m: complex | np.ndarray,
    x: float | np.ndarray,
    mu: float | np.ndarray,
    n_med: complex | np.ndarray = 1.0,
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """Phase function ``p(mu)`` (per steradian, integrating to 1 over the sphere) of spheres.

    The talk's ``p = (|S_1|^2 + |S_2|^2) / (2 |k|^2 C_s)``, written as
    ``(|S_1|^2 + |S_2|^2) / (4 pi sum (2n+1)(|a_n|^2 + |b_n|^2))`` so that it is normalised
    in an absorbing host too (FCJ07's factor cancels). With ``weights`` (one per sphere,
    e.g. ``N(r) dr C_s(r)``) it returns the weighted mixture ``sum w_i p_i / sum w_i``: the
    phase function of an ensemble (FCJ07 sec. 4).

    Returns
    -------
    1-D array over ``mu``.
    """
    # Copied (contiguous and writable whatever was passed): one compiled specialisation.
    mu_arr = np.array(mu, dtype=np.float64, ndmin=1, order="C")
    if mu_arr.ndim != 1 or not np.all(np.isfinite(mu_arr)) or np.any(np.abs(mu_arr) > 1.0):
        raise ValueError("mu: expected cosines in [-1, 1] as a number or a 1-D array")
    m_f, x_f, h_f, _ = _prepare(m, x, n_med)
    if weights is None:
        w = np.ones(x_f.size)
    else:
        w = np.broadcast_to(np.asarray(weights, dtype=np.float64), np.broadcast(m, x, n_med).shape).ravel()
        if not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ValueError("weights: expected finite values >= 0")
    total = float(w.sum())
    if total <= 0:
        raise ValueError("weights: expected at least one positive weight")
    nchunks = max(1, min(64, x_f.size))
    out = np.zeros((nchunks, mu_arr.size))
    _phase_mix_kernel(m_f, x_f, h_f, np.array(w, order="C"), mu_arr, out)
    return out.sum(axis=0) / total
