"""The dipole diffusion model of subsurface scattering (Jensen, Marschner, Levoy & Hanrahan 2001).

Light that enters a homogeneous, highly scattering half-space at one point comes back out
around it; the radiant exitance at distance ``r`` per unit flux entering is the dipole's
``R_d(r)``: a real point source at depth ``z_r = 1 / sigma_t'`` and a negative (virtual)
one at height ``z_v = z_r (1 + 4A/3)`` above the surface, where ``A`` carries the internal
reflection at a boundary of relative index ``eta`` (Groenhuis et al. 1983; ``F_dr`` from
Egan & Hilgeman's fit):

    R_d(r) = alpha' / (4 pi) [ z_r (sigma_tr d_r + 1) e^(-sigma_tr d_r) / d_r^3
                             + z_v (sigma_tr d_v + 1) e^(-sigma_tr d_v) / d_v^3 ],

``d_r = sqrt(r^2 + z_r^2)``, ``d_v = sqrt(r^2 + z_v^2)``, ``sigma_tr = sqrt(3 sigma_a sigma_t')``,
``alpha' = sigma_s' / sigma_t'`` and reduced coefficients ``sigma_s' = sigma_s (1 - g)``,
``sigma_t' = sigma_a + sigma_s'`` (Jensen et al. 2001, eqs. 4-5). Its integral over the plane
is ``(alpha'/2) (1 + exp(-4/3 A sqrt(3 (1 - alpha')))) exp(-sqrt(3 (1 - alpha')))`` (their eq. 6).

``printapp/bench/reference/slab_walk.py`` is the Monte Carlo random walk in a half-space that
tests/test_bssrdf.py compares this with. This module is the profile only: previews do not yet
render a BSSRDF (see docs/benchmarks.md, "render").
"""

from __future__ import annotations

import math

import numpy as np


def fresnel_diffuse_reflectance_fit(eta: float) -> float:
    """``F_dr`` for light inside a medium of relative index ``eta`` (Egan & Hilgeman 1979's fit)."""
    if not (math.isfinite(eta) and eta > 0):
        raise ValueError(f"eta: expected a positive relative index, got {eta!r}")
    return -1.440 / eta**2 + 0.710 / eta + 0.668 + 0.0636 * eta


def _params(sigma_s: float, sigma_a: float, g: float, eta: float) -> tuple[float, float, float, float]:
    if not (sigma_s >= 0 and sigma_a >= 0 and sigma_s + sigma_a > 0 and -1 < g < 1):
        raise ValueError("expected sigma_s, sigma_a >= 0 (not both 0) and -1 < g < 1")
    reduced = sigma_s * (1.0 - g)
    sigma_t = sigma_a + reduced
    alpha = reduced / sigma_t
    sigma_tr = math.sqrt(3.0 * sigma_a * sigma_t)
    f_dr = fresnel_diffuse_reflectance_fit(eta)
    a = (1.0 + f_dr) / (1.0 - f_dr)
    z_r = 1.0 / sigma_t
    return alpha, sigma_tr, z_r, z_r * (1.0 + 4.0 * a / 3.0)


def dipole_profile(
    r_mm: np.ndarray | float, sigma_s: float, sigma_a: float, g: float = 0.0, eta: float = 1.0
) -> np.ndarray:
    """``R_d(r)`` (1/mm^2): radiant exitance at distance ``r`` per unit flux entering (module doc).

    ``sigma_s``, ``sigma_a`` in 1/mm; ``g`` the phase function's mean cosine; ``eta`` the
    medium's index relative to the outside.
    """
    alpha, sigma_tr, z_r, z_v = _params(sigma_s, sigma_a, g, eta)
    r = np.asarray(r_mm, dtype=np.float64)
    d_r = np.sqrt(r * r + z_r * z_r)
    d_v = np.sqrt(r * r + z_v * z_v)
    real = z_r * (sigma_tr * d_r + 1.0) * np.exp(-sigma_tr * d_r) / d_r**3
    virtual = z_v * (sigma_tr * d_v + 1.0) * np.exp(-sigma_tr * d_v) / d_v**3
    return alpha / (4.0 * math.pi) * (real + virtual)


def dipole_total_reflectance(sigma_s: float, sigma_a: float, g: float = 0.0, eta: float = 1.0) -> float:
    """The integral of :func:`dipole_profile` over the plane (Jensen et al. 2001, eq. 6)."""
    alpha, _, _, _ = _params(sigma_s, sigma_a, g, eta)
    f_dr = fresnel_diffuse_reflectance_fit(eta)
    a = (1.0 + f_dr) / (1.0 - f_dr)
    root = math.sqrt(3.0 * (1.0 - alpha))
    return 0.5 * alpha * (1.0 + math.exp(-4.0 / 3.0 * a * root)) * math.exp(-root)
