"""Slow reference: the albedo of a half-space of isotropic scatterers by a Monte Carlo random walk.

Photons arrive from a diffuse (cosine-weighted) outside; with ``eta > 1`` each is refracted
into the medium with probability ``1 - F`` (unpolarised Fresnel) and counted relative to the
photons that got in, which is what ``render.translucency.diffuse_albedo`` defines. Inside,
exponential free paths (sigma_t = 1), isotropic scattering, survival ``albedo`` per event;
a photon that crosses z = 0 upwards has come back. No interface on the way out.
"""

from __future__ import annotations

import numpy as np


def albedo(single_scattering_albedo: float, eta: float = 1.0, photons: int = 200_000, seed: int = 1) -> float:
    """Fraction of the photons that entered which come back out (relative index ``eta``)."""
    rng = np.random.default_rng(seed)
    cos_i = np.sqrt(rng.random(photons))
    sin_t2 = (1 - cos_i**2) / eta**2
    cos_t = np.sqrt(1 - sin_t2)
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    enters = rng.random(photons) >= 0.5 * (rs**2 + rp**2)
    uz = cos_t[enters]
    n = uz.size
    z = np.zeros(n)
    alive = np.ones(n, dtype=bool)
    back = 0
    while alive.any():
        idx = np.nonzero(alive)[0]
        z[idx] += -np.log(rng.random(idx.size)) * uz[idx]
        out = z[idx] < 0
        back += int(out.sum())
        alive[idx[out]] = False
        idx = idx[~out]
        absorbed = rng.random(idx.size) >= single_scattering_albedo
        alive[idx[absorbed]] = False
        idx = idx[~absorbed]
        uz[idx] = 2 * rng.random(idx.size) - 1
    return back / n
