"""The tabulated-NDF compact model (:mod:`render.tabulated_ndf`) as a Mitsuba BSDF plugin.

``printapp_tabulated`` evaluates the model as :func:`render.tabulated_ndf.evaluate` does
(the NDF bilinear over its nodes, the masking, multiple-scattering and body tables
bilinear over their directions; the mirror spike as a GGX lobe of ``spike_alpha``) and
samples it: with the probability of the surface reflection (its albedo table against the
body's), a facet normal from the table's ``D cos(theta_m)`` (Mitsuba's
``MarginalContinuous2D0`` over the same nodes, so sampled and evaluated densities are one
function) or, with the spike's share, a visible normal of the spike's GGX lobe; else a
cosine-weighted direction for the body. The pdf is that mixture's.

The tables are too large for a plugin's properties, so they are registered in this
module under a key derived from their bytes, and the plugin's ``model`` property names
the key: ``{"type": "printapp_tabulated", "model": key, "body": rgb}``. Mitsuba is
imported lazily.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from render.mitsuba_shared import fresnel_dr, glossy_or_diffuse_sample, in_world_x_frame

_models: dict[str, TabulatedSurface] = {}
_registered: set[str] = set()


@dataclass(frozen=True, eq=False)
class TabulatedSurface:
    """The compact model's tables for rendering (see :class:`render.tabulated_ndf.TabulatedMicrofacet`).

    ``body_rgb`` is the resin's linear-RGB body albedo; the direction tables are on the
    grids of :mod:`render.tabulated_ndf` (``area`` on ``DIR_THETA x DIR_PHI``, the others on
    ``MS_THETA x MS_PHI``, polar angles evenly from 0 to 90 degrees, azimuths over 360).
    """

    density: np.ndarray
    extent: float
    spike_weight: float
    spike_alpha: float
    area: np.ndarray
    ms_factor: np.ndarray
    surface_albedo: np.ndarray
    body_kernel: np.ndarray
    ior: float
    body_rgb: tuple[float, float, float]

    def key(self) -> str:
        """A name for the tables, from their bytes: the same model registers once."""
        digest = hashlib.sha256()
        for a in (self.density, self.area, self.ms_factor, self.surface_albedo, self.body_kernel):
            digest.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
        digest.update(np.array([self.extent, self.spike_weight, self.spike_alpha, self.ior]).tobytes())
        return digest.hexdigest()[:24]


def register_model(surface: TabulatedSurface) -> str:
    """Keep the surface's tables for the plugin; returns the key its ``model`` property takes."""
    key = surface.key()
    _models[key] = surface
    return key


def tabulated_plugin_dict(surface: TabulatedSurface) -> dict[str, Any]:
    """The plugin description of a surface (registers its tables and the plugin)."""
    register_plugin()
    return {
        "type": "printapp_tabulated",
        "model": register_model(surface),
        "body": {"type": "rgb", "value": [float(c) for c in surface.body_rgb]},
    }


def register_plugin() -> None:
    """Define and register ``printapp_tabulated`` for the current Mitsuba variant (once per variant)."""
    import drjit as dr
    import mitsuba as mi

    from render.fresnel import diffuse_fresnel_reflectance

    variant = mi.variant()
    if variant in _registered:
        return

    fresnel = fresnel_dr

    def corners(w, n_t, n_p):
        """The four grid nodes round ``w`` and their bilinear weights (theta clamped, phi periodic)."""
        theta = dr.acos(dr.clip(w.z, -1.0, 1.0))
        phi = dr.atan2(w.y, w.x)
        phi = dr.select(phi < 0.0, phi + 2.0 * dr.pi, phi)
        ft = dr.minimum(theta * (2.0 / dr.pi) * (n_t - 1), n_t - 1.0)
        i0 = dr.minimum(mi.UInt32(ft), n_t - 2)
        at = ft - mi.Float(i0)
        fp = phi * (0.5 / dr.pi) * n_p
        j0f = dr.floor(fp)
        ap = fp - j0f
        j0 = mi.UInt32(j0f) % n_p
        j1 = (j0 + 1) % n_p
        index = (i0 * n_p + j0, i0 * n_p + j1, (i0 + 1) * n_p + j0, (i0 + 1) * n_p + j1)
        weight = ((1.0 - at) * (1.0 - ap), (1.0 - at) * ap, at * (1.0 - ap), at * ap)
        return index, weight

    class TabulatedResin(mi.BSDF):
        """The tabulated-NDF model: the relief's own facets, a mirror spike, the facet-local body."""

        def __init__(self, props):
            super().__init__(props)
            s = _models[str(props.get("model"))]
            self.eta = float(s.ior)
            self.extent = float(s.extent)
            self.spike_weight = float(s.spike_weight)
            self.spike = mi.MicrofacetDistribution(mi.MicrofacetType.GGX, s.spike_alpha, s.spike_alpha, True)
            density = np.ascontiguousarray(s.density, dtype=np.float32)
            self.has_table = bool(density.sum() > 0.0) and self.spike_weight < 1.0
            if not self.has_table:
                density = np.ones_like(density)  # never sampled, never evaluated (weight 0)
            self.ndf = mi.MarginalContinuous2D0(density, normalize=True)
            self.area_shape = s.area.shape
            self.ms_shape = s.ms_factor.shape
            self.area = mi.Float(np.ascontiguousarray(s.area, dtype=np.float32).ravel())
            self.ms = mi.Float(np.ascontiguousarray(s.ms_factor, dtype=np.float32).ravel())
            self.albedo = mi.Float(np.ascontiguousarray(s.surface_albedo, dtype=np.float32).ravel())
            self.kernel = mi.Float(np.ascontiguousarray(s.body_kernel, dtype=np.float32).ravel())
            self.n_ms = int(np.prod(self.ms_shape))
            body = props.get("body", mi.ScalarColor3f(0.5, 0.5, 0.5))
            rho = [float(body[i]) for i in range(3)]
            f_int = diffuse_fresnel_reflectance(1.0 / self.eta)
            self.body_factor = mi.Color3f(*[r / (math.pi * self.eta**2 * (1.0 - r * f_int)) for r in rho])
            self.body_mean = sum(rho) / 3.0
            self.m_components = [
                mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide,
                mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide,
            ]
            self.m_flags = self.m_components[0] | self.m_components[1]

        def _grid(self, table, shape, w):
            index, weight = corners(w, shape[0], shape[1])
            out = mi.Float(0.0)
            for i, c in zip(index, weight, strict=True):
                out += c * dr.gather(mi.Float, table, i)
            return out

        def _kernel(self, wi, wo):
            ii, ci = corners(wi, self.ms_shape[0], self.ms_shape[1])
            io, co = corners(wo, self.ms_shape[0], self.ms_shape[1])
            out = mi.Float(0.0)
            for a in range(4):
                for b in range(4):
                    out += ci[a] * co[b] * dr.gather(mi.Float, self.kernel, ii[a] * self.n_ms + io[b])
            return out

        def _table_density(self, m):
            """D of the non-flat facets, normalised (``integral D cos = 1``); zero off the table."""
            if not self.has_table:
                return mi.Float(0.0)
            scale = 0.5 / self.extent
            pos = mi.Point2f(m.x * scale + 0.5, m.y * scale + 0.5)
            inside = (pos.x >= 0.0) & (pos.x <= 1.0) & (pos.y >= 0.0) & (pos.y <= 1.0) & (m.z > 0.0)
            value = self.ndf.eval(pos, active=inside) * (scale * scale)
            return dr.select(inside, value, 0.0)

        def _p_spec(self, wi):
            e = dr.clip(self._grid(self.albedo, self.ms_shape, wi), 0.0, 1.0)
            body = (1.0 - e) * self.body_mean
            return dr.select(e + body > 0.0, e / dr.maximum(e + body, 1e-12), 1.0)

        def _all(self, wi, wo):
            """f cos(theta_o) (surface, body) and the pdf of sampling wo."""
            h = dr.normalize(wi + wo)
            w = self.spike_weight
            d_table = self._table_density(h)
            d_spike = self.spike.eval(h)
            a_i = self._grid(self.area, self.area_shape, wi)
            a_o = self._grid(self.area, self.area_shape, wo)
            g2cc = dr.rcp(dr.maximum(wi.z * wo.z + a_i * wo.z + a_o * wi.z, 1e-12))
            k = self._grid(self.ms, self.ms_shape, wi) * self._grid(self.ms, self.ms_shape, wo)
            spec = fresnel(dr.dot(wi, h), self.eta) * ((1.0 - w) * d_table + w * d_spike) * g2cc * 0.25 * k
            body = self._kernel(wi, wo) * g2cc
            jac = dr.rcp(4.0 * dr.maximum(dr.abs(dr.dot(wo, h)), 1e-12))
            pdf_table = d_table * h.z * jac
            pdf_spike = self.spike.pdf(wi, h) * jac
            p_spec = self._p_spec(wi)
            pdf_spec = (1.0 - w) * pdf_table + w * pdf_spike
            pdf = p_spec * pdf_spec + (1.0 - p_spec) * mi.warp.square_to_cosine_hemisphere_pdf(wo)
            return spec * wo.z, body * wo.z, pdf

        def _ok(self, si, wo, active):
            return active & (mi.Frame3f.cos_theta(si.wi) > 0) & (mi.Frame3f.cos_theta(wo) > 0)

        def eval(self, ctx, si, wo, active=True):
            spec, body, _ = self._all(si.wi, wo)
            return dr.select(self._ok(si, wo, active), mi.Spectrum(spec) + self.body_factor * body, 0.0)

        def pdf(self, ctx, si, wo, active=True):
            _, _, pdf = self._all(si.wi, wo)
            return dr.select(self._ok(si, wo, active), pdf, 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            spec, body, pdf = self._all(si.wi, wo)
            ok = self._ok(si, wo, active)
            return dr.select(ok, mi.Spectrum(spec) + self.body_factor * body, 0.0), dr.select(ok, pdf, 0.0)

        def sample(self, ctx, si, sample1, sample2, active=True):
            wi = si.wi
            active = active & (mi.Frame3f.cos_theta(wi) > 0)
            p_spec = self._p_spec(wi)
            pick_spec = sample1 < p_spec
            pick_spike = sample1 / dr.maximum(p_spec, 1e-12) < self.spike_weight
            m_spike, _ = self.spike.sample(wi, sample2)
            if self.has_table:
                pos, _ = self.ndf.sample(sample2)
                mx = (2.0 * pos.x - 1.0) * self.extent
                my = (2.0 * pos.y - 1.0) * self.extent
                m_table = mi.Vector3f(mx, my, dr.safe_sqrt(1.0 - mx * mx - my * my))
                m = dr.select(pick_spike, m_spike, m_table)
            else:
                m = m_spike
            wo_spec = 2.0 * dr.dot(wi, m) * m - wi
            wo = dr.select(pick_spec, wo_spec, mi.warp.square_to_cosine_hemisphere(sample2))
            return glossy_or_diffuse_sample(wo, pick_spec, *self._all(wi, wo), self.body_factor, active)

        def to_string(self):
            return f"TabulatedResin[spike = {self.spike_weight}, extent = {self.extent}]"

    resin = in_world_x_frame(TabulatedResin)
    mi.register_bsdf("printapp_tabulated", lambda props: resin(props))
    _registered.add(variant)
