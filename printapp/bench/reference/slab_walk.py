"""A plain Monte Carlo random walk in a scattering half-space or slab: where entering light comes out.

The slow, simple reference for :mod:`render.bssrdf`'s dipole. Photons enter at the origin,
straight down; they fly exponential distances with the reduced extinction ``sigma_t'``,
scatter isotropically with probability ``alpha'`` (else they are absorbed), and at the
surface leave with the Fresnel transmittance of an interface of relative index ``eta``
(else they are reflected back in). The exit points' distances from the origin are returned.
Vectorised over photons in numpy; nothing clever.
"""

from __future__ import annotations

import numpy as np


def _fresnel(cos_i: np.ndarray, eta: float) -> np.ndarray:
    """Unpolarised Fresnel reflectance for light inside (index eta) meeting the boundary at cos_i."""
    sin_t2 = eta * eta * (1.0 - cos_i * cos_i)
    out = np.ones_like(cos_i)
    ok = sin_t2 < 1.0
    cos_t = np.sqrt(1.0 - sin_t2[ok])
    ci = cos_i[ok]
    rs = (eta * ci - cos_t) / (eta * ci + cos_t)
    rp = (ci - eta * cos_t) / (ci + eta * cos_t)
    out[ok] = 0.5 * (rs * rs + rp * rp)
    return out


def exit_radii(
    photons: int, sigma_s: float, sigma_a: float, g: float = 0.0, eta: float = 1.0, seed: int = 0
) -> np.ndarray:
    """Distances (mm) from the entry point at which the photons that came back out left the surface.

    ``len(result) / photons`` is the total diffuse reflectance; a histogram over annuli,
    divided by the annuli's areas and ``photons``, is the exitance profile ``R_d(r)``.
    """
    return slab_exit_radii(photons, sigma_s, sigma_a, g, eta, np.inf, seed)[0]


def slab_exit_radii(
    photons: int,
    sigma_s: float,
    sigma_a: float,
    g: float = 0.0,
    eta: float = 1.0,
    thickness_mm: float = np.inf,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """As :func:`exit_radii` in a slab of ``thickness_mm``: exit radii at the entry face and at the far face.

    Both faces have the relative index ``eta``.
    """
    rng = np.random.default_rng(seed)
    reduced = sigma_s * (1.0 - g)
    sigma_t = sigma_a + reduced
    alpha = reduced / sigma_t
    pos = np.zeros((photons, 3))
    direction = np.tile([0.0, 0.0, 1.0], (photons, 1))  # z grows with depth
    radii: list[np.ndarray] = []
    through: list[np.ndarray] = []
    alive = np.arange(photons)
    while alive.size:
        step = rng.exponential(1.0 / sigma_t, alive.size)
        new = pos[alive] + direction[alive] * step[:, None]
        keep = np.ones(alive.size, dtype=bool)
        out = (new[:, 2] < 0.0) | (new[:, 2] > thickness_mm)
        if np.any(out):
            # Crossing a face: move to it, then leave or be reflected back in.
            idx = alive[out]
            d = direction[idx]
            face = np.where(d[:, 2] < 0.0, 0.0, thickness_mm)
            t = (face - pos[idx, 2]) / d[:, 2]
            at = pos[idx] + d * t[:, None]
            leave = rng.random(idx.size) >= _fresnel(np.abs(d[:, 2]), eta)
            top = leave & (face == 0.0)
            radii.append(np.hypot(at[top, 0], at[top, 1]))
            bottom = leave & (face != 0.0)
            through.append(np.hypot(at[bottom, 0], at[bottom, 1]))
            back = idx[~leave]
            pos[back] = at[~leave]
            direction[back, 2] = -direction[back, 2]
            keep[np.flatnonzero(out)[leave]] = False
        inside = ~out
        pos[alive[inside]] = new[inside]
        # Scatter (isotropically) or be absorbed, at the interaction points.
        scatter_here = alive[inside]
        absorbed = rng.random(scatter_here.size) >= alpha
        mu = rng.uniform(-1.0, 1.0, scatter_here.size)
        phi = rng.uniform(0.0, 2.0 * np.pi, scatter_here.size)
        s = np.sqrt(1.0 - mu * mu)
        direction[scatter_here] = np.stack([s * np.cos(phi), s * np.sin(phi), mu], axis=1)
        keep[np.flatnonzero(inside)[absorbed]] = False
        alive = alive[keep]
    empty = np.zeros(0)
    return (np.concatenate(radii) if radii else empty), (np.concatenate(through) if through else empty)
