"""Slow reference: Lorenz–Mie coefficients from mpmath's Bessel functions at high precision.

Written from the formulas (Bohren & Huffman 1983 eqs. 4.53, 4.56, 4.61, 4.62, 4.74, 4.82;
Frisvad, Christensen & Jensen 2007 for the absorbing host), with no recurrences of our own:
psi_n(z) = z j_n(z) and xi_n(z) = z h_n^(1)(z) straight from mpmath, so it checks the numba
kernels' recurrences independently. Indices here in Bohren & Huffman's n + i kappa.

mpmath is in the dev extra only, so it is imported when a function first runs, not with
this module: without it, calling one raises ``ImportError`` (``pip install mpmath``).
"""

from __future__ import annotations

from typing import Any


def _mpmath() -> Any:
    import mpmath

    return mpmath


def _psi(n: int, z):
    mp = _mpmath()
    return mp.sqrt(mp.pi * z / 2) * mp.besselj(n + mp.mpf(1) / 2, z)


def _xi(n: int, z):
    mp = _mpmath()
    return mp.sqrt(mp.pi * z / 2) * (mp.besselj(n + mp.mpf(1) / 2, z) + 1j * mp.bessely(n + mp.mpf(1) / 2, z))


def coefficients(m: complex, x: complex, n_terms: int, dps: int = 40) -> tuple[list, list]:
    """a_n, b_n (n = 1..n_terms) for relative index m and (possibly complex) size parameter x.

    FCJ07's form with n_med = 1 after dividing by the host's index:
    a_n = (psi_n'(y) psi_n(x) - m psi_n(y) psi_n'(x)) / (psi_n'(y) xi_n(x) - m psi_n(y) xi_n'(x)).
    """
    mp = _mpmath()
    with mp.workdps(dps):
        m = mp.mpc(m)
        x = mp.mpc(x)
        y = m * x
        a, b = [], []
        psi_x_prev, psi_y_prev, xi_x_prev = _psi(0, x), _psi(0, y), _xi(0, x)
        for n in range(1, n_terms + 1):
            psi_x, psi_y, xi_x = _psi(n, x), _psi(n, y), _xi(n, x)
            dpsi_x = psi_x_prev - n * psi_x / x
            dpsi_y = psi_y_prev - n * psi_y / y
            dxi_x = xi_x_prev - n * xi_x / x
            a.append((dpsi_y * psi_x - m * psi_y * dpsi_x) / (dpsi_y * xi_x - m * psi_y * dxi_x))
            b.append((m * dpsi_y * psi_x - psi_y * dpsi_x) / (m * dpsi_y * xi_x - psi_y * dxi_x))
            psi_x_prev, psi_y_prev, xi_x_prev = psi_x, psi_y, xi_x
        return a, b


def efficiencies(
    m: complex, x: float, host_k: float = 0.0, dps: int = 40
) -> tuple[float, float, float, float]:
    """(q_ext, q_sca, q_back, g); m = n + i kappa relative to the host n_med = n'(1 + i host_k).

    The number of terms is well past Wiscombe's so that truncation is not what is measured.
    """
    mp = _mpmath()
    with mp.workdps(dps):
        nu = mp.mpc(1, host_k)
        xc = x * nu
        n_terms = int(abs(xc) + 6 * abs(xc) ** (1 / 3) + 12)
        a, b = coefficients(m, xc, n_terms, dps)
        sca = mp.fsum((2 * n + 1) * (abs(a[n - 1]) ** 2 + abs(b[n - 1]) ** 2) for n in range(1, n_terms + 1))
        ext = mp.fsum((2 * n + 1) * (a[n - 1] + b[n - 1]) / nu**2 for n in range(1, n_terms + 1))
        back = mp.fsum((-1) ** n * (2 * n + 1) * (a[n - 1] - b[n - 1]) for n in range(1, n_terms + 1))
        gsum = mp.fsum(
            n * (n + 2) / mp.mpf(n + 1) * mp.re(a[n - 1] * mp.conj(a[n]) + b[n - 1] * mp.conj(b[n]))
            + (2 * n + 1) / mp.mpf(n * (n + 1)) * mp.re(a[n - 1] * mp.conj(b[n - 1]))
            for n in range(1, n_terms)
        )
        alpha = 2 * mp.im(xc)
        # FCJ07: C_s carries exp(-alpha) / gamma, gamma = 2 (1 + (alpha - 1) e^alpha) / alpha^2.
        factor = (
            mp.mpf(1) if alpha == 0 else mp.exp(-alpha) * alpha**2 / (2 * (1 + (alpha - 1) * mp.exp(alpha)))
        )
        q_sca = 2 * factor * sca / (x**2 * abs(nu) ** 2)
        q_ext = 2 * mp.re(ext) / x**2
        q_back = q_sca * abs(back) ** 2 / (2 * sca)
        g = 2 * gsum / sca
        return float(q_ext), float(q_sca), float(q_back), float(g)


def amplitudes(m: complex, x: float, mu: list[float], dps: int = 30) -> tuple[list[complex], list[complex]]:
    """S1, S2 (BH 4.74, BH convention) at cosines mu in a clear host, pi_n and tau_n from mpmath's
    associated Legendre functions (pi_n = P_n^1 / sin, tau_n = dP_n^1 / d theta)."""
    mp = _mpmath()
    with mp.workdps(dps):
        n_terms = int(x + 6 * x ** (1 / 3) + 12)
        a, b = coefficients(m, x, n_terms, dps)
        s1s, s2s = [], []
        for u in mu:
            u = mp.mpf(u)
            theta = mp.acos(u)
            s1 = s2 = mp.mpc(0)
            for n in range(1, n_terms + 1):
                # P_n^1 without the Condon-Shortley phase, as Bohren & Huffman use it.
                pi_n = mp.diff(lambda t, n=n: mp.legendre(n, mp.cos(t)), theta) / -mp.sin(theta)
                tau_n = mp.diff(lambda t, n=n: -mp.diff(lambda s: mp.legendre(n, mp.cos(s)), t), theta)
                c = mp.mpf(2 * n + 1) / (n * (n + 1))
                s1 += c * (a[n - 1] * pi_n + b[n - 1] * tau_n)
                s2 += c * (a[n - 1] * tau_n + b[n - 1] * pi_n)
            s1s.append(complex(s1))
            s2s.append(complex(s2))
        return s1s, s2s
