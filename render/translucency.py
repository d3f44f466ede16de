"""From scattering properties to what a renderer needs: a body albedo, a BSSRDF or a medium, and which.

Three representations of a scattering material behind a smooth dielectric surface:

* the *body albedo* (cheap): the resin is Mitsuba's ``plastic``, a Lambertian body under the
  interface, whose internal reflections ``plastic`` accounts for itself. The body's albedo is
  that of a semi-infinite medium with isotropic scattering of single-scattering albedo
  ``a' = sigma_s' / (sigma_a + sigma_s')``, ``sigma_s' = sigma_s (1 - g)`` (the similarity
  relation, which carries anisotropic scattering over to isotropic scattering with the same
  diffusion; e.g. Wyman, Patterson & Wilson 1989, J. Comput. Phys. 81, 137), lit by diffuse
  light refracted through the surface: Chandrasekhar's (1950, Radiative Transfer, ch. V) exact
  plane albedo ``A(mu0) = 1 - sqrt(1 - a') H(mu0)`` averaged over the refracted directions
  with their Fresnel transmittance (:func:`diffuse_albedo`). ``H`` solves
  ``1/H(mu) = sqrt(1 - a') + a'/2 int_0^1 mu' H(mu') / (mu + mu') dmu'``, iterated on 48
  Gauss–Legendre nodes. It is exact for isotropic scattering (tests compare it with a Monte
  Carlo random walk); the similarity relation and the Lambertian exit are the approximations.
* the *BSSRDF* (tiles only): the light entering the tile diffuses through its box and comes
  back out as a glow (:mod:`render.subsurface`, :mod:`render.diffusion`); rendered without
  Monte Carlo noise, but the diffusion approximation needs light to scatter many times before
  it leaves;
* the *medium* (costly): a homogeneous medium with sigma_s, sigma_a and a Henyey–Greenstein
  phase function with the ensemble's g, inside a smooth dielectric boundary (the relief in the
  mesh is the rough surface).

"Model no more than a scene needs" (DESIGN.md): light wandering under the surface changes
what is seen only when it goes, before its direction is randomised, farther than a pixel sees:
when the transport mean free path ``ell* = 1 / (sigma_a + sigma_s')`` exceeds
``MEDIUM_THRESHOLD`` times the pixel footprint on the object (``printapp bench mie``). Then
the BSSRDF, while ``ell*`` is at most ``BSSRDF_MAX_MFP_OVER_THICKNESS`` times the part's
thickness, and the medium beyond, where light crosses the part in a few steps and
diffusion no longer holds (``printapp bench translucency``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from render.colour import cie1931_cmf, spectrum_to_rgb

MEDIUM_THRESHOLD = 1.0
"""Transport mean free path over pixel footprint above which the light under the surface is rendered.

``printapp bench mie`` renders a relief tile both ways for transport mean free paths from
0.1 to 30 pixel footprints: below one footprint the two images differ by a constant floor
(about 3.5 8-bit levels, the models' difference for an opaque resin); from one footprint on
the body albedo's error climbs above it (docs/benchmarks.md, section "mie")."""

BSSRDF_MAX_MFP_OVER_THICKNESS = 0.5
"""Transport mean free path over the part's thickness up to which the BSSRDF stands in for the
medium. ``printapp bench translucency`` (docs/benchmarks.md) renders a 3 mm relief tile both
ways against a converged medium: the BSSRDF's error is 3-7 % up to 0.37, 9.5 % at 0.55 and
18 % at 1 (where light crosses the part in a few steps and diffusion fails); 10 % falls at
about 0.57, and this keeps a little below it."""

_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(48)
_MU = 0.5 * (_NODES + 1.0)
_W = 0.5 * _WEIGHTS


def _fresnel_unpolarised(cos_i: np.ndarray, eta: float) -> tuple[np.ndarray, np.ndarray]:
    """Fresnel reflectance from outside (index 1) into index ``eta``, and the refracted cosine."""
    sin_t2 = (1.0 - cos_i**2) / eta**2
    cos_t = np.sqrt(np.clip(1.0 - sin_t2, 0.0, None))
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (rs**2 + rp**2), cos_t


def _h_function(albedo: np.ndarray) -> np.ndarray:
    """Chandrasekhar's H(mu) for isotropic scattering at the Gauss nodes, one row per albedo."""
    s = np.sqrt(1.0 - albedo)[:, None]
    h = np.ones((albedo.size, _MU.size))
    kernel = (_W * _MU)[None, :] / (_MU[:, None] + _MU[None, :])  # w_j mu_j / (mu_i + mu_j)
    for _ in range(4000):
        h_new = 1.0 / (s + 0.5 * albedo[:, None] * (h @ kernel.T))
        if np.max(np.abs(h_new - h)) < 1e-13:
            return h_new
        h = h_new
    return h


def diffuse_albedo(single_scattering_albedo: np.ndarray | float, eta: float = 1.0) -> np.ndarray:
    """Albedo of a half-space of isotropic scatterers lit diffusely through a smooth interface.

    Parameters
    ----------
    single_scattering_albedo : float or array in [0, 1]
        ``a'`` (use the similarity-reduced ``sigma_s' / (sigma_a + sigma_s')`` for anisotropic
        scattering).
    eta : float
        Index of the medium relative to the outside. ``eta = 1``: the bihemispherical
        reflectance ``1 - 2 sqrt(1 - a') int_0^1 H(mu) mu dmu``. ``eta > 1``: the plane albedo
        ``1 - sqrt(1 - a') H(mu_t)`` (Chandrasekhar 1950, ch. V) averaged over the directions
        that diffuse light from outside refracts into, weighted by its Fresnel transmittance
        ``(1 - F(mu_i)) 2 mu_i``: refraction bends light towards the normal, where it goes deeper
        and comes back less. The interface itself (reflection, the internal reflections of the
        light on its way out) is not included: that is the ``plastic`` model's part.

    Returns
    -------
    array of the same shape as ``single_scattering_albedo``.
    """
    a = np.asarray(single_scattering_albedo, dtype=np.float64)
    if not np.all(np.isfinite(a)) or np.any(a < 0) or np.any(a > 1):
        raise ValueError("single_scattering_albedo: expected values in [0, 1]")
    if not (math.isfinite(eta) and eta >= 1.0):
        raise ValueError(f"eta: expected a relative index >= 1, got {eta!r}")
    flat = a.ravel()
    h = _h_function(flat)
    s = np.sqrt(1.0 - flat)
    if eta == 1.0:
        albedo = 1.0 - 2.0 * s * (h @ (_W * _MU))
    else:
        fresnel, cos_t = _fresnel_unpolarised(_MU, eta)
        weight = _W * 2.0 * _MU * (1.0 - fresnel)
        h_t = np.stack([np.interp(cos_t, _MU, row) for row in h])
        albedo = 1.0 - s * (h_t @ weight) / weight.sum()
    return np.clip(albedo, 0.0, 1.0).reshape(a.shape)


@dataclass(frozen=True)
class MediumRGB:
    """A homogeneous medium in linear RGB: coefficients per millimetre, one HG asymmetry."""

    sigma_s_per_mm: tuple[float, float, float]
    sigma_a_per_mm: tuple[float, float, float]
    g: float

    @property
    def transport_mfp_mm(self) -> tuple[float, float, float]:
        out = []
        for s, a in zip(self.sigma_s_per_mm, self.sigma_a_per_mm, strict=True):
            total = a + s * (1.0 - self.g)
            out.append(math.inf if total <= 0 else 1.0 / total)
        return tuple(out)  # type: ignore[return-value]


@dataclass(frozen=True)
class Appearance:
    """What a material looks like to the renderer, both ways, reduced to RGB."""

    refractive_index: float
    body_albedo: tuple[float, float, float]
    medium: MediumRGB
    transport_mfp_mm: tuple[float, float, float]


def appearance_from_spectra(
    wavelength_nm: np.ndarray,
    host_index: np.ndarray,
    sigma_s_per_mm: np.ndarray,
    sigma_a_per_mm: np.ndarray,
    g: np.ndarray,
) -> Appearance:
    """Reduce spectral scattering properties to a body albedo, a medium and an index, in RGB.

    The body albedo is computed per wavelength (:func:`diffuse_albedo` of the reduced albedo)
    and then reduced like a reflectance spectrum; coefficients are reduced as spectra with
    :func:`render.colour.spectrum_to_rgb`, ``g`` weighted by ``sigma_s``; the index is the
    host's real part weighted by the luminance function y-bar.
    """
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    s = np.asarray(sigma_s_per_mm, dtype=np.float64)
    a = np.asarray(sigma_a_per_mm, dtype=np.float64)
    gg = np.asarray(g, dtype=np.float64)
    ybar = cie1931_cmf(lam)[..., 1]
    index = float(np.sum(ybar * np.real(host_index)) / np.sum(ybar))
    reduced = s * (1.0 - gg)
    with np.errstate(invalid="ignore", divide="ignore"):
        single = np.where(reduced + a > 0, reduced / (reduced + a), 0.0)
    eta = max(1.0, index)
    albedo_rgb = spectrum_to_rgb(diffuse_albedo(np.clip(single, 0.0, 1.0), eta), lam)
    s_rgb = spectrum_to_rgb(s, lam)
    a_rgb = spectrum_to_rgb(np.clip(a, 0.0, None), lam)
    sg_rgb = spectrum_to_rgb(s * gg, lam)
    g_rgb = np.divide(sg_rgb, s_rgb, out=np.zeros(3), where=s_rgb > 0)
    g_one = float(np.sum(s_rgb * g_rgb) / np.sum(s_rgb)) if np.sum(s_rgb) > 0 else 0.0
    medium = MediumRGB(
        tuple(float(v) for v in s_rgb),  # type: ignore[arg-type]
        tuple(float(v) for v in a_rgb),  # type: ignore[arg-type]
        float(np.clip(g_one, -0.99, 0.99)),
    )
    mfp = []
    for sc, ab, gc in zip(s_rgb, a_rgb, g_rgb, strict=True):
        total = ab + sc * (1.0 - gc)
        mfp.append(math.inf if total <= 0 else 1.0 / float(total))
    return Appearance(
        refractive_index=index,
        body_albedo=tuple(float(min(max(v, 0.0), 1.0)) for v in albedo_rgb),  # type: ignore[arg-type]
        medium=medium,
        transport_mfp_mm=tuple(mfp),  # type: ignore[arg-type]
    )


def choose_translucency(
    transport_mfp_mm: tuple[float, ...] | np.ndarray,
    footprint_mm: float,
    threshold: float = MEDIUM_THRESHOLD,
    thickness_mm: float | None = None,
    bssrdf_limit: float = BSSRDF_MAX_MFP_OVER_THICKNESS,
) -> Literal["medium", "bssrdf", "albedo"]:
    """The representation the view needs, by the largest transport mean free path ``ell*``.

    ``"albedo"`` while ``ell*`` is at most ``threshold`` pixel footprints (the light's wandering
    is not seen); else ``"bssrdf"`` when a ``thickness_mm`` is given (a tile: the BSSRDF is
    rendered for tiles only) and ``ell*`` is at most ``bssrdf_limit`` times it; else ``"medium"``.
    """
    if not (footprint_mm > 0 and math.isfinite(footprint_mm)):
        raise ValueError(f"footprint_mm: expected a positive length, got {footprint_mm!r}")
    if thickness_mm is not None and not (thickness_mm > 0 and math.isfinite(thickness_mm)):
        raise ValueError(f"thickness_mm: expected a positive length, got {thickness_mm!r}")
    longest = float(np.max(np.asarray(transport_mfp_mm, dtype=np.float64)))
    if longest <= threshold * footprint_mm:
        return "albedo"
    if thickness_mm is not None and longest <= bssrdf_limit * thickness_mm:
        return "bssrdf"
    return "medium"
