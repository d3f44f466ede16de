"""Mitsuba's ``path`` with every lamp sampled at the camera's vertex: the estimator of a preview
whose relief wears a BRDF representation (the compact model, the traced table).

``path`` draws one emitter for next-event estimation at every vertex, by its sampling weight;
under printapp's studio light (a large soft box, a small bright spot and a dim uniform sky,
:class:`render.mitsuba_adapter.StudioLight`) a point lit by both lamps then sees one or the
other on each sample, and a glossy lobe that catches the spot's reflection gets it on a few
samples only. Here, at the vertex the camera sees, each lamp gets a light sample and a shadow
ray, the sky none (the BSDF's own samples find a uniform sky in proportion to what it
brings, weight 1), and the BSDF's sample is weighed against each lamp's own density (the power
heuristic); past that vertex the estimator is ``path``'s. The expected image is ``path``'s
(``tests/test_lamps_path.py``). On ``bench scale``'s 20 mm tile as its compact model, a
sample's noise falls from 0.185 to 0.085 for a pass 1.3 times dearer (docs/benchmarks.md,
eighteenth run). The coated resin's geometry has its own estimator, :mod:`render.coated_path`,
which also splits its mirror.
"""

from __future__ import annotations

from typing import Any

from render.mitsuba_shared import power_heuristic as _power


class LampsPath:
    """``path`` (``max_depth`` segments), every lamp sampled at the camera's vertex (module doc).

    It has the ``sample`` signature of a Mitsuba integrator, as
    :class:`render.progressive.SampleRenderer` calls it. The scene's emitters other than its
    environment must be its lamps (not the relief: a glowing relief keeps ``path``).
    """

    def __init__(self, max_depth: int = 8) -> None:
        if max_depth < 2:
            raise ValueError(f"max_depth: expected at least 2, got {max_depth}")
        self.max_depth = int(max_depth)
        self.rr_depth = 5

    def sample(self, scene: Any, sampler: Any, ray: Any, medium: Any, active: Any) -> tuple[Any, Any, list]:
        """One sample per lane: (radiance, valid, no AOVs), as ``mi.SamplingIntegrator.sample``."""
        import mitsuba as mi

        global _TRACE
        if _TRACE is None:
            import drjit as dr

            _TRACE = dr.syntax(_trace)  # (reads the function's source: once)
        return _TRACE(self, scene, sampler, mi.Ray3f(ray), active), mi.Bool(active), []


def light_found(scene: Any, si: Any, prev: Any, prev_pdf: Any, prev_delta: Any, first: Any, go: Any) -> tuple:
    """What a hit emits, and its multiple-importance weight against the light samples taken at the
    last vertex ``prev``: at the camera's (``first``) every lamp was sampled once and the sky
    never; past it, ``path``'s one emitter by its sampling weight. After a delta lobe, weight 1."""
    import drjit as dr
    import mitsuba as mi

    emitter = si.emitter(scene)
    emitted = emitter.eval(si, go)
    found = mi.DirectionSample3f(scene, si, prev)
    em_pdf = dr.select(
        first,
        dr.select(si.is_valid(), emitter.pdf_direction(prev, found, go & first & ~prev_delta), 0.0),
        scene.pdf_emitter_direction(prev, found, go & ~first & ~prev_delta),
    )
    return emitted, dr.select(prev_delta, 1.0, _power(prev_pdf, em_pdf))


def russian_roulette(sampler: Any, beta: Any, go: Any, depth: Any, rr_depth: int) -> tuple:
    """``path``'s Russian roulette past ``rr_depth``: the surviving lanes' weights and which go on."""
    import drjit as dr

    q = dr.minimum(dr.max(beta), 0.95)
    roulette = go & (depth >= rr_depth)
    survive = sampler.next_1d(roulette) < q
    beta = dr.select(roulette, dr.select(survive, beta / dr.maximum(q, 1e-12), 0.0), beta)
    return beta, go & (~roulette | survive)


_TRACE: Any = None


def _camera_vertex(scene: Any, sampler: Any, ray: Any, active: Any) -> tuple:
    """What the camera's vertex adds (what it sees, each lamp's light), and where the path goes on:
    the ray, its weight, the vertex, the BSDF's density of the ray, whether it was a delta lobe,
    which lanes go on."""
    import drjit as dr
    import mitsuba as mi

    ctx = mi.BSDFContext()
    si = scene.ray_intersect(ray, active)
    result = dr.select(active, si.emitter(scene).eval(si, active), 0.0)
    bsdf = si.bsdf(ray)
    on = active & si.is_valid()
    for lamp in (e for e in scene.emitters() if not e.is_environment()):
        ds, lamp_weight = lamp.sample_direction(si, sampler.next_2d(on), on)
        seen = on & (ds.pdf > 0) & (dr.max(lamp_weight) > 0)
        seen &= ~scene.ray_test(si.spawn_ray_to(ds.p), seen)
        f_lamp, pdf_lamp = bsdf.eval_pdf(ctx, si, si.to_local(ds.d), seen)
        result += dr.select(seen, lamp_weight * f_lamp * _power(ds.pdf, pdf_lamp), 0.0)
    bs, bsdf_weight = bsdf.sample(ctx, si, sampler.next_1d(on), sampler.next_2d(on), on)
    beta = dr.select(on, bsdf_weight, 0.0)
    delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
    ray = si.spawn_ray(si.to_world(bs.wo))
    return result, ray, beta, mi.Interaction3f(si), bs.pdf, delta, on & (dr.max(beta) > 0)


def _trace(integrator: LampsPath, scene: Any, sampler: Any, ray: Any, active: Any) -> Any:
    """The camera's vertex, then ``path``'s loop (next-event estimation of one emitter by its
    weight, the power heuristic, Russian roulette past ``rr_depth``)."""
    import drjit as dr
    import mitsuba as mi

    ctx = mi.BSDFContext()
    result, ray, beta, prev, prev_pdf, prev_delta, go = _camera_vertex(scene, sampler, ray, active)
    depth = mi.UInt32(1)  # vertices scattered so far
    while go:
        si = scene.ray_intersect(ray, go)
        emitted, weight_found = light_found(scene, si, prev, prev_pdf, prev_delta, depth == 1, go)
        result += dr.select(go, beta * emitted * weight_found, 0.0)
        on = go & si.is_valid() & (depth + 2 <= integrator.max_depth)
        bsdf = si.bsdf(ray)
        ds, em_weight = scene.sample_emitter_direction(si, sampler.next_2d(on), True, on)
        f_nee, pdf_nee = bsdf.eval_pdf(ctx, si, si.to_local(ds.d), on)
        nee = em_weight * f_nee * dr.select(ds.delta, 1.0, _power(ds.pdf, pdf_nee))
        result += dr.select(on, beta * nee, 0.0)
        bs, bsdf_weight = bsdf.sample(ctx, si, sampler.next_1d(on), sampler.next_2d(on), on)
        beta *= dr.select(on, bsdf_weight, 0.0)
        ray = si.spawn_ray(si.to_world(bs.wo))
        prev, prev_pdf = mi.Interaction3f(si), bs.pdf
        prev_delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
        depth += 1
        beta, go = russian_roulette(sampler, beta, on & (dr.max(beta) > 0), depth, integrator.rr_depth)
    return result
