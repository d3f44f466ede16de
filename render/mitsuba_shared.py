"""What printapp's Mitsuba BSDF plugins share: Fresnel in Dr.Jit, and a shading frame that does not
depend on how the surface is triangulated.

Mitsuba builds a triangle's shading frame from its first edge when the mesh carries no
texture coordinates, so an anisotropic (or azimuth-dependent, tabulated) BRDF turns from
one triangle to the next: the two triangles of a flat tile top rendered with its traced
table showed as two differently lit halves, split along the diagonal. printapp's BRDFs are
measured in the tile's frame (azimuth 0 along +x), so each plugin evaluates and samples
in the frame whose tangent is the world's +x projected into the tangent plane (+y where
the normal is within 26 degrees of x, on faces whose azimuth the tables do not describe).
"""

from __future__ import annotations

from typing import Any


def fresnel_dr(cos_i: Any, eta: Any) -> Any:
    """Unpolarised Fresnel reflectance of a dielectric interface (relative index ``eta``) in Dr.Jit,
    the same formula as :func:`render.fresnel.fresnel_dielectric` (1 beyond the critical angle)."""
    import drjit as dr

    cos_i = dr.clip(dr.abs(cos_i), 0.0, 1.0)
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    cos_t = dr.safe_sqrt(1.0 - sin2_t)
    r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return dr.select(sin2_t >= 1.0, 1.0, 0.5 * (r_perp * r_perp + r_par * r_par))


def power_heuristic(a: Any, b: Any) -> Any:
    """The power heuristic's weight (Veach 1997, eq. 9.13, beta = 2) of a sample drawn with density
    ``a`` against another strategy of density ``b``, in Dr.Jit."""
    import drjit as dr

    a2, b2 = a * a, b * b
    return dr.select(a2 + b2 > 0, a2 / (a2 + b2), 0.0)


def lobe_or_body_sample(wo: Any, pick_lobe: Any, lobe_flag: Any, pdf: Any) -> Any:
    """A ``BSDFSample3f`` for direction ``wo`` drawn from a BSDF's first component (a lobe of type
    ``lobe_flag``) where ``pick_lobe``, else from its second, the diffuse body; density ``pdf``."""
    import drjit as dr
    import mitsuba as mi

    bs = mi.BSDFSample3f()
    bs.wo = wo
    bs.eta = 1.0
    bs.sampled_component = dr.select(pick_lobe, mi.UInt32(0), mi.UInt32(1))
    bs.sampled_type = dr.select(pick_lobe, mi.UInt32(+lobe_flag), mi.UInt32(+mi.BSDFFlags.DiffuseReflection))
    bs.pdf = pdf
    return bs


def glossy_or_diffuse_sample(
    wo: Any, pick_glossy: Any, glossy: Any, body: Any, pdf: Any, body_factor: Any, active: Any
) -> tuple[Any, Any]:
    """The ``BSDFSample3f`` and weight of a direction ``wo`` drawn from a glossy lobe or the
    cosine-weighted body (``pick_glossy`` says which), whose value is ``glossy + body_factor * body``
    (already times the cosine) and whose mixture density is ``pdf``."""
    import drjit as dr
    import mitsuba as mi

    bs = lobe_or_body_sample(wo, pick_glossy, mi.BSDFFlags.GlossyReflection, pdf)
    ok = active & (mi.Frame3f.cos_theta(wo) > 0) & (pdf > 0)
    weight = (mi.Spectrum(glossy) + body_factor * body) / dr.maximum(pdf, 1e-12)
    return bs, dr.select(ok, weight, 0.0)


def in_world_x_frame(base: Any) -> Any:
    """A subclass of the Mitsuba BSDF class ``base`` that evaluates and samples it in the world-x frame.

    ``base`` works on directions in its own local frame (``si.wi``, ``wo``); the subclass
    rotates them about the normal from Mitsuba's shading frame into the world-x frame before
    calling it, and the sampled direction back. Values and densities do not change under a
    rotation, so nothing else does. ``base``'s methods must not call each other through
    ``self`` (that would rotate twice).
    """
    import drjit as dr
    import mitsuba as mi

    def rotation(si: Any) -> tuple[Any, Any]:
        n = si.sh_frame.n
        ref = dr.select(dr.abs(n.x) < 0.9, mi.Vector3f(1.0, 0.0, 0.0), mi.Vector3f(0.0, 1.0, 0.0))
        local = si.sh_frame.to_local(ref)
        norm = dr.safe_sqrt(local.x * local.x + local.y * local.y)
        ok = norm > 1e-6
        return dr.select(ok, local.x / norm, 1.0), dr.select(ok, local.y / norm, 0.0)

    def to_fixed(v: Any, c: Any, s: Any) -> Any:
        return mi.Vector3f(c * v.x + s * v.y, c * v.y - s * v.x, v.z)

    def from_fixed(v: Any, c: Any, s: Any) -> Any:
        return mi.Vector3f(c * v.x - s * v.y, s * v.x + c * v.y, v.z)

    def rotated(si: Any) -> tuple[Any, Any, Any]:
        c, s = rotation(si)
        si_fixed = mi.SurfaceInteraction3f(si)
        si_fixed.wi = to_fixed(si.wi, c, s)
        return si_fixed, c, s

    class WorldXFrame(base):
        def eval(self, ctx, si, wo, active=True):
            si_fixed, c, s = rotated(si)
            return super().eval(ctx, si_fixed, to_fixed(wo, c, s), active)

        def pdf(self, ctx, si, wo, active=True):
            si_fixed, c, s = rotated(si)
            return super().pdf(ctx, si_fixed, to_fixed(wo, c, s), active)

        def eval_pdf(self, ctx, si, wo, active=True):
            si_fixed, c, s = rotated(si)
            return super().eval_pdf(ctx, si_fixed, to_fixed(wo, c, s), active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            si_fixed, c, s = rotated(si)
            bs, weight = super().sample(ctx, si_fixed, sample1, sample2, active)
            bs.wo = from_fixed(bs.wo, c, s)
            return bs, weight

    WorldXFrame.__name__ = base.__name__
    return WorldXFrame
