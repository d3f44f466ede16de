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

import math

import numpy as np
from numba import njit, prange

P_TERMS = 4.3
"""The talk's ``p`` in ``M = ceil(|x| + p |x|^(1/3) + 1)``: a truncation error below 1e-8."""
X_RAYLEIGH = 1e-10
"""Below this size parameter the series is replaced by its Rayleigh limit, exact to
``O(x^2)`` relative, i.e. to rounding: the series' Riccati–Bessel functions would
overflow for ``x`` below about 1e-60."""
MAX_X = 1e6
MAX_ABS_M = 1e4
MAX_HOST_ALPHA = 100.0
"""Largest host absorption over a particle, ``alpha = 4 pi r Im(n_med) / lambda``."""
_CHUNK = 32


@njit(cache=True)
def _n_terms(size: float) -> int:
    return int(math.ceil(size + P_TERMS * size ** (1.0 / 3.0) + 1.0))


@njit(cache=True)
def _n_start(n_terms: int, size_y: float) -> int:
    # Start the downward recurrences past the turning point n = |y| by several widths of the
    # transition zone (|y|^(1/3)), where an arbitrary start value has decayed below rounding.
    top = max(float(n_terms), size_y)
    return int(top + 8.0 * top ** (1.0 / 3.0) + 16.0)


@njit(cache=True)
def _lentz(z, n, max_terms):
    """D_n(z) from the continued fraction for J_(n-1/2)(z) / J_(n+1/2)(z) (Lentz 1976, Appl. Opt.
    15, 668, with Thompson & Barnett's guard against zero denominators), or ``nan`` when it
    has not converged within ``max_terms`` terms."""
    nu = n + 0.5
    inv = 2.0 / z
    f = nu * inv
    c = f
    dd = 0j
    sign = -1.0
    for k in range(1, max_terms + 1):
        bk = sign * (nu + k) * inv
        sign = -sign
        dd = bk + dd
        if dd == 0:
            dd = 1e-300
        dd = 1.0 / dd
        c = bk + 1.0 / c
        if c == 0:
            c = 1e-300
        delta = c * dd
        f *= delta
        if abs(delta - 1.0) < 1e-16:
            return f - n / z
    return complex(math.nan, math.nan)


@njit(cache=True)
def _downward_start(z, nmax, size):
    """Where to start the downward recurrence of D_n(z) and with which value.

    Far above the turning point ``n = |z|`` any start value is forgotten (``_n_start``); when that
    is a long way above ``nmax`` (large, strongly absorbing ``z``), the continued fraction gives
    D_(nmax+1) directly in fewer steps, if it converges within half the recurrence's cost.
    """
    far = _n_start(nmax, size)
    near = nmax + 1
    if far - near > 64:
        value = _lentz(z, near, far - near)
        if value == value:
            return near, value
    return far, 0j


@njit(cache=True)
def _ab_clear(m, x, a, b, absorb, d, ax):
    """a_n, b_n (BH convention, m = n + i kappa) for n = 1..len(a) in a clear host.

    ``absorb[n-1]`` gets ``Re(a_n + b_n) - |a_n|^2 - |b_n|^2`` without cancellation.
    ``d`` and ``ax`` are scratch arrays of length ``len(a) + 1``.
    """
    nmax = a.shape[0]
    y = m * x
    # D_n(y) = psi_n'(y) / psi_n(y), downwards.
    nstart, dn = _downward_start(y, nmax, abs(y))
    if nstart <= nmax:
        d[nstart] = dn
    for n in range(nstart, 1, -1):
        nz = n / y
        dn = nz - 1.0 / (dn + nz)
        if n - 1 <= nmax:
            d[n - 1] = dn
    # A_n(x), the same for the real x, needed only above n = x.
    n_switch = int(math.floor(x)) + 1
    an = 0.0
    nstart_x = _n_start(nmax, x)
    for n in range(nstart_x, n_switch, -1):
        nz = n / x
        an = nz - 1.0 / (an + nz)
        if n - 1 <= nmax:
            ax[n - 1] = an
    sx = math.sin(x)
    cx = math.cos(x)
    psi_nm2, psi_nm1 = cx, sx  # psi_-1, psi_0
    chi_nm2, chi_nm1 = -sx, cx  # chi_-1, chi_0 (BH: xi_n = psi_n - i chi_n)
    for n in range(1, nmax + 1):
        nx = n / x
        # Upwards while psi_n oscillates; above n = x from the ratio psi_(n-1) / psi_n.
        psi_n = (2 * n - 1) / x * psi_nm1 - psi_nm2 if n < n_switch else psi_nm1 / (ax[n] + nx)
        chi_n = (2 * n - 1) / x * chi_nm1 - chi_nm2
        pa = d[n] / m + nx
        ua = pa * psi_n - psi_nm1
        wa = ua - 1j * (pa * chi_n - chi_nm1)
        pb = m * d[n] + nx
        ub = pb * psi_n - psi_nm1
        wb = ub - 1j * (pb * chi_n - chi_nm1)
        a[n - 1] = ua / wa
        b[n - 1] = ub / wb
        wa2 = wa.real * wa.real + wa.imag * wa.imag
        wb2 = wb.real * wb.real + wb.imag * wb.imag
        absorb[n - 1] = -(pa.imag / wa2 + pb.imag / wb2)
        psi_nm2, psi_nm1 = psi_nm1, psi_n
        chi_nm2, chi_nm1 = chi_nm1, chi_n


@njit(cache=True)
def _exp_2iz_minus_1(z):
    """exp(2 i z) - 1 without cancellation for small z."""
    re = -2.0 * z.imag
    im = 2.0 * z.real
    em1 = math.expm1(re)
    s = math.sin(0.5 * im)
    return complex(em1 * math.cos(im) - 2.0 * s * s, (em1 + 1.0) * math.sin(im))


@njit(cache=True)
def _ab_host(m, xc, a, b, ay, ax):
    """a_n, b_n (BH convention) in an absorbing host (FCJ07 sec. 3): complex size parameter ``xc``.

    ``m`` is the particle's index relative to the host's complex index.
    """
    nmax = a.shape[0]
    y = m * xc
    for z, out in ((y, ay), (xc, ax)):
        nstart, an = _downward_start(z, nmax, abs(z))
        for n in range(nstart, 0, -1):
            nz = n / z
            if n <= nmax:
                out[n] = an
            an = nz - 1.0 / (an + nz)
    # psi_0 zeta_0 = (1 - exp(2iz)) / 2, psi_0 / zeta_0 = (1 - exp(-2iz)) / 2, B_0 = i.
    psi_zeta = -0.5 * _exp_2iz_minus_1(xc)
    ratio = -0.5 * _exp_2iz_minus_1(-xc)
    b_prev = 1j
    for n in range(1, nmax + 1):
        nz = n / xc
        inv = 1.0 / (ax[n] + nz)  # = n/z - A_(n-1)(z): no cancellation at small z
        psi_zeta = psi_zeta * inv * (nz - b_prev)
        bn = ax[n] + 1j / psi_zeta
        ratio = ratio * (bn + nz) * inv
        a[n - 1] = ratio * (ay[n] - m * ax[n]) / (ay[n] - m * bn)
        b[n - 1] = ratio * (m * ay[n] - ax[n]) / (m * ay[n] - bn)
        b_prev = bn


@njit(cache=True)
def _scattering_factor(alpha: float) -> float:
    """FCJ07's ``exp(-alpha) / gamma`` with ``gamma = 2 (1 + (alpha - 1) e^alpha) / alpha^2``."""
    if alpha < 1e-3:
        return 1.0 / (1.0 - alpha / 3.0 + alpha * alpha / 12.0 - alpha**3 / 60.0)
    return alpha * alpha * math.exp(-2.0 * alpha) / (2.0 * (math.exp(-alpha) + alpha - 1.0))


@njit(cache=True)
def _rayleigh(m, x):
    """Small-sphere limit (BH sec. 5.2; g and the back term to leading order, Wiscombe 1979)."""
    m2 = m * m
    k = (m2 - 1.0) / (m2 + 2.0)
    k2 = k.real * k.real + k.imag * k.imag
    qsca = 8.0 / 3.0 * x**4 * k2
    qabs = 4.0 * x * k.imag
    # g to leading order: Re(a1 conj(a2 + b1)) / |a1|^2 with the x^2 terms of Wiscombe's
    # small-particle coefficients a2 = i x^2 (m^2-1)/(15 (2m^2+3)), b1 = i x^2 (m^2-1)/45.
    a1 = 2j * k / 3.0
    a2 = 1j * x * x * (m2 - 1.0) / (15.0 * (2.0 * m2 + 3.0))
    b1 = 1j * x * x * (m2 - 1.0) / 45.0
    num = a1 * np.conj(a2 + b1)
    a1s = a1.real * a1.real + a1.imag * a1.imag
    g = num.real / a1s if a1s > 0.0 else 0.0
    qback = 4.0 * x**4 * k2
    return qsca + qabs, qsca, qback, g


@njit(cache=True)
def _sums(a, b, nmax):
    """Sum_(2n+1)(|a|^2+|b|^2), sum (-1)^n (2n+1)(a-b), and the asymmetry sum (BH 4.62/4.74)."""
    sca = 0.0
    back = 0j
    gsum = 0.0
    sign = -1.0
    for i in range(nmax):
        n = i + 1.0
        c = 2.0 * n + 1.0
        ai = a[i]
        bi = b[i]
        sca += c * (ai.real * ai.real + ai.imag * ai.imag + bi.real * bi.real + bi.imag * bi.imag)
        back += sign * c * (ai - bi)
        sign = -sign
        gsum += c / (n * (n + 1.0)) * (ai.real * bi.real + ai.imag * bi.imag)
        if i + 1 < nmax:
            an1 = a[i + 1]
            bn1 = b[i + 1]
            gsum += (
                n
                * (n + 2.0)
                / (n + 1.0)
                * (ai.real * an1.real + ai.imag * an1.imag + bi.real * bn1.real + bi.imag * bn1.imag)
            )
    return sca, back, gsum


@njit(cache=True)
def _sphere(m, x, host_k, a, b, absorb, c1, c2, r1):
    """(q_ext, q_sca, q_back, g) for one sphere; BH-convention ``m``; ``host_k = Im/Re of n_med``."""
    if x <= 0.0:
        return 0.0, 0.0, 0.0, 0.0
    if host_k == 0.0:
        if x < X_RAYLEIGH:
            return _rayleigh(m, x)
        nmax = _n_terms(x)
        _ab_clear(m, x, a[:nmax], b[:nmax], absorb[:nmax], c1, r1)
        sca, back, gsum = _sums(a, b, nmax)
        qabs = 0.0
        for i in range(nmax):
            qabs += (2.0 * i + 3.0) * absorb[i]
        x2 = x * x
        qsca = 2.0 * sca / x2
        qext = qsca + 2.0 * qabs / x2
        qback = (back.real * back.real + back.imag * back.imag) / x2
        g = 2.0 * gsum / sca if sca > 0.0 else 0.0
        return qext, qsca, qback, g
    nu = complex(1.0, host_k)
    xc = x * nu
    nmax = _n_terms(abs(xc))
    _ab_host(m, xc, a[:nmax], b[:nmax], c1, c2)
    sca, back, gsum = _sums(a, b, nmax)
    ext = 0j
    inv_nu2 = 1.0 / (nu * nu)
    for i in range(nmax):
        ext += (2.0 * i + 3.0) * (a[i] + b[i]) * inv_nu2
    x2 = x * x
    factor = _scattering_factor(2.0 * xc.imag)
    qsca = 2.0 * factor * sca / (x2 * (1.0 + host_k * host_k))
    qext = 2.0 * ext.real / x2
    if sca > 0.0:
        qback = qsca * (back.real * back.real + back.imag * back.imag) / (2.0 * sca)
        g = 2.0 * gsum / sca
    else:
        qback = 0.0
        g = 0.0
    return qext, qsca, qback, g


@njit(cache=True)
def _buffer_size(x, host_k):
    return _n_terms(x * math.sqrt(1.0 + host_k * host_k)) + 2


@njit(cache=True)
def _efficiencies_chunk(m, x, host_k, out, lo, hi):
    size = 0
    for i in range(lo, hi):
        size = max(size, _buffer_size(x[i], host_k[i]))
    a = np.empty(size, np.complex128)
    b = np.empty(size, np.complex128)
    absorb = np.empty(size, np.float64)
    c1 = np.empty(size, np.complex128)
    c2 = np.empty(size, np.complex128)
    r1 = np.empty(size, np.float64)
    for i in range(lo, hi):
        q = _sphere(m[i], x[i], host_k[i], a, b, absorb, c1, c2, r1)
        out[i, 0] = q[0]
        out[i, 1] = q[1]
        out[i, 2] = q[2]
        out[i, 3] = q[3]


@njit(parallel=True, cache=True)
def _efficiencies_kernel(m, x, host_k, out):
    n = x.shape[0]
    nchunks = (n + _CHUNK - 1) // _CHUNK
    for c in prange(nchunks):
        _efficiencies_chunk(m, x, host_k, out, c * _CHUNK, min(n, (c + 1) * _CHUNK))


@njit(cache=True)
def _coefficients(m, x, host_k, a, b):
    """Fill a, b (zeros beyond the returned number of terms) for one sphere of size x > 0."""
    size = a.shape[0]
    if x < X_RAYLEIGH:
        # Only the electric dipole is left (BH 5.2); a_1 in the BH convention.
        nu = complex(1.0, host_k)
        m2 = m * m
        a[0] = -2j / 3.0 * (m2 - 1.0) / (m2 + 2.0) * (x * nu) ** 3
        return 1
    absorb = np.empty(size, np.float64)
    c1 = np.empty(size, np.complex128)
    c2 = np.empty(size, np.complex128)
    r1 = np.empty(size, np.float64)
    if host_k == 0.0:
        nmax = _n_terms(x)
        _ab_clear(m, x, a[:nmax], b[:nmax], absorb[:nmax], c1, r1)
    else:
        nmax = _n_terms(abs(x * complex(1.0, host_k)))
        _ab_host(m, x * complex(1.0, host_k), a[:nmax], b[:nmax], c1, c2)
    return nmax


@njit(cache=True)
def _amplitudes_one(a, b, nmax, mu, s1, s2):
    """S1, S2 (BH 4.74) at each mu from a_n, b_n; pi_n, tau_n by BH's upward recurrence."""
    for k in range(mu.shape[0]):
        u = mu[k]
        pi_nm1 = 0.0
        pi_n = 1.0
        t1 = 0j
        t2 = 0j
        for i in range(nmax):
            n = i + 1.0
            tau_n = n * u * pi_n - (n + 1.0) * pi_nm1
            c = (2.0 * n + 1.0) / (n * (n + 1.0))
            t1 += c * (a[i] * pi_n + b[i] * tau_n)
            t2 += c * (a[i] * tau_n + b[i] * pi_n)
            pi_next = ((2.0 * n + 1.0) * u * pi_n - (n + 1.0) * pi_nm1) / n
            pi_nm1 = pi_n
            pi_n = pi_next
        s1[k] = t1
        s2[k] = t2


@njit(parallel=True, cache=True)
def _amplitudes_kernel(m, x, host_k, mu, s1, s2, norm):
    for i in prange(x.shape[0]):
        size = _buffer_size(x[i], host_k[i])
        a = np.zeros(size, np.complex128)
        b = np.zeros(size, np.complex128)
        nmax = 0 if x[i] <= 0.0 else _coefficients(m[i], x[i], host_k[i], a, b)
        _amplitudes_one(a, b, nmax, mu, s1[i], s2[i])
        total = 0.0
        for j in range(nmax):
            total += (2.0 * j + 3.0) * (abs(a[j]) ** 2 + abs(b[j]) ** 2)
        norm[i] = total


@njit(parallel=True, cache=True)
def _phase_mix_kernel(m, x, host_k, weight, mu, out):
    """out[c, k] = sum over the particles of chunk c of weight_i * p_i(mu_k) (p over 4 pi sr)."""
    n = x.shape[0]
    nchunks = out.shape[0]
    per = (n + nchunks - 1) // nchunks
    nmu = mu.shape[0]
    for c in prange(nchunks):
        s1 = np.empty(nmu, np.complex128)
        s2 = np.empty(nmu, np.complex128)
        for i in range(c * per, min(n, (c + 1) * per)):
            if weight[i] == 0.0 or x[i] <= 0.0:
                continue
            size = _buffer_size(x[i], host_k[i])
            a = np.zeros(size, np.complex128)
            b = np.zeros(size, np.complex128)
            nmax = _coefficients(m[i], x[i], host_k[i], a, b)
            total = 0.0
            for j in range(nmax):
                total += (2.0 * j + 3.0) * (abs(a[j]) ** 2 + abs(b[j]) ** 2)
            if total <= 0.0:
                continue
            _amplitudes_one(a, b, nmax, mu, s1, s2)
            scale = weight[i] / (4.0 * math.pi * total)
            for k in range(nmu):
                out[c, k] += scale * (abs(s1[k]) ** 2 + abs(s2[k]) ** 2)


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
        np.ascontiguousarray(np.conj(m_b).ravel()),
        np.ascontiguousarray(x_b.ravel()),
        np.ascontiguousarray(host_k.ravel()),
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
    mu_arr = np.atleast_1d(np.asarray(mu, dtype=np.float64))
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
    mu_arr = np.atleast_1d(np.asarray(mu, dtype=np.float64))
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
    _phase_mix_kernel(m_f, x_f, h_f, np.ascontiguousarray(w), mu_arr, out)
    return out.sum(axis=0) / total
