"""Model no more than a scene needs: which representation of a printed relief to render.

Three representations of the printed surface, from cheapest to dearest:

* ``"model"``: the compact BRDF (the tabulated-NDF model of :mod:`render.tabulated_ndf`, or
  an analytic one of :mod:`render.brdf_model`) on the smooth base shape;
* ``"table"``: the traced BRDF table itself, on the base shape;
* ``"geometry"``: the displaced microgeometry in smooth resin, the reference.

A BRDF stands in for geometry only where the camera cannot resolve the relief: where
many relief features fall in one pixel, a pixel sees the relief's average
reflectance, which is its BRDF. Where features span pixels, their shading and
shadows are what is seen, and only geometry shows them. The chooser compares the
relief's base feature size with the pixel footprint at the object, with a threshold
measured by ``printapp bench render`` (:data:`GEOMETRY_FROM_FEATURES_PER_PIXEL`), and
between the two BRDFs takes the compact model unless its error against the traced table
is above ``max(10 %, 3 x the table's noise)`` (:func:`tolerance_for`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from render.brdf_model import MicrofacetBRDF
from render.fresnel import diffuse_fresnel_reflectance
from render.gonio import direction_from_angles, estimate_brdf
from render.mitsuba_bsdfs import CompactSurface, TableSurface
from render.mitsuba_tabulated import TabulatedSurface
from render.tabulated_ndf import TabulatedMicrofacet

REPRESENTATIONS = ("model", "table", "geometry")

GEOMETRY_FROM_FEATURES_PER_PIXEL = 1.5
"""Render geometry where one relief feature spans at least this many pixels.

From ``printapp bench render`` (docs/benchmarks.md, "render"): on its test tile the
compact model's image error against the geometry reference (noise taken off) is 3.9 % at
1.1 pixels per feature and 6.8 % at 2.2 (3.3 % and 7.1 % under the soft box alone); 5 %
falls at about 1.5. Below that, the pixels average the relief into its BRDF; above it,
the camera sees the features themselves."""

MODEL_TOLERANCE = 0.10
"""The smallest tolerance of :func:`tolerance_for`: the compact model may stand in for the
table where it misses it by at most 10 %, or by three times the table's own noise where
that is more (a difference the noise could make)."""


def tolerance_for(table_noise: float) -> float:
    """Largest relative error at which the compact model may stand in for the traced table.

    ``max(10 %, 3 x table_noise)``: an error below three times the table's own noise cannot
    be told from it. Without a finite noise, 10 %.
    """
    if table_noise is None or not math.isfinite(table_noise):
        return MODEL_TOLERANCE
    return max(MODEL_TOLERANCE, 3.0 * float(table_noise))


@dataclass(frozen=True)
class Choice:
    """The representation chosen, and why."""

    mode: str
    reason: str
    pixels_per_feature: float


def choose_representation(
    feature_size_mm: float,
    pixel_footprint_mm: float,
    fit_error: float,
    *,
    table_noise: float = math.nan,
    geometry_from: float = GEOMETRY_FROM_FEATURES_PER_PIXEL,
    model_tolerance: float | None = None,
) -> Choice:
    """The cheapest representation that shows what the camera can see.

    Parameters
    ----------
    feature_size_mm : float
        Size of the relief's base features (mm).
    pixel_footprint_mm : float
        Width of a pixel at the object (mm).
    fit_error : float
        Relative error of the compact model against the traced table.
    table_noise : float
        The table's own relative noise on the same bins; the tolerance is
        :func:`tolerance_for` of it (10 % without it), unless ``model_tolerance`` is given.
    """
    tolerance = tolerance_for(table_noise) if model_tolerance is None else model_tolerance
    if not (feature_size_mm > 0 and pixel_footprint_mm > 0):
        raise ValueError("feature_size_mm and pixel_footprint_mm must be positive")
    pixels = feature_size_mm / pixel_footprint_mm
    if pixels >= geometry_from:
        return Choice(
            "geometry",
            f"relief features span {pixels:.2g} pixels (>= {geometry_from:g}): the camera resolves them",
            pixels,
        )
    if math.isfinite(fit_error) and fit_error <= tolerance:
        return Choice(
            "model",
            f"relief features span {pixels:.2g} pixels (< {geometry_from:g}) and the compact model fits "
            f"the traced BRDF to {fit_error:.1%}",
            pixels,
        )
    return Choice(
        "table",
        f"relief features span {pixels:.2g} pixels (< {geometry_from:g}) but the compact model misses the "
        f"traced BRDF by {fit_error:.1%} (> {tolerance:.1%})",
        pixels,
    )


def _body_k(rho: float, f_int: float) -> float:
    return rho / (1.0 - rho * f_int)


def body_tint(body_rgb: tuple[float, float, float], grey: float, ior: float) -> tuple[float, float, float]:
    """Per-channel factors that turn a body term traced at albedo ``grey`` into ``body_rgb``'s.

    The body term is proportional to ``rho / (1 - rho F_dr,int)`` (the internal
    reflections summed), so the factor per channel is that ratio.
    """
    f_int = diffuse_fresnel_reflectance(1.0 / ior)
    base = _body_k(grey, f_int)
    if base <= 0.0:
        return (0.0, 0.0, 0.0)
    return tuple(_body_k(c, f_int) / base for c in body_rgb)  # type: ignore[return-value]


def compact_surface(
    model: MicrofacetBRDF | TabulatedMicrofacet, body_rgb: tuple[float, float, float], grey: float
) -> CompactSurface | TabulatedSurface:
    """Representation (a) from a compact model; the model's (grey) body albedo is given the design's tint.

    An analytic model becomes a :class:`CompactSurface`, the tabulated-NDF model a
    :class:`render.mitsuba_tabulated.TabulatedSurface`.
    """
    scale = model.body_albedo / grey if grey > 0 else 0.0
    rgb = tuple(min(1.0, c * scale) for c in body_rgb)
    if isinstance(model, TabulatedMicrofacet):
        return TabulatedSurface(
            model.ndf.density,
            model.ndf.extent,
            model.ndf.spike_weight,
            model.spike_alpha,
            model.ndf.area,
            model.ms_factor,
            model.surface_albedo,
            model.body_kernel,
            model.ior,
            rgb,  # type: ignore[arg-type]
        )
    return CompactSurface(
        model.distribution,
        model.alpha_u,
        model.alpha_v,
        model.azimuth_rad,
        model.ior,
        rgb,  # type: ignore[arg-type]
        model.spike_weight,
        model.spike_alpha if model.spike_weight > 0 else 0.002,
    )


def table_surface(
    heights_mm: np.ndarray,
    pitch_x_mm: float,
    pitch_y_mm: float,
    *,
    ior: float,
    body_rgb: tuple[float, float, float],
    grey: float,
    rays: int = 20_000,
    n_theta_i: int = 10,
    n_phi_i: int = 12,
    n_theta: int = 45,
    n_phi: int = 90,
    theta_i_max_deg: float = 85.0,
    seed: int = 0,
    periodic: bool = False,
) -> TableSurface:
    """Representation (b): trace the relief's BRDF over a grid of incident directions.

    ``n_theta_i`` polar angles evenly from 0 to ``theta_i_max_deg`` times ``n_phi_i``
    azimuths, ``rays`` each (the first row, at normal incidence, is traced once and
    repeated).
    """
    theta_i = np.radians(np.linspace(0.0, theta_i_max_deg, n_theta_i))
    phi_i = np.arange(n_phi_i) * (2.0 * math.pi / n_phi_i)
    tt, pp = np.meshgrid(theta_i[1:], phi_i, indexing="ij")
    wi = np.vstack([direction_from_angles(0.0, 0.0), direction_from_angles(tt.ravel(), pp.ravel())])
    table = estimate_brdf(
        heights_mm,
        pitch_x_mm,
        pitch_y_mm,
        wi,
        rays=rays,
        ior=ior,
        body_albedo=grey,
        n_theta=n_theta,
        n_phi=n_phi,
        seed=seed,
        periodic=periodic,
    )
    spec = np.empty((n_theta_i, n_phi_i, n_theta, n_phi))
    body = np.empty_like(spec)
    spec[0] = table.f_specular[0]
    body[0] = table.f[0] - table.f_specular[0]
    spec[1:] = table.f_specular[1:].reshape(n_theta_i - 1, n_phi_i, n_theta, n_phi)
    body[1:] = (table.f[1:] - table.f_specular[1:]).reshape(n_theta_i - 1, n_phi_i, n_theta, n_phi)
    return TableSurface(spec, body, math.radians(theta_i_max_deg), body_tint(body_rgb, grey, ior))
