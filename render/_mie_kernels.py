"""The Lorenz-Mie series as numba kernels (private; :mod:`render.mie` documents and wraps them).

See :mod:`render.mie` for the method, the recurrences and the conventions.
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


_CHUNK = 32  # spheres per parallel task: enough work to amortise the task, small enough to balance


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
