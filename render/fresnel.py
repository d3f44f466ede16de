"""Fresnel reflectance of a smooth dielectric interface, and its hemispherical averages.

The talk's formulas ("Ray tracing specular surfaces"): with relative index
``eta = n_t / n_i`` and ``cos_t = sqrt(1 - sin^2(theta_i) / eta^2)``,

    r_perp = (cos_i - eta cos_t) / (cos_i + eta cos_t)
    r_par  = (eta cos_i - cos_t) / (eta cos_i + cos_t)
    R = (r_perp^2 + r_par^2) / 2            (unpolarised)

and ``R = 1`` beyond the critical angle (total internal reflection, ``eta < 1``).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _fresnel(cos_i: float, eta: float) -> float:
    cos_i = min(abs(cos_i), 1.0)
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    if sin2_t >= 1.0:
        return 1.0
    cos_t = math.sqrt(1.0 - sin2_t)
    r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (r_perp * r_perp + r_par * r_par)


@njit(cache=True)
def _fresnel_array(cos_i: np.ndarray, eta: float, out: np.ndarray) -> None:
    for k in range(cos_i.size):
        out[k] = _fresnel(cos_i[k], eta)


def fresnel_dielectric(cos_theta_i: np.ndarray | float, eta: float) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a smooth dielectric interface.

    Parameters
    ----------
    cos_theta_i : array_like
        Cosine of the angle of incidence, measured from the normal on the incident
        side (its sign is ignored).
    eta : float
        Relative refractive index ``n_t / n_i`` (1.5 for air into resin; 1/1.5 from
        inside the resin out, where total internal reflection gives 1).

    Returns
    -------
    ndarray
        Reflectance in [0, 1], shaped like ``cos_theta_i``.
    """
    if not (eta > 0.0 and math.isfinite(eta)):
        raise ValueError(f"eta: expected a positive finite relative index, got {eta}")
    c = np.asarray(cos_theta_i, dtype=np.float64)
    # Flat in and out, whatever the shape: one compiled specialisation instead of one per
    # number of dimensions.
    flat = np.ascontiguousarray(c).reshape(-1)
    out = np.empty_like(flat)
    _fresnel_array(flat, float(eta), out)
    return out.reshape(c.shape)


@functools.lru_cache(maxsize=64)
def diffuse_fresnel_reflectance(eta: float) -> float:
    """Hemispherical (cosine-weighted) average of the Fresnel reflectance, ``F_dr``.

    ``F_dr = 2 * integral_0^1 R(mu) mu dmu``. For light arriving diffusely from
    outside a resin of index 1.5, ``eta = 1.5`` gives about 0.092; from inside,
    ``eta = 1/1.5`` gives about 0.596 (mostly total internal reflection), and
    ``1 - F_dr(1/n) = (1 - F_dr(n)) / n^2``. Gauss-Legendre on each side of the
    critical angle, where ``R`` has its kink, so that 128 nodes reach rounding error.
    """
    nodes, weights = np.polynomial.legendre.leggauss(128)
    mu_c = math.sqrt(1.0 - eta * eta) if eta < 1.0 else 0.0
    total = mu_c * mu_c  # R = 1 below the critical cosine: 2 * integral_0^mu_c mu dmu
    mu = mu_c + (1.0 - mu_c) * 0.5 * (nodes + 1.0)
    total += (1.0 - mu_c) * float(np.sum(weights * fresnel_dielectric(mu, eta) * mu))
    return total
