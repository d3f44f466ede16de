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

A slab of thickness ``d`` has a second boundary; Donner & Jensen (2005, "Light diffusion in
multi-layered translucent materials", eqs. 11-12) mirror the dipole in both extrapolated
boundaries, ``z_b = 2 A D`` outside each face (``D = 1 / (3 sigma_t')``): pairs of poles at

    z_r,i = 2 i (d + 2 z_b) + z_r,    z_v,i = 2 i (d + 2 z_b) - z_r - 2 z_b,    i = -n..n,

whose fields give the reflected profile ``R(r)`` (exitance at the entry face) and the transmitted
one ``T(r)`` (at the far face) (:func:`slab_profiles`). ``i = 0`` alone is Jensen's dipole.
Each pole's integral over the plane is ``(alpha'/2) sign(z) exp(-sigma_tr |z|)``, which gives
the totals in closed form (:func:`slab_totals`).

``printapp/bench/reference/slab_walk.py`` is the Monte Carlo random walk in a half-space or slab
that tests/test_bssrdf.py compares these with. Previews render the same diffusion equation
solved in the tile's own box (:mod:`render.diffusion`, :mod:`render.subsurface`): in a small
tile that absorbs little, most light meets a wall, which the half-space and the slab do not
have; at three mean free paths the walk's reflectance (0.570) also sides with the box's
exponential sources (0.569) against the multipole's point sources (0.621).
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


SLAB_PAIRS = 12
"""Mirror pairs of the slab's multipole on each side of the dipole (``n`` above)."""


def _slab_poles(
    sigma_s: float, sigma_a: float, g: float, eta: float, thickness_mm: float, pairs: int
) -> tuple[float, float, np.ndarray, np.ndarray]:
    if not (math.isfinite(thickness_mm) and thickness_mm > 0):
        raise ValueError(f"thickness_mm: expected a positive thickness, got {thickness_mm!r}")
    alpha, sigma_tr, z_r, z_v = _params(sigma_s, sigma_a, g, eta)
    z_b = (z_v - z_r) / 2.0  # 2 A D: z_v = z_r + 4 A D
    i = np.arange(-pairs, pairs + 1, dtype=np.float64)
    period = 2.0 * i * (thickness_mm + 2.0 * z_b)
    return alpha, sigma_tr, period + z_r, period - z_r - 2.0 * z_b


def _pole_field(r: np.ndarray, z: np.ndarray, sigma_tr: float) -> np.ndarray:
    """``z (1 + sigma_tr d) exp(-sigma_tr d) / d^3`` summed with signs over poles at heights ``z``."""
    d = np.sqrt(r[..., None] ** 2 + z**2)
    return np.sum(z * (sigma_tr * d + 1.0) * np.exp(-sigma_tr * d) / d**3, axis=-1)


def slab_profiles(
    r_mm: np.ndarray | float,
    sigma_s: float,
    sigma_a: float,
    g: float,
    eta: float,
    thickness_mm: float,
    pairs: int = SLAB_PAIRS,
) -> tuple[np.ndarray, np.ndarray]:
    """``R(r)`` and ``T(r)`` (1/mm^2) of a slab (Donner & Jensen 2005, eqs. 11-12; module doc).

    Exitance at distance ``r`` (mm) from the entry point, per unit flux entering, on the entry
    face (``R``) and on the far face (``T``); both faces have the same relative index ``eta``.
    Coefficients in 1/mm. With ``thickness_mm`` many transport mean free paths, ``R`` is
    :func:`dipole_profile`.
    """
    alpha, sigma_tr, zr, zv = _slab_poles(sigma_s, sigma_a, g, eta, thickness_mm, pairs)
    r = np.asarray(r_mm, dtype=np.float64)
    scale = alpha / (4.0 * math.pi)
    reflect = scale * (_pole_field(r, zr, sigma_tr) - _pole_field(r, zv, sigma_tr))
    d = thickness_mm
    transmit = scale * (_pole_field(r, d - zr, sigma_tr) - _pole_field(r, d - zv, sigma_tr))
    return reflect, transmit


def slab_totals(
    sigma_s: float, sigma_a: float, g: float, eta: float, thickness_mm: float, pairs: int = SLAB_PAIRS
) -> tuple[float, float]:
    """The integrals of :func:`slab_profiles` over the plane: total reflectance and transmittance.

    Summed pole by pole; without absorption the truncated series carries part of the flux
    out to distances of about ``pairs`` times the thickness, so use the profiles' integral
    over a finite window there (as :mod:`render.subsurface` does).
    """
    alpha, sigma_tr, zr, zv = _slab_poles(sigma_s, sigma_a, g, eta, thickness_mm, pairs)

    def pole(z: np.ndarray) -> float:
        return float(np.sum(np.sign(z) * np.exp(-sigma_tr * np.abs(z))))

    d = thickness_mm
    return 0.5 * alpha * (pole(zr) - pole(zv)), 0.5 * alpha * (pole(d - zr) - pole(d - zv))
