"""A compact BRDF that fits what is printed: microfacets whose normal distribution is the relief's own.

The analytic models (:mod:`render.brdf_model`) assume a GGX or Beckmann distribution of
facet normals; a printed relief has its own, often neither (layer terraces, the printer's
pixel steps, grooves). Here the distribution is tabulated from the relief's facets, as
Dupuy et al. (2015, "Extracting microfacet-based BRDF parameters from arbitrary
materials with power iterations") tabulate a measured one, and every other term of the
microfacet model follows from the table:

* **D.** The tracer's facets (:func:`render.gonio.facet_slopes`, four per cell, equal
  areas) give normals ``m``; their projections ``(m_x, m_y)`` are deposited, cloud in
  cell, on an ``n x n`` grid of nodes over ``[-e, e]^2`` and read back bilinearly. The
  density of ``(m_x, m_y)`` over the macro area *is* ``D(m)``: ``D(m) cos(theta_m) d omega_m =
  D(m) dm_x dm_y``, so the table integrates to ``integral D cos d omega = 1``. Facets that
  are exactly flat (the tops of printed layers) are the mirror spike instead, with weight
  ``w`` (their share of the area): ``D_total = (1 - w) D + w delta(m - z)``.
* **Masking.** Smith's ``Lambda`` from the same table (Heitz 2014, "Understanding the
  masking-shadowing function in microfacet-based BRDFs", eq. 72 in slope space, eq. 17
  as the projected area): ``Lambda(o) cos(theta_o) = integral max(0, -o . m) D_total(m)
  d omega_m``, tabulated on a grid of directions and interpolated; ``G2`` is the
  height-correlated form ``1 / (1 + Lambda(i) + Lambda(o))`` (eq. 99).
* **Single scattering.** ``f_s = F(i . h) D_total(h) G2 / (4 cos(theta_i) cos(theta_o))``
  (Walter et al. 2007), F the dielectric Fresnel factor at the resin's index.
* **Multiple scattering.** A steep relief sends some light from facet to facet (9 % of the
  surface reflection at 75 degrees on a grooved Gaussian relief of slopes 0.25, measured by
  the tracer). Its energy is the expected second bounce of Smith's random walk (Heitz et al.
  2016, "Multiple-scattering microfacet BSDFs with the Smith model"): light a facet reflects
  into the surface (``1 - G2 / G1``) meets a facet drawn from those facing it, reflects
  with that facet's Fresnel factor and escapes with ``G1``. It is put back into the
  single-scattering lobe, whose shape it follows on reliefs like these (Turquin 2019,
  "Practical multiple scattering compensation for microfacet models"), reciprocally: the
  surface term is ``f_s(i, o) k(i) k(o)`` with ``k`` solved on the direction grid so that
  each direction's albedo is single plus double scattering.
* **Body.** The pigmented body under the interface, as in :mod:`render.brdf_model`.

The model has no free parameter but the body's albedo: everything else is the relief.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from render._tabulated_kernels import _deposit, _energies, _projected_area, _second_bounce
from render.fresnel import diffuse_fresnel_reflectance, fresnel_dielectric

NDF_NODES = 256
"""Nodes of the NDF table per side."""
DIR_THETA, DIR_PHI = 31, 48
"""The direction grid of the masking table: 3-degree polar steps, 7.5-degree azimuths."""
MS_THETA, MS_PHI = 16, 24
"""The coarser direction grid of the (smooth) multiple-scattering and albedo tables: 6 and 15 degrees."""
BOUNCE_THETA = 31
"""Polar nodes (0 to 180 degrees) of the second-bounce table, over the whole sphere of travel directions."""
SPIKE_ALPHA = 0.002
"""GGX roughness that stands for the mirror spike where a lobe must have a width (Mitsuba)."""
SMOOTH_FACETS = 16
"""Facets per node below which the NDF histogram is smoothed more than half a node."""
MS_NODES = 48
"""Nodes per side of the coarser NDF the (smooth) multiple-scattering integrals use."""
_MS_ROUNDS = 6


def direction_grid(n_theta: int, n_phi: int, theta_max: float) -> np.ndarray:
    """Unit directions ``(n_theta * n_phi, 3)``: polar angles evenly over [0, theta_max], azimuths round."""
    theta = np.linspace(0.0, theta_max, n_theta)
    phi = np.arange(n_phi) * (2.0 * math.pi / n_phi)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    return np.column_stack(
        [(np.sin(t) * np.cos(p)).ravel(), (np.sin(t) * np.sin(p)).ravel(), np.cos(t).ravel()]
    )


def grid_lookup(table: np.ndarray, theta_max: float, w: np.ndarray) -> np.ndarray:
    """Bilinear lookup of an ``(n_theta, n_phi)`` direction table at unit directions ``w`` (..., 3)."""
    n_t, n_p = table.shape
    theta = np.arccos(np.clip(w[..., 2], -1.0, 1.0))
    phi = np.arctan2(w[..., 1], w[..., 0]) % (2.0 * math.pi)
    ft = np.minimum(theta / theta_max * (n_t - 1), n_t - 1.0)
    i0 = np.minimum(ft.astype(np.int64), n_t - 2)
    at = ft - i0
    fp = phi / (2.0 * math.pi) * n_p
    j0 = np.floor(fp).astype(np.int64)
    ap = fp - j0
    j0 %= n_p
    j1 = (j0 + 1) % n_p
    low = (1.0 - ap) * table[i0, j0] + ap * table[i0, j1]
    high = (1.0 - ap) * table[i0 + 1, j0] + ap * table[i0 + 1, j1]
    return (1.0 - at) * low + at * high


@dataclass(frozen=True, eq=False)
class TabulatedNDF:
    """A relief's distribution of facet normals, its masking, and the flat part.

    Attributes
    ----------
    density : (n, n) array
        ``D(m)`` of the facets that are not flat, at nodes ``(m_x, m_y)`` evenly over
        ``[-extent, extent]^2`` (rows along ``m_y``, columns along ``m_x``), bilinear
        between them, zero outside the unit disk; ``sum density * step^2 = 1``.
    extent : float
        Half the side of the table in ``m_x`` and ``m_y`` (at most 1).
    spike_weight : float
        Share of the macro area whose facets are exactly flat (the mirror spike).
    area : (DIR_THETA, DIR_PHI) array
        ``Lambda(o) cos(theta_o)`` of the whole surface (spike included) on
        :func:`direction_grid` ``(DIR_THETA, DIR_PHI, pi / 2)``.
    alpha_u, alpha_v, azimuth_rad : float
        Beckmann-equivalent roughness of the facets that are not flat (``sqrt(2)`` times
        the principal standard deviations of their slopes) and the direction of ``alpha_u``,
        for a summary.
    """

    density: np.ndarray
    extent: float
    spike_weight: float
    area: np.ndarray
    alpha_u: float
    alpha_v: float
    azimuth_rad: float

    @property
    def step(self) -> float:
        """Spacing of the nodes in ``m_x`` and ``m_y``."""
        return 2.0 * self.extent / (self.density.shape[0] - 1)

    def nodes(self, coarse: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The whole surface as weighted normals ``(m (K, 3), w (K,))``: ``w = D_total dm_x dm_y``.

        With ``coarse``, blocks of nodes are pooled into their mass-weighted mean normals
        on a ``coarse x coarse`` grid (for integrals of smooth functions). The spike is the
        last entry, at ``(0, 0, 1)``.
        """
        d = self.density * self.step**2 * (1.0 - self.spike_weight)
        n = d.shape[0]
        x = np.linspace(-self.extent, self.extent, n)
        mx, my = np.meshgrid(x, x)
        if coarse is not None and coarse < n:
            block = -(-n // coarse)
            pad = block * coarse - n
            shape = (coarse, block, coarse, block)

            def pool(a: np.ndarray) -> np.ndarray:
                return np.pad(a, ((0, pad), (0, pad))).reshape(shape).sum(axis=(1, 3))

            mass = pool(d)
            with np.errstate(invalid="ignore", divide="ignore"):
                mx, my = pool(d * mx) / mass, pool(d * my) / mass
            d = mass
        keep = d > 0.0
        mx, my, w = mx[keep], my[keep], d[keep]
        mz = np.sqrt(np.clip(1.0 - mx * mx - my * my, 1e-12, None))
        m = np.column_stack([mx, my, mz])
        if self.spike_weight > 0.0:
            m = np.vstack([m, [0.0, 0.0, 1.0]])
            w = np.append(w, self.spike_weight)
        return np.ascontiguousarray(m), np.ascontiguousarray(w)

    def value(self, m: np.ndarray) -> np.ndarray:
        """``D(m)`` of the facets that are not flat (bilinear in ``(m_x, m_y)``), for unit ``m`` (..., 3)."""
        n = self.density.shape[0]
        fx = (m[..., 0] + self.extent) / self.step
        fy = (m[..., 1] + self.extent) / self.step
        inside = (fx >= 0) & (fx <= n - 1) & (fy >= 0) & (fy <= n - 1) & (m[..., 2] > 0)
        i0 = np.clip(np.floor(fx).astype(np.int64), 0, n - 2)
        j0 = np.clip(np.floor(fy).astype(np.int64), 0, n - 2)
        ax = np.clip(fx - i0, 0.0, 1.0)
        ay = np.clip(fy - j0, 0.0, 1.0)
        d = self.density
        v = (1 - ay) * ((1 - ax) * d[j0, i0] + ax * d[j0, i0 + 1]) + ay * (
            (1 - ax) * d[j0 + 1, i0] + ax * d[j0 + 1, i0 + 1]
        )
        return np.where(inside, v, 0.0)

    def smith_lambda(self, w: np.ndarray) -> np.ndarray:
        """Smith's ``Lambda`` of the whole surface for unit directions ``w`` (..., 3) above it."""
        return grid_lookup(self.area, math.pi / 2, w) / np.maximum(w[..., 2], 1e-12)


def tabulate_ndf(
    heights_mm: np.ndarray, pitch_x_mm: float, pitch_y_mm: float, *, periodic: bool = True,
    window: np.ndarray | None = None, nodes: int = NDF_NODES,
) -> TabulatedNDF:  # fmt: skip
    """The distribution of a relief's facet normals (the tracer's facets), tabulated.

    ``periodic=False`` (a patch cut from a larger relief) leaves out the cells that wrap
    around the patch's seam, a step that is not part of the relief. ``window`` (first
    cell and cells along x, then along y, as :func:`render.gonio.lit_window` gives them)
    takes only the facets of those cells: the part of a patch the tracer lights. On a
    patch of a relief whose features are large against it, the lit interior's slopes
    can differ from the whole patch's by tens of percent.

    The table spans the facets' normals (``extent`` is their largest ``|m_x|`` or
    ``|m_y|`` and two nodes more, at most 1), so that its resolution follows the
    relief: ``2 extent / (nodes - 1)`` in ``m_x`` and ``m_y``. Nodes whose bilinear
    cells reach outside the unit disk are emptied (normals within about two nodes of
    the horizon, slopes above 1 / (2 step), lose their share, and the table is
    renormalised).
    """
    from render.gonio import facet_slopes

    h = np.asarray(heights_mm, dtype=np.float64)
    if h.ndim != 2 or min(h.shape) < 2 or not np.all(np.isfinite(h)):
        raise ValueError("heights_mm: expected a finite 2-D array of at least 2x2 samples")
    gx, gy = facet_slopes(h, pitch_x_mm, pitch_y_mm)
    if not periodic or window is not None:
        inner = np.zeros(h.shape, dtype=bool)
        if window is None:
            inner[:-1, :-1] = True
        else:
            x0, nxw, y0, nyw = (int(v) for v in window)
            inner[y0 : y0 + nyw, x0 : x0 + nxw] = True
            if not periodic:
                inner[-1, :] = inner[:, -1] = False
        inner = np.tile(inner.ravel(), 4)
        gx, gy = gx[inner], gy[inner]
    return ndf_from_slopes(gx, gy, nodes=nodes)


def ndf_from_slopes(
    slope_x: np.ndarray, slope_y: np.ndarray, *, nodes: int = NDF_NODES, smooth: float | None = None
) -> TabulatedNDF:
    """The tabulated NDF of facets of equal area with slopes ``dh/dx``, ``dh/dy`` (see :func:`tabulate_ndf`).

    Facets with both slopes exactly zero are the mirror spike. The histogram is smoothed
    by a Gaussian of ``smooth`` nodes (default: enough that a node holds the share of
    about :data:`SMOOTH_FACETS` facets, 0.5 to 2 nodes): a relief of few facets would
    otherwise give a comb of nodes, noise that renders as glitter.
    """
    from render.microfacet import slope_roughness

    gx = np.asarray(slope_x, dtype=np.float64).ravel()
    gy = np.asarray(slope_y, dtype=np.float64).ravel()
    if gx.shape != gy.shape or gx.size == 0 or not (np.all(np.isfinite(gx)) and np.all(np.isfinite(gy))):
        raise ValueError("slopes: expected two finite arrays of the same, non-zero size")
    if nodes < 8:
        raise ValueError(f"nodes: expected at least 8 nodes per side, got {nodes}")
    flat = (gx == 0.0) & (gy == 0.0)
    spike = float(np.mean(flat))
    gx, gy = gx[~flat], gy[~flat]
    density = np.zeros((nodes, nodes))
    extent = 1.0
    r = None
    if gx.size:
        inv = 1.0 / np.sqrt(1.0 + gx * gx + gy * gy)
        mx, my = -gx * inv, -gy * inv
        reach = float(max(np.max(np.abs(mx)), np.max(np.abs(my))))
        extent = min(1.0, max(reach, 1e-6) * (nodes - 1) / (nodes - 5))
        _deposit(mx, my, extent, nodes, density)
        if smooth is None:
            occupied = max(int(np.count_nonzero(density)), 1)
            smooth = float(np.clip(0.5 * math.sqrt(SMOOTH_FACETS * occupied / gx.size), 0.5, 2.0))
        if smooth > 0.0:
            from scipy.ndimage import gaussian_filter

            density = gaussian_filter(density, smooth, mode="constant", truncate=3.0)
        step = 2.0 * extent / (nodes - 1)
        x = np.linspace(-extent, extent, nodes)
        xx, yy = np.meshgrid(x, x)
        density[np.hypot(xx, yy) > 1.0 - 1.5 * step] = 0.0
        total = density.sum()
        density = density / (total * step * step) if total > 0 else density
        if gx.size > 1:
            r = slope_roughness(gx, gy)
    if not density.any():
        spike = 1.0
    partial = TabulatedNDF(density, extent, spike, np.zeros((DIR_THETA, DIR_PHI)), 0.0, 0.0, 0.0)
    m, w = partial.nodes()
    area = np.empty(DIR_THETA * DIR_PHI)
    _projected_area(m, w, direction_grid(DIR_THETA, DIR_PHI, math.pi / 2), area)
    return TabulatedNDF(
        density,
        extent,
        spike,
        area.reshape(DIR_THETA, DIR_PHI),
        0.0 if r is None else r.alpha_major,
        0.0 if r is None else r.alpha_minor,
        0.0 if r is None else r.major_azimuth_rad,
    )


@dataclass(frozen=True, eq=False)
class TabulatedMicrofacet:
    """The compact model with a tabulated NDF (module docstring): the relief's facets, its body, its index.

    ``ms_factor`` is ``k`` on :func:`direction_grid` ``(MS_THETA, MS_PHI, pi / 2)``
    (all ones without multiple scattering); ``ior=None`` makes every facet a perfect mirror
    (F = 1, no light enters the body: the white furnace). ``surface_albedo`` the surface reflection's
    directional albedo on the same grid (single scattering, and the second bounce with
    ``k``); ``body_kernel`` the body's facet-local kernel (:func:`body_kernel`) on
    pairs of those directions. The attributes a
    :class:`render.brdf_model.MicrofacetBRDF` has are here too, for the summaries.
    """

    ndf: TabulatedNDF
    body_albedo: float
    ior: float | None
    ms_factor: np.ndarray
    surface_albedo: np.ndarray
    body_kernel: np.ndarray
    distribution: str = "tabulated"
    spike_alpha: float = SPIKE_ALPHA

    @property
    def alpha_u(self) -> float:
        return self.ndf.alpha_u

    @property
    def alpha_v(self) -> float:
        return self.ndf.alpha_v

    @property
    def azimuth_rad(self) -> float:
        return self.ndf.azimuth_rad

    @property
    def spike_weight(self) -> float:
        return self.ndf.spike_weight

    def as_dict(self) -> dict[str, Any]:
        return {
            "distribution": self.distribution,
            "alpha_u": self.alpha_u,
            "alpha_v": self.alpha_v,
            "azimuth_deg": math.degrees(self.azimuth_rad),
            "body_albedo": self.body_albedo,
            "ior": math.nan if self.ior is None else self.ior,
            "spike_weight": self.spike_weight,
            "spike_alpha": self.spike_alpha if self.spike_weight > 0 else 0.0,
            "ndf_nodes": int(self.ndf.density.shape[0]),
            "ndf_step": self.ndf.step,
            "multiple_scattering_max": float(np.max(self.ms_factor) ** 2),
        }

    def arrays(self) -> dict[str, np.ndarray]:
        """The model as arrays (for ``brdf.npz``)."""
        return {
            "model_ndf": self.ndf.density,
            "model_ndf_extent": np.float64(self.ndf.extent),
            "model_spike_weight": np.float64(self.ndf.spike_weight),
            "model_lambda_area": self.ndf.area,
            "model_ms_factor": self.ms_factor,
            "model_surface_albedo": self.surface_albedo,
            "model_body_kernel": self.body_kernel.astype(np.float32),  # halves brdf.npz; smooth
            "model_body_albedo": np.float64(self.body_albedo),
            "model_ior": np.float64(math.nan if self.ior is None else self.ior),
        }


def second_bounce(ndf: TabulatedNDF, ior: float | None) -> np.ndarray:
    """``(BOUNCE_THETA, MS_PHI)``: per travel direction of a blocked ray, the ``F G1`` of its next facet.

    See :func:`render._tabulated_kernels._second_bounce`; ``ior=None``: F = 1.
    """
    m, w = ndf.nodes(coarse=MS_NODES)
    out = np.empty(BOUNCE_THETA * MS_PHI)
    eta = -1.0 if ior is None else float(ior)
    _second_bounce(m, w, direction_grid(BOUNCE_THETA, MS_PHI, math.pi), ndf.area, math.pi / 2, eta, out)
    return out.reshape(BOUNCE_THETA, MS_PHI)


def scattering_energies(
    ndf: TabulatedNDF, ior: float | None, factor: np.ndarray | None = None, bounce: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Single-scattering albedo, its ``factor``-weighted form and the second bounce, on the MS grid.

    ``ior=None`` makes every facet a perfect mirror (F = 1), for the white furnace;
    ``factor`` is a ``(MS_THETA, MS_PHI)`` table (default ones), ``bounce`` the
    :func:`second_bounce` table (computed when not given). Returns three
    ``(MS_THETA, MS_PHI)`` arrays (see :func:`render._tabulated_kernels._energies`).
    """
    e_ss, e_2, weights = _energy_terms(ndf, ior, bounce)
    factor = np.ones((MS_THETA, MS_PHI)) if factor is None else np.asarray(factor, dtype=np.float64)
    return e_ss, (weights @ factor.ravel()).reshape(MS_THETA, MS_PHI), e_2


def _energy_terms(
    ndf: TabulatedNDF, ior: float | None, bounce: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``E_ss`` and ``E_2`` on the MS grid, and the matrix that weights any factor table into
    ``integral f_ss factor cos`` (``(MS_THETA * MS_PHI)`` squared; :func:`_energies`)."""
    m, w = ndf.nodes(coarse=MS_NODES)
    eta = -1.0 if ior is None else float(ior)
    bounce = second_bounce(ndf, ior) if bounce is None else bounce
    out = np.empty((MS_THETA * MS_PHI, 2))
    weights = np.empty((MS_THETA * MS_PHI, MS_THETA * MS_PHI))
    _energies(
        m, w, direction_grid(MS_THETA, MS_PHI, math.pi / 2), ndf.area, bounce, math.pi / 2, math.pi, eta,
        MS_THETA, MS_PHI, out, weights,
    )  # fmt: skip
    e = out.reshape(MS_THETA, MS_PHI, 2)
    return e[..., 0], e[..., 1], weights


def multiple_scattering_factor(ndf: TabulatedNDF, ior: float | None) -> tuple[np.ndarray, np.ndarray]:
    """``k`` and the surface's albedo ``E_ss + E_2`` on the MS grid.

    ``k(i) integral f_s(i, o) k(o) cos d omega_o = E_ss(i) + E_2(i)``, solved by a damped
    fixed-point iteration (``k <- sqrt(k target / integral f_s k)``) from ``k = 1``; six
    rounds take it to within 0.1 % where ``k`` is within 10 % of 1. The integral is linear
    in ``k``: one pass over the facets gives its matrix, and each round is a product with it.
    """
    e_ss, e_2, weights = _energy_terms(ndf, ior, None)
    target = e_ss + e_2
    k = np.ones_like(target)
    for _ in range(_MS_ROUNDS):
        # e_k is the albedo with k(o) alone; k(i) multiplies it.
        e_k = (weights @ k.ravel()).reshape(k.shape)
        new = np.where(e_k > 1e-12, target / np.maximum(e_k, 1e-300), 1.0)
        k = np.sqrt(k * new)
    return k, target


def body_kernel(ndf: TabulatedNDF, ior: float | None) -> np.ndarray:
    """The body's light through the rough interface, facet by facet, on pairs of MS-grid directions.

    Light enters the body through a facet ``m`` and comes back out through the same facet,
    as the tracer has it (the pigment's mean free path is far below a facet), with the
    Lambertian emission of a smooth interface about ``m``; so the body's BRDF is

        f_b(i, o) = rho / (pi n^2 (1 - rho F_dr,int)) K(i, o) G2(i, o) / (cos_i cos_o),
        K(i, o) = integral D_total(m) t(i . m) t(o . m) d omega_m,  t(c) = max(0, c) (1 - F(c)),

    symmetric in ``i`` and ``o``. On a flat surface it is the smooth interface's body term.
    Returns ``K`` as a ``(MS_THETA * MS_PHI, MS_THETA * MS_PHI)`` matrix (zero for perfect
    mirrors, ``ior=None``: nothing enters).
    """
    if ior is None:
        return np.zeros((MS_THETA * MS_PHI, MS_THETA * MS_PHI))
    m, w = ndf.nodes(coarse=MS_NODES)
    c = direction_grid(MS_THETA, MS_PHI, math.pi / 2) @ m.T
    t = np.maximum(c, 0.0) * (1.0 - fresnel_dielectric(np.clip(c, 0.0, 1.0), ior))
    return (t * (w / m[:, 2])) @ t.T


def _pair_lookup(kernel: np.ndarray, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """Bilinear in ``wi`` and in ``wo`` over the MS grid: a symmetric kernel stays symmetric."""
    n_t, n_p = MS_THETA, MS_PHI

    def corners(w: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
        theta = np.arccos(np.clip(w[..., 2], -1.0, 1.0))
        phi = np.arctan2(w[..., 1], w[..., 0]) % (2.0 * math.pi)
        ft = np.minimum(theta / (math.pi / 2) * (n_t - 1), n_t - 1.0)
        i0 = np.minimum(ft.astype(np.int64), n_t - 2)
        at = ft - i0
        fp = phi / (2.0 * math.pi) * n_p
        j0 = np.floor(fp).astype(np.int64)
        ap = fp - j0
        j0 %= n_p
        j1 = (j0 + 1) % n_p
        index = [i0 * n_p + j0, i0 * n_p + j1, (i0 + 1) * n_p + j0, (i0 + 1) * n_p + j1]
        weight = [(1 - at) * (1 - ap), (1 - at) * ap, at * (1 - ap), at * ap]
        return index, weight

    # Each side's cells from its own directions, combined by broadcasting (as in _surface).
    ii, wwi = corners(wi)
    io, wwo = corners(wo)
    out = np.zeros(np.broadcast_shapes(wi.shape, wo.shape)[:-1])
    for a in range(4):
        for b in range(4):
            out += wwi[a] * wwo[b] * kernel[ii[a], io[b]]
    return out


def _body_term(model: TabulatedMicrofacet, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """The facet-local body term (1/sr) of :func:`body_kernel`."""
    rho, n = model.body_albedo, model.ior
    if n is None or rho <= 0.0:
        return np.zeros(np.broadcast_shapes(np.shape(wi), np.shape(wo))[:-1])
    wi, wo = np.asarray(wi, dtype=np.float64), np.asarray(wo, dtype=np.float64)
    a_i = grid_lookup(model.ndf.area, math.pi / 2, wi)
    a_o = grid_lookup(model.ndf.area, math.pi / 2, wo)
    kernel = _pair_lookup(model.body_kernel, wi, wo)
    wi, wo = np.broadcast_arrays(wi, wo)
    cos_i, cos_o = wi[..., 2], wo[..., 2]
    factor = rho / (math.pi * n * n * (1.0 - rho * diffuse_fresnel_reflectance(1.0 / n)))
    with np.errstate(divide="ignore", invalid="ignore"):
        value = factor * kernel / (cos_i * cos_o + a_i * cos_o + a_o * cos_i)
    return np.where((cos_i > 0.0) & (cos_o > 0.0), value, 0.0)


def tabulated_model(
    ndf: TabulatedNDF, body_albedo: float, ior: float | None, *, multiple_scattering: bool = True
) -> TabulatedMicrofacet:
    """The compact model of a tabulated NDF, with or without its multiple-scattering factor.

    ``ior=None``: perfect mirror facets (F = 1), for the white furnace.
    """
    if multiple_scattering:
        factor, albedo = multiple_scattering_factor(ndf, ior)
    else:
        factor = np.ones((MS_THETA, MS_PHI))
        albedo, _, _ = scattering_energies(ndf, ior)
    n = None if ior is None else float(ior)
    return TabulatedMicrofacet(ndf, float(body_albedo), n, factor, albedo, body_kernel(ndf, n))


def _fresnel(model: TabulatedMicrofacet, cos: np.ndarray) -> np.ndarray:
    return np.ones_like(cos) if model.ior is None else fresnel_dielectric(cos, model.ior)


def _surface(
    model: TabulatedMicrofacet,
    wi: np.ndarray,
    wo: np.ndarray,
    *,
    spike: bool,
    wo_tables: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """The surface term (1/sr) without (or with, as a GGX lobe of ``spike_alpha``) the mirror spike.

    ``wo_tables``: :func:`surface_tables` of ``wo``, for a caller that evaluates the same
    outgoing directions for many incident ones.
    """
    ndf = model.ndf
    wi, wo = np.asarray(wi, dtype=np.float64), np.asarray(wo, dtype=np.float64)
    # The tables are looked up at each side's own directions and the values broadcast: the
    # same numbers as looking up the broadcast arrays, where an incident direction is usually
    # one against thousands of outgoing ones (model_bins: half its lookups' arccos and arctan2).
    a_i, k_i = surface_tables(model, wi)
    a_o, k_o = surface_tables(model, wo) if wo_tables is None else wo_tables
    k = k_i * k_o
    wi, wo = np.broadcast_arrays(wi, wo)
    cos_i, cos_o = wi[..., 2], wo[..., 2]
    hv = wi + wo
    hv = hv / np.maximum(np.linalg.norm(hv, axis=-1, keepdims=True), 1e-300)
    d = (1.0 - ndf.spike_weight) * ndf.value(hv)
    if spike and ndf.spike_weight > 0.0:
        a2 = model.spike_alpha**2
        q = (hv[..., 0] ** 2 + hv[..., 1] ** 2) / a2 + hv[..., 2] ** 2
        d = d + ndf.spike_weight / (math.pi * a2 * q * q)
    with np.errstate(divide="ignore", invalid="ignore"):
        # G2 / (cos_i cos_o) = 1 / (cos_i cos_o + A_i cos_o + A_o cos_i), finite at grazing.
        g2_cc = 1.0 / (cos_i * cos_o + a_i * cos_o + a_o * cos_i)
        f = _fresnel(model, np.sum(wi * hv, axis=-1)) * d * g2_cc / 4.0
    return np.where((cos_i > 0.0) & (cos_o > 0.0) & (hv[..., 2] > 0.0), f * k, 0.0)


def surface_tables(model: TabulatedMicrofacet, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The masking table ``Lambda cos`` and the multiple-scattering factor ``k`` at unit directions ``w``."""
    return grid_lookup(model.ndf.area, math.pi / 2, w), grid_lookup(model.ms_factor, math.pi / 2, w)


def evaluate(
    model: TabulatedMicrofacet, wi: np.ndarray, wo: np.ndarray, *, specular_only: bool = False
) -> np.ndarray:
    """The model's BRDF (1/sr), the spike as a GGX lobe of ``spike_alpha`` (as Mitsuba renders it)."""
    f = _surface(model, wi, wo, spike=True)
    if specular_only or model.body_albedo <= 0.0:
        return f
    return f + _body_term(model, wi, wo)


def spike_energy(model: TabulatedMicrofacet, wi: np.ndarray) -> np.ndarray:
    """Power the mirror spike reflects for incident ``wi`` (n, 3): ``w F(cos_i) G2(i, r) k(i) k(r)``."""
    wi = np.atleast_2d(wi)
    ndf = model.ndf
    r = wi * np.array([-1.0, -1.0, 1.0])
    cos = wi[:, 2]
    a = grid_lookup(ndf.area, math.pi / 2, wi)
    a_r = grid_lookup(ndf.area, math.pi / 2, r)
    g2 = cos * cos / (cos * cos + a * cos + a_r * cos)
    k = grid_lookup(model.ms_factor, math.pi / 2, wi) * grid_lookup(model.ms_factor, math.pi / 2, r)
    return ndf.spike_weight * _fresnel(model, cos) * g2 * k
