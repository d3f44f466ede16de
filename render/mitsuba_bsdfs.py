"""The printed surface's appearance as Mitsuba BSDFs: the fitted compact model and the traced table.

printapp's BSDF plugins, registered with Mitsuba on first use; :mod:`render.mitsuba_adapter`
renders with them. Mitsuba is imported lazily.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from render.mitsuba_shared import fresnel_dr, glossy_or_diffuse_sample, in_world_x_frame, lobe_or_body_sample

_registered: dict[str, Any] = {}


@dataclass(frozen=True)
class CompactSurface:
    """Representation (a): the fitted compact model (:class:`render.brdf_model.MicrofacetBRDF`).

    ``body_rgb`` is the resin's linear-RGB body albedo (the fit's grey albedo is its
    luminance). The anisotropy's azimuth is measured in the shading frame, which on a
    surface facing +z is the world's x and y.
    """

    distribution: str
    alpha_u: float
    alpha_v: float
    azimuth_rad: float
    ior: float
    body_rgb: tuple[float, float, float]
    spike_weight: float = 0.0
    spike_alpha: float = 0.002


@dataclass(frozen=True)
class TableSurface:
    """Representation (b): a traced BRDF table over a regular grid of incident directions.

    ``specular`` and ``body`` are ``(n_theta_i, n_phi_i, n_theta_o, n_phi_o)`` arrays
    (1/sr) of the surface-only and the through-the-body parts; incident polar angles run
    evenly from 0 to ``theta_i_max_rad``, azimuths evenly over [0, 2 pi); ``body_tint``
    scales the body part per channel (for a coloured resin traced in grey).
    """

    specular: np.ndarray
    body: np.ndarray
    theta_i_max_rad: float
    body_tint: tuple[float, float, float] = (1.0, 1.0, 1.0)


def surface_bsdf(surface: Any) -> Any:
    """A Mitsuba BSDF object for a representation of the printed surface (variant already set).

    ``surface`` is a :class:`CompactSurface`, a :class:`TableSurface` or a
    :class:`render.mitsuba_tabulated.TabulatedSurface` (the tabulated-NDF compact model).
    A ``dict`` is a Mitsuba plugin description, loaded as it is (for comparisons with
    Mitsuba's own BSDFs).
    """
    import mitsuba as mi

    from render.fresnel import diffuse_fresnel_reflectance
    from render.mitsuba_tabulated import TabulatedSurface, tabulated_plugin_dict

    _register_plugins()
    if isinstance(surface, dict):
        return mi.load_dict(surface)
    if isinstance(surface, TabulatedSurface):
        return mi.load_dict(tabulated_plugin_dict(surface))
    if isinstance(surface, CompactSurface):
        return mi.load_dict(
            {
                "type": "printapp_compact",
                "distribution": surface.distribution,
                "alpha_u": float(surface.alpha_u),
                "alpha_v": float(surface.alpha_v),
                "azimuth": float(surface.azimuth_rad),
                "spike_weight": float(surface.spike_weight),
                "spike_alpha": float(surface.spike_alpha),
                "ior": float(surface.ior),
                "f_dr_int": float(diffuse_fresnel_reflectance(1.0 / surface.ior)),
                "body": {"type": "rgb", "value": [float(c) for c in surface.body_rgb]},
            }
        )
    bsdf = mi.load_dict({"type": "printapp_table"})
    bsdf.set_table(surface.specular, surface.body, surface.theta_i_max_rad, surface.body_tint)
    return bsdf


MIRROR_PROBABILITY = 0.7
"""How often the coated resin draws its mirror reflection. Measured with 16 samples a half on four
examples' previews (tag_with_slot, part_relief, brushed_cylinder, tile_fbm), the variance at
0.7 was 0.77-0.92 times that at 0.5; 0.75 was even with 0.7, 0.8 worse on part_relief, 0.85
and up worse still (the body's indirect light getting too few samples). Measured again with the
unbiased ``multijitter`` sampler (docs/benchmarks.md, "Sixteenth run"): best on the demo, 3 %
more variance than 0.6 on part_relief."""


def coated_resin_bsdf(
    body_rgb: tuple[float, float, float], ior: float, mirror_probability: float = MIRROR_PROBABILITY
) -> Any:
    """A smooth resin as a Mitsuba BSDF: Mitsuba's ``plastic`` (nonlinear), its mirror drawn with
    probability ``mirror_probability`` instead of plastic's Fresnel-weighted choice (variant already set).

    ``body_rgb`` is the linear-RGB body albedo, ``ior`` the resin's refractive index.
    """
    import mitsuba as mi

    from render.fresnel import diffuse_fresnel_reflectance

    if not 0.0 < mirror_probability < 1.0:
        raise ValueError(f"mirror_probability: expected a probability in (0, 1), got {mirror_probability}")
    _register_plugins()
    return mi.load_dict(
        {
            "type": "printapp_coated",
            "ior": float(ior),
            "f_dr_int": float(diffuse_fresnel_reflectance(1.0 / ior)),
            "mirror_probability": float(mirror_probability),
            "body": {"type": "rgb", "value": [float(c) for c in body_rgb]},
        }
    )


def _register_plugins() -> None:
    """Define and register printapp's BSDF plugins for the current variant (once per variant)."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if variant in _registered:
        return

    fresnel = fresnel_dr

    def held(value: float) -> Any:
        # A design's number held in memory, not written into the traced kernel as a literal:
        # as literals, every new body colour or index compiled the preview's kernels anew.
        return dr.opaque(mi.Float, value) if dr.is_jit_v(mi.Float) else value

    class CompactResin(mi.BSDF):
        """The fitted compact model: anisotropic microfacet lobe, optional sharp spike, Lambertian body."""

        def __init__(self, props):
            super().__init__(props)
            self.ggx = props.get("distribution", "ggx") == "ggx"  # else Beckmann
            self.alpha_u = float(props.get("alpha_u", 0.1))
            self.alpha_v = float(props.get("alpha_v", 0.1))
            self.azimuth = float(props.get("azimuth", 0.0))
            self.spike_weight = float(props.get("spike_weight", 0.0))
            self.spike_alpha = float(props.get("spike_alpha", 0.002))
            self.eta = float(props.get("ior", 1.5))
            body = props.get("body", mi.ScalarColor3f(0.5, 0.5, 0.5))
            f_int = float(props.get("f_dr_int", 0.6))
            rho = [float(body[i]) for i in range(3)]
            # rho / (pi n^2 (1 - rho F_dr,int)) per channel
            self.body_factor = mi.Color3f(*[r / (math.pi * self.eta**2 * (1.0 - r * f_int)) for r in rho])
            self.body_mean = sum(rho) / 3.0
            self.m_components = [
                mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide,
                mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide,
            ]
            self.m_flags = self.m_components[0] | self.m_components[1]

        # --- one lobe -----------------------------------------------------------------
        def _rot(self, v):
            c, s = math.cos(self.azimuth), math.sin(self.azimuth)
            return mi.Vector3f(c * v.x + s * v.y, -s * v.x + c * v.y, v.z)

        def _unrot(self, v):
            c, s = math.cos(self.azimuth), math.sin(self.azimuth)
            return mi.Vector3f(c * v.x - s * v.y, s * v.x + c * v.y, v.z)

        def _d(self, m, au, av):
            x2 = (m.x * m.x) / (au * au) + (m.y * m.y) / (av * av)
            z2 = m.z * m.z
            if self.ggx:
                q = x2 + z2
                return dr.rcp(dr.pi * au * av * q * q)
            return dr.exp(-x2 / z2) / (dr.pi * au * av * z2 * z2)

        def _lambda(self, w, au, av):
            proj = dr.sqrt(au * au * w.x * w.x + av * av * w.y * w.y)
            wz = dr.maximum(w.z, 1e-7)
            if self.ggx:
                return 0.5 * (dr.sqrt(1.0 + (proj / wz) ** 2) - 1.0)
            a = wz / dr.maximum(proj, 1e-12)
            lam = 0.5 * (dr.erf(a) - 1.0) + dr.exp(-a * a) / (2.0 * a * math.sqrt(math.pi))
            return dr.select(a > 26.0, 0.0, lam)

        def _distribution(self, au, av):
            kind = mi.MicrofacetType.GGX if self.ggx else mi.MicrofacetType.Beckmann
            return mi.MicrofacetDistribution(kind, au, av, True)

        def _lobe_eval_pdf(self, wi, wo, au, av):
            """f cos(theta_o), and the pdf of sampling wo by this lobe's visible normals (rotated frame)."""
            h = dr.normalize(wi + wo)
            d = self._d(h, au, av)
            g2 = dr.rcp(1.0 + self._lambda(wi, au, av) + self._lambda(wo, au, av))
            f = fresnel(dr.dot(wi, h), self.eta) * d * g2 / (4.0 * wi.z)
            # Visible normals (Heitz 2018): pdf(m) = G1(wi) max(0, wi.m) D(m) / cos(theta_i).
            g1 = dr.rcp(1.0 + self._lambda(wi, au, av))
            pdf = (
                g1
                * dr.maximum(dr.dot(wi, h), 0.0)
                * d
                / wi.z
                / (4.0 * dr.maximum(dr.abs(dr.dot(wo, h)), 1e-12))
            )
            return f, pdf

        def _choice(self, cos_i):
            f = fresnel(cos_i, self.eta)
            spec = f
            body = (1.0 - f) * self.body_mean
            p_spec = spec / dr.maximum(spec + body, 1e-12)
            return p_spec

        def _all(self, wi_l, wo_l):
            wi, wo = self._rot(wi_l), self._rot(wo_l)
            w = self.spike_weight
            f1, p1 = self._lobe_eval_pdf(wi, wo, self.alpha_u, self.alpha_v)
            value = (1.0 - w) * f1
            pdf_spec = (1.0 - w) * p1
            if w > 0.0:
                f2, p2 = self._lobe_eval_pdf(wi, wo, self.spike_alpha, self.spike_alpha)
                value += w * f2
                pdf_spec += w * p2
            body = (1.0 - fresnel(wi.z, self.eta)) * (1.0 - fresnel(wo.z, self.eta)) * wo.z
            p_spec = self._choice(wi.z)
            pdf = p_spec * pdf_spec + (1.0 - p_spec) * mi.warp.square_to_cosine_hemisphere_pdf(wo_l)
            return value, body, pdf

        def eval(self, ctx, si, wo, active=True):
            ok = active & (mi.Frame3f.cos_theta(si.wi) > 0) & (mi.Frame3f.cos_theta(wo) > 0)
            value, body, _ = self._all(si.wi, wo)
            out = mi.Spectrum(value) + self.body_factor * body
            return dr.select(ok, out, 0.0)

        def pdf(self, ctx, si, wo, active=True):
            ok = active & (mi.Frame3f.cos_theta(si.wi) > 0) & (mi.Frame3f.cos_theta(wo) > 0)
            _, _, pdf = self._all(si.wi, wo)
            return dr.select(ok, pdf, 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            ok = active & (mi.Frame3f.cos_theta(si.wi) > 0) & (mi.Frame3f.cos_theta(wo) > 0)
            value, body, pdf = self._all(si.wi, wo)
            out = mi.Spectrum(value) + self.body_factor * body
            return dr.select(ok, out, 0.0), dr.select(ok, pdf, 0.0)

        def sample(self, ctx, si, sample1, sample2, active=True):
            wi_l = si.wi
            cos_i = mi.Frame3f.cos_theta(wi_l)
            active = active & (cos_i > 0)
            p_spec = self._choice(cos_i)
            pick_spec = sample1 < p_spec
            # Which lobe: the spike with probability spike_weight (reusing sample1's remainder).
            u_lobe = sample1 / dr.maximum(p_spec, 1e-12)
            wi = self._rot(wi_l)
            m, _ = self._distribution(self.alpha_u, self.alpha_v).sample(wi, sample2)
            if self.spike_weight > 0.0:
                m_spike, _ = self._distribution(self.spike_alpha, self.spike_alpha).sample(wi, sample2)
                m = dr.select(u_lobe < self.spike_weight, m_spike, m)
            wo_spec = self._unrot(2.0 * dr.dot(wi, m) * m - wi)
            wo_diff = mi.warp.square_to_cosine_hemisphere(sample2)
            wo = dr.select(pick_spec, wo_spec, wo_diff)
            return glossy_or_diffuse_sample(wo, pick_spec, *self._all(wi_l, wo), self.body_factor, active)

        def to_string(self):
            return f"CompactResin[alpha = ({self.alpha_u}, {self.alpha_v}), spike = {self.spike_weight}]"

    class TabulatedBRDF(mi.BSDF):
        """A traced BRDF table over a grid of incident directions, looked up bin by bin.

        The value is bilinear in the incident direction (theta_i, phi_i) between the grid's
        directions and constant over each outgoing bin (the table holds bin averages). The
        surface-only part and the body part are kept apart so that the body can be tinted
        per channel. Sampling is cosine-weighted.
        """

        def __init__(self, props):
            super().__init__(props)
            self.m_components = [mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide]
            self.m_flags = self.m_components[0]
            self.n_ti = self.n_pi = self.n_to = self.n_po = 1
            self.theta_i_max = 1.0

        def set_table(self, specular, body, theta_i_max, body_tint):
            """``specular``, ``body``: (n_theta_i, n_phi_i, n_theta_o, n_phi_o) in 1/sr."""
            self.n_ti, self.n_pi, self.n_to, self.n_po = specular.shape
            self.theta_i_max = float(theta_i_max)
            self.spec = mi.Float(np.ascontiguousarray(specular, dtype=np.float32).ravel())
            self.body = mi.Float(np.ascontiguousarray(body, dtype=np.float32).ravel())
            self.tint = mi.Color3f(*[float(t) for t in body_tint])

        def _bin(self, w):
            theta = dr.acos(dr.clip(w.z, -1.0, 1.0))
            phi = dr.atan2(w.y, w.x)
            phi = dr.select(phi < 0.0, phi + 2.0 * dr.pi, phi)
            to = dr.minimum(mi.UInt32(theta * (2.0 / dr.pi) * self.n_to), self.n_to - 1)
            po = dr.minimum(mi.UInt32(phi * (0.5 / dr.pi) * self.n_po), self.n_po - 1)
            return to * self.n_po + po

        def _lookup(self, wi, wo):
            """Bilinear over the incident grid (theta_i clamped, phi_i periodic).

            The body part is read at ``wo`` itself. The surface part is read, at each of
            the four grid directions ``wi_k``, where ``wi_k`` has the same half vector as
            ``(wi, wo)``: ``wo_k = 2 (wi_k . h) h - wi_k``, and carried over as
            ``f cos(theta_i) cos(theta_o)``, which for microfacet reflection is
            ``F D G / 4``, a function of h but for F and G. A glossy lobe moves with its
            mirror direction, so blending lobes read this way moves the lobe instead of
            smearing two copies of it.
            """
            theta_i = dr.acos(dr.clip(wi.z, -1.0, 1.0))
            phi_i = dr.atan2(wi.y, wi.x)
            phi_i = dr.select(phi_i < 0.0, phi_i + 2.0 * dr.pi, phi_i)
            h = dr.normalize(wi + wo)
            direct = self._bin(wo)
            ti = dr.clip(theta_i / self.theta_i_max * (self.n_ti - 1), 0.0, self.n_ti - 1.0)
            pi_ = phi_i * (0.5 / dr.pi) * self.n_pi
            t0 = dr.minimum(mi.UInt32(dr.floor(ti)), self.n_ti - 1)
            t1 = dr.minimum(t0 + 1, self.n_ti - 1)
            ft = ti - mi.Float(t0)
            p0 = mi.UInt32(dr.floor(pi_)) % self.n_pi
            p1 = (p0 + 1) % self.n_pi
            fp = pi_ - dr.floor(pi_)
            spec = mi.Float(0.0)
            body = mi.Float(0.0)
            per_in = self.n_to * self.n_po
            for t, wt in ((t0, 1.0 - ft), (t1, ft)):
                theta_k = mi.Float(t) * (self.theta_i_max / max(self.n_ti - 1, 1))
                for p, wp in ((p0, 1.0 - fp), (p1, fp)):
                    phi_k = mi.Float(p) * (2.0 * dr.pi / self.n_pi)
                    sin_k = dr.sin(theta_k)
                    wi_k = mi.Vector3f(sin_k * dr.cos(phi_k), sin_k * dr.sin(phi_k), dr.cos(theta_k))
                    wo_k = 2.0 * dr.dot(wi_k, h) * h - wi_k
                    moved = wo_k.z > 0.0
                    out_k = dr.select(moved, self._bin(wo_k), direct)
                    # f cos_i cos_o = F D G / 4 depends on h (and slowly on F, G): carry that.
                    scale = dr.select(moved, wi_k.z * wo_k.z / dr.maximum(wi.z * wo.z, 1e-4), 1.0)
                    base = (t * self.n_pi + p) * per_in
                    spec += wt * wp * scale * dr.gather(mi.Float, self.spec, base + out_k)
                    body += wt * wp * dr.gather(mi.Float, self.body, base + direct)
            return spec, body

        def eval(self, ctx, si, wo, active=True):
            ok = active & (mi.Frame3f.cos_theta(si.wi) > 0) & (mi.Frame3f.cos_theta(wo) > 0)
            spec, body = self._lookup(si.wi, wo)
            value = (mi.Spectrum(spec) + self.tint * body) * mi.Frame3f.cos_theta(wo)
            return dr.select(ok, value, 0.0)

        def pdf(self, ctx, si, wo, active=True):
            ok = active & (mi.Frame3f.cos_theta(si.wi) > 0) & (mi.Frame3f.cos_theta(wo) > 0)
            return dr.select(ok, mi.warp.square_to_cosine_hemisphere_pdf(wo), 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            # Named, not dispatched: a subclass (render.mitsuba_shared) has already rotated si and wo.
            return TabulatedBRDF.eval(self, ctx, si, wo, active), TabulatedBRDF.pdf(self, ctx, si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            wo = mi.warp.square_to_cosine_hemisphere(sample2)
            bs = mi.BSDFSample3f()
            bs.wo = wo
            bs.eta = 1.0
            bs.pdf = mi.warp.square_to_cosine_hemisphere_pdf(wo)
            bs.sampled_component = mi.UInt32(0)
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            ok = active & (mi.Frame3f.cos_theta(si.wi) > 0) & (bs.pdf > 0)
            spec, body = self._lookup(si.wi, wo)
            weight = (mi.Spectrum(spec) + self.tint * body) * dr.pi  # f cos / (cos / pi)
            return bs, dr.select(ok, weight, 0.0)

        def to_string(self):
            return f"TabulatedBRDF[{self.n_ti} x {self.n_pi} incident, {self.n_to} x {self.n_po} outgoing]"

    class CoatedResin(mi.BSDF):
        """Mitsuba's ``plastic`` (a smooth dielectric coat over a Lambertian body, with the body's
        internal reflections), sampled so that the coat's mirror reflection is drawn more often.

        ``plastic`` draws the mirror with probability ``F w / (F w + (1 - F)(1 - w))``, ``w`` the
        specular sampling weight: about 8 % at normal incidence on a resin. The mirror carries
        every glint of the soft box on a relief's facets, and no light sample can find it (it is
        a delta lobe), so a glint pixel's samples are 0 or 12 times its mean: on the part_relief
        example that was half of the preview's variance in 1 % of its pixels. Drawn with
        probability ``p`` = 0.7 (:data:`MIRROR_PROBABILITY`), the mirror's relative variance
        ``(1 - p) / p`` falls from 11 to 0.43; the body's sampled directions (indirect light
        only: direct light comes from light samples) fall to 30 %.
        Values and densities are plastic's (tests/test_representations.py compares them).
        """

        def __init__(self, props):
            super().__init__(props)
            self.eta = float(props.get("ior", 1.5))
            self.eta_held = held(self.eta)
            body = props.get("body", mi.ScalarColor3f(0.5, 0.5, 0.5))
            f_int = float(props.get("f_dr_int", 0.6))
            self.p_mirror = float(props.get("mirror_probability", MIRROR_PROBABILITY))
            rho = [float(body[i]) for i in range(3)]
            # rho / (pi n^2 (1 - rho F_dr,int)) per channel: plastic's nonlinear body
            factors = [r / (math.pi * self.eta**2 * (1.0 - r * f_int)) for r in rho]
            self.body_factor = mi.Color3f(*[held(f) for f in factors])
            self.m_components = [
                mi.BSDFFlags.DeltaReflection | mi.BSDFFlags.FrontSide,
                mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.FrontSide,
            ]
            self.m_flags = self.m_components[0] | self.m_components[1]

        def _p_mirror(self, ctx):
            mirror = ctx.is_enabled(mi.BSDFFlags.DeltaReflection, 0)
            body = ctx.is_enabled(mi.BSDFFlags.DiffuseReflection, 1)
            if mirror and body:
                return self.p_mirror
            return 1.0 if mirror else 0.0

        def _body(self, ctx, si, wo, active):
            cos_i, cos_o = mi.Frame3f.cos_theta(si.wi), mi.Frame3f.cos_theta(wo)
            ok = active & (cos_i > 0) & (cos_o > 0)
            t = (1.0 - fresnel(cos_i, self.eta_held)) * (1.0 - fresnel(cos_o, self.eta_held)) * cos_o
            value = dr.select(ok, self.body_factor * t, 0.0)
            p_body = 1.0 - self._p_mirror(ctx)
            pdf = dr.select(ok, p_body * mi.warp.square_to_cosine_hemisphere_pdf(wo), 0.0)
            return value, pdf

        def eval(self, ctx, si, wo, active=True):
            if not ctx.is_enabled(mi.BSDFFlags.DiffuseReflection, 1):
                return mi.Spectrum(0.0)
            return self._body(ctx, si, wo, active)[0]

        def pdf(self, ctx, si, wo, active=True):
            if not ctx.is_enabled(mi.BSDFFlags.DiffuseReflection, 1):
                return mi.Float(0.0)
            return self._body(ctx, si, wo, active)[1]

        def eval_pdf(self, ctx, si, wo, active=True):
            if not ctx.is_enabled(mi.BSDFFlags.DiffuseReflection, 1):
                return mi.Spectrum(0.0), mi.Float(0.0)
            return self._body(ctx, si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            cos_i = mi.Frame3f.cos_theta(si.wi)
            active = active & (cos_i > 0)
            p = self._p_mirror(ctx)
            pick_mirror = mi.Bool(sample1 < p)
            wo_body = mi.warp.square_to_cosine_hemisphere(sample2)
            wo = dr.select(pick_mirror, mi.reflect(si.wi), wo_body)
            body, body_pdf = self._body(ctx, si, wo_body, active)
            bs = lobe_or_body_sample(
                wo, pick_mirror, mi.BSDFFlags.DeltaReflection, dr.select(pick_mirror, p, body_pdf)
            )
            mirror_weight = mi.Spectrum(fresnel(cos_i, self.eta_held) / max(p, 1e-12))
            weight = dr.select(pick_mirror, mirror_weight, body / dr.maximum(body_pdf, 1e-12))
            return bs, dr.select(active & (bs.pdf > 0), weight, 0.0)

        def to_string(self):
            return f"CoatedResin[ior = {self.eta}, mirror drawn with p = {self.p_mirror}]"

    compact, table = in_world_x_frame(CompactResin), in_world_x_frame(TabulatedBRDF)
    mi.register_bsdf("printapp_compact", lambda props: compact(props))
    mi.register_bsdf("printapp_table", lambda props: table(props))
    mi.register_bsdf("printapp_coated", lambda props: CoatedResin(props))
    _registered[variant] = table
