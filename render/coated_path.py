"""The camera's paths on a coated resin, less the lamps' caustics: the path estimator of a preview.

A coated relief's preview (:func:`render.mitsuba_adapter.resin_scene_dict`: a diffuse
pigmented body under a smooth dielectric coat, a soft box, a small spot lamp and a dim
uniform environment) is split by path (:mod:`render.caustics`): the lamps' ``E D S L``
caustics are light-traced, and everything else is estimated here from the camera. The
estimator is Mitsuba's ``path`` (next-event estimation, the power heuristic, Russian roulette)
with the camera's vertex done apart, where most of a preview's variance is, in three ways:

* **The coat's mirror, split.** ``path`` draws the coat's mirror or its body at the vertex
  (the mirror with probability 0.7, :data:`render.mitsuba_bsdfs.MIRROR_PROBABILITY`), so a
  pixel that mirrors a lamp gets its glint on some samples and not others. Here the mirror's
  direct light (what the reflected ray meets: a lamp's face, the environment) is added on
  every sample, with its Fresnel weight: on the samples that go on by the body it is traced
  with a ray of its own, on those that go on by the mirror the next vertex finds it (a ray
  that is traced anyway). The path goes on by the mirror only with probability
  :data:`FIRST_MIRROR_PROBABILITY`, since all that is then left on that branch is the
  relief's reflections of itself. A vertex that the camera sees through the mirror alone
  (the relief reflected in itself, as often as the path keeps to the mirror) is split the same
  way: the glints seen in a neighbouring facet's reflection, on ``brushed_part`` 29 % of the
  variance left after the camera's own vertex was split.
* **Every lamp sampled.** ``path`` draws one emitter for next-event estimation, by its
  sampling weight; a facet lit by both lamps then sees one or the other on each sample. Here
  each lamp gets a light sample (and a shadow ray) at the camera's vertex, and the uniform
  environment none: the body's cosine-weighted directions sample it in proportion to what it
  brings, so it is found by them alone (weight 1).
* **Multiple importance sampling kept exact.** The lamps' light samples and the body's
  directions are weighed by the power heuristic with the densities actually used there (the
  body drawn with probability ``1 - FIRST_MIRROR_PROBABILITY``, each lamp with probability
  1); past the camera's vertex the weights are ``path``'s.
* **No shadow ray that cannot matter.** A light sample below the surface in its shading frame
  (a lamp behind a wall, the lower half of the sky's directions) adds nothing to a coat that
  only reflects, so its shadow ray is not traced (:func:`light_sample`, and at the camera's
  vertex the same test): the same image, byte for byte, for a pass about a sixth cheaper on
  ``brushed_part``.

The expected image is ``path``'s (less the caustics, where they are light-traced), whatever
the probabilities: ``tests/test_caustics.py`` holds it to Mitsuba's own ``path`` on a grooved
tile. The samples a pixel that the CAD examples' previews take for 2 % noise fall by half
(``brushed_part`` 529 to 243, ``part_relief`` 378 to 173), though a sample costs about a
fifth more; on a flat glossy tile a sample costs 1.4 times ``path``'s and is 4 times less
noisy (docs/benchmarks.md, eighteenth run).
"""

from __future__ import annotations

from typing import Any

from render.mitsuba_shared import power_heuristic as _power

FIRST_MIRROR_PROBABILITY = 0.3
"""How often a path goes on by the coat's mirror at the camera's vertex (module doc)."""


def _fresnel(cos_i: Any, eta: float) -> Any:
    from render.mitsuba_shared import fresnel_dr

    return fresnel_dr(cos_i, eta)


def _light_found(
    scene: Any, si: Any, prev: Any, prev_pdf: Any, prev_delta: Any, first: Any, go: Any
) -> tuple:
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


def _in_front(si: Any, ds: Any) -> Any:
    """Whether a light sample's direction is above the surface in its shading frame: the coat
    reflects only, so below it the sample adds nothing and needs no shadow ray."""
    import mitsuba as mi

    return mi.Frame3f.cos_theta(si.to_local(ds.d)) > 0


def light_sample(scene: Any, si: Any, sample: Any, active: Any) -> tuple:
    """Mitsuba's ``scene.sample_emitter_direction`` with its visibility test, the shadow ray traced
    only where the sample can add light to the coated resin.

    The coat reflects only, so a sample below the surface in its shading frame (a lamp behind a
    wall, half the sky's uniform directions) adds nothing whether it is occluded or not; such a
    sample is given the value Mitsuba gives an occluded one (weight and density 0) without its
    ray. On ``brushed_part``'s preview a pass is about a sixth cheaper, the same image byte for
    byte (docs/benchmarks.md, twenty-third run).

    Parameters
    ----------
    scene : mitsuba.Scene
    si : mitsuba.SurfaceInteraction3f
        The vertex on the coated resin (its shading frame decides "below").
    sample : mitsuba.Point2f
        The light sample's two uniform numbers.
    active : mitsuba.Bool

    Returns
    -------
    ``(ds, weight)`` as ``sample_emitter_direction(si, sample, True, active)`` returns them
    wherever the direction is above the surface (tests/test_caustics.py compares them).
    """
    ds, weight = scene.sample_emitter_direction(si, sample, False, active)
    test = active & (ds.pdf != 0)
    blocked = test & ~_in_front(si, ds)
    blocked |= scene.ray_test(si.spawn_ray_to(ds.p), test & ~blocked)
    weight[blocked] = 0.0
    ds.pdf[blocked] = 0.0
    return ds, weight


def _russian_roulette(sampler: Any, beta: Any, go: Any, depth: Any, rr_depth: int) -> tuple:
    """``path``'s Russian roulette past ``rr_depth``: the surviving lanes' weights and which go on."""
    import drjit as dr

    q = dr.minimum(dr.max(beta), 0.95)
    roulette = go & (depth >= rr_depth)
    survive = sampler.next_1d(roulette) < q
    beta = dr.select(roulette, dr.select(survive, beta / dr.maximum(q, 1e-12), 0.0), beta)
    return beta, go & (~roulette | survive)


class CoatedPath:
    """Mitsuba's ``path`` (``max_depth`` segments) on the coated resin, its camera vertex done apart
    (module doc).

    It has the ``sample`` signature of a Mitsuba integrator, as
    :class:`render.progressive.SampleRenderer` calls it. ``coat`` is the scene's coated resin
    (:func:`render.mitsuba_bsdfs.coated_resin_bsdf`, loaded); the lamps must be black-faced
    shapes; every other surface is ignored past its emission. ``caustics`` says what becomes
    of the lamps' ``E D S L`` caustics: ``"light"`` leaves them out (for
    :func:`render.caustics.caustic_image` to light-trace), ``"camera"`` keeps them (the whole
    image), ``"only"`` keeps nothing else (the camera's own estimate of them, what the light
    tracer is checked against).
    """

    def __init__(
        self,
        coat: Any,
        max_depth: int = 8,
        *,
        caustics: str = "light",
        first_mirror_probability: float = FIRST_MIRROR_PROBABILITY,
    ) -> None:
        if max_depth < 3:
            raise ValueError(f"max_depth: expected at least 3, got {max_depth}")
        if caustics not in ("light", "camera", "only"):
            raise ValueError(f"caustics: expected 'light', 'camera' or 'only', got {caustics!r}")
        if not 0.0 < first_mirror_probability < 1.0:
            raise ValueError(f"first_mirror_probability: expected in (0, 1), got {first_mirror_probability}")
        self.caustics = caustics
        self.coat = coat
        self.p_mirror = float(coat.p_mirror)
        self.p_first = float(first_mirror_probability)
        self.eta = coat.eta_held  # (held in memory: see render.mitsuba_bsdfs)
        self.max_depth = int(max_depth)
        self.rr_depth = 5

    def sample(self, scene: Any, sampler: Any, ray: Any, medium: Any, active: Any) -> tuple[Any, Any, list]:
        """One sample per lane: (radiance, valid, no AOVs), as ``mi.SamplingIntegrator.sample``."""
        import mitsuba as mi

        global _TRACE
        if _TRACE is None:
            import drjit as dr

            # dr.syntax turns the ``while`` into Dr.Jit's symbolic loop (one kernel, lanes leave
            # as their paths end); it reads the function's source, so it is done once.
            _TRACE = dr.syntax(_trace)
        return _TRACE(self, scene, sampler, mi.Ray3f(ray), active), mi.Bool(active), []


def _plain_relief(scene_dict: dict[str, Any]) -> Any:
    """The relief (a loaded shape) of a preview scene's description where it is a surface alone:
    None for a medium, a glowing body, or a relief not loaded yet."""
    relief = scene_dict.get("relief")
    if isinstance(relief, dict) and relief.get("type") == "instance":
        relief = scene_dict.get("relief_group", {}).get("relief")
    if relief is None or isinstance(relief, dict) or not hasattr(relief, "bsdf"):
        return None
    if relief.interior_medium() is not None or relief.emitter() is not None:
        return None
    return relief


def coat_of(scene_dict: dict[str, Any]) -> Any:
    """The relief's coated resin (a loaded BSDF) in a preview scene's description, or None when
    the relief wears anything else (a BRDF representation, a medium, a glowing body)."""
    relief = _plain_relief(scene_dict)
    bsdf = None if relief is None else relief.bsdf()
    return bsdf if bsdf is not None and "CoatedResin" in str(bsdf) else None


def camera_estimator(renderer: Any) -> CoatedPath | None:
    """The whole image's estimator (caustics kept) for a :class:`render.progressive.SampleRenderer`
    of a preview scene whose relief is the coated resin; None where the scene's own integrator
    must serve (Mitsuba's scalar variant, a BRDF representation, a medium, a glowing body)."""
    if renderer.scalar:
        return None
    coat = coat_of(renderer.scene_dict)
    spec = renderer.scene_dict.get("integrator", {})
    if coat is None or spec.get("type") != "path":
        return None
    return CoatedPath(coat, int(spec.get("max_depth", 8)), caustics="camera")


_TRACE: Any = None


def _trace(integrator: CoatedPath, scene: Any, sampler: Any, ray: Any, active: Any) -> Any:
    """The camera's vertex (module doc), then the path loop: Mitsuba's ``path`` on the coated
    resin, with or without the lamps' ``E D S L`` paths. The loop carries the ray and a small
    interaction, as ``path`` does, not the whole surface interaction (which made a first
    version 10-30 % slower a sample)."""
    import drjit as dr
    import mitsuba as mi

    ctx = mi.BSDFContext()
    coat, coat_ptr = integrator.coat, mi.BSDFPtr(integrator.coat)
    p_mirror, p_first, eta = integrator.p_mirror, integrator.p_first, integrator.eta
    only, leave_out = integrator.caustics == "only", integrator.caustics == "light"
    body_share = (1.0 - p_first) / (1.0 - p_mirror)  # (as at the camera's vertex)

    # --- The camera's vertex (apart, so that none of its values is carried by the loop).
    result, ray, beta, prev, prev_pdf, took_mirror, go = _camera_vertex(
        integrator, scene, sampler, ray, active
    )
    prev_mirror = mi.Bool(took_mirror)
    body_first = ~took_mirror
    chain = mi.Bool(took_mirror)  # every vertex so far went on by the mirror: the camera sees this one
    depth = mi.UInt32(1)  # vertices scattered so far

    # --- The rest of the path: Mitsuba's path.
    while go:
        si = scene.ray_intersect(ray, mi.RayFlags.Minimal | mi.RayFlags.ShadingFrame, False, go)
        emitted, weight_found = _light_found(scene, si, prev, prev_pdf, prev_mirror, depth == 1, go)
        # Seen through mirrors alone, this light was added at the last vertex with weight F, not F / p.
        weight_found = dr.select(chain, p_first, weight_found)
        on_lamp = si.is_valid() & (si.shape.emitter() != None)  # noqa: E711 (Dr.Jit's pointer test)
        caustic = (depth == 2) & body_first & prev_mirror & on_lamp  # E D S L: the light tracer's
        if only:
            result += dr.select(go & caustic, beta * emitted, 0.0)
        elif leave_out:
            result += dr.select(go & ~caustic, beta * emitted * weight_found, 0.0)
        else:
            result += dr.select(go, beta * emitted * weight_found, 0.0)
        on = go & si.is_valid() & (si.bsdf() == coat_ptr) & (mi.Frame3f.cos_theta(si.wi) > 0)
        on &= depth + 2 <= integrator.max_depth
        ds, em_weight = light_sample(scene, si, sampler.next_2d(on), on)
        # A vertex the camera sees through mirrors is done as the camera's own (module doc).
        share = dr.select(chain, body_share, 1.0)
        f_nee, pdf_nee = coat.eval_pdf(ctx, si, si.to_local(ds.d), on)
        if not only:
            nee = em_weight * f_nee * dr.select(ds.delta, 1.0, _power(ds.pdf, share * pdf_nee))
            result += dr.select(on, beta * nee, 0.0)
        p_here = dr.select(chain, p_first, p_mirror)
        mirror = sampler.next_1d(on) < p_here
        fresnel = _fresnel(mi.Frame3f.cos_theta(si.wi), eta)
        split = on & chain & ~mirror
        seen_by_mirror = scene.ray_intersect(
            si.spawn_ray(si.to_world(mi.reflect(si.wi))), mi.RayFlags.Minimal, False, split
        )
        if not only:
            result += dr.select(
                split, beta * fresnel * seen_by_mirror.emitter(scene).eval(seen_by_mirror, split), 0.0
            )
        wo_body = mi.warp.square_to_cosine_hemisphere(sampler.next_2d(on))
        f_body, pdf_body = coat.eval_pdf(ctx, si, wo_body, on)
        pdf_body *= share
        beta *= dr.select(
            mirror,
            mi.Spectrum(fresnel / p_here),
            dr.select(pdf_body > 0, f_body / dr.maximum(pdf_body, 1e-12), 0.0),
        )
        ray = si.spawn_ray(si.to_world(dr.select(mirror, mi.reflect(si.wi), wo_body)))
        prev, prev_pdf, prev_mirror = mi.Interaction3f(si), pdf_body, mirror
        chain &= mirror
        depth += 1
        beta, go = _russian_roulette(sampler, beta, on & (dr.max(beta) > 0), depth, integrator.rr_depth)
    return result


def _camera_vertex(integrator: CoatedPath, scene: Any, sampler: Any, ray: Any, active: Any) -> tuple:
    """The camera's vertex (module doc): what it adds to the image, and where the path goes on
    (the ray, its weight, the vertex, the body's density of the ray, whether it took the mirror,
    which lanes go on)."""
    import drjit as dr
    import mitsuba as mi

    ctx = mi.BSDFContext()
    coat, coat_ptr = integrator.coat, mi.BSDFPtr(integrator.coat)
    p_mirror, p_first, eta = integrator.p_mirror, integrator.p_first, integrator.eta
    only = integrator.caustics == "only"
    si = scene.ray_intersect(mi.Ray3f(ray), mi.RayFlags.Minimal | mi.RayFlags.ShadingFrame, True, active)
    result = mi.Spectrum(0.0) if only else dr.select(active, si.emitter(scene).eval(si, active), 0.0)
    on = active & si.is_valid() & (si.bsdf() == coat_ptr) & (mi.Frame3f.cos_theta(si.wi) > 0)
    # The body's density here is the coat's, with the body drawn 1 - p_first of the time.
    body_share = (1.0 - p_first) / (1.0 - p_mirror)
    for lamp in (e for e in scene.emitters() if not e.is_environment()):
        ds, lamp_weight = lamp.sample_direction(si, sampler.next_2d(on), on)
        seen = on & (ds.pdf > 0) & (dr.max(lamp_weight) > 0) & _in_front(si, ds)
        seen &= ~scene.ray_test(si.spawn_ray_to(ds.p), seen)
        f_lamp, pdf_lamp = coat.eval_pdf(ctx, si, si.to_local(ds.d), seen)
        if not only:
            result += dr.select(seen, lamp_weight * f_lamp * _power(ds.pdf, body_share * pdf_lamp), 0.0)
    fresnel = _fresnel(mi.Frame3f.cos_theta(si.wi), eta)
    mirror = sampler.next_1d(on) < p_first
    # The mirror's direct light on every sample: here where the path goes on by the body (the
    # branch by the mirror finds it at its next vertex).
    split = on & ~mirror
    seen_by_mirror = scene.ray_intersect(
        si.spawn_ray(si.to_world(mi.reflect(si.wi))), mi.RayFlags.Minimal, False, split
    )
    if not only:
        result += dr.select(split, fresnel * seen_by_mirror.emitter(scene).eval(seen_by_mirror, split), 0.0)
    wo_body = mi.warp.square_to_cosine_hemisphere(sampler.next_2d(on))
    f_body, pdf_body = coat.eval_pdf(ctx, si, wo_body, on)
    pdf_body *= body_share
    beta = dr.select(
        mirror,
        mi.Spectrum(fresnel / p_first),
        dr.select(pdf_body > 0, f_body / dr.maximum(pdf_body, 1e-12), 0.0),
    )
    ray = si.spawn_ray(si.to_world(dr.select(mirror, mi.reflect(si.wi), wo_body)))
    return result, ray, beta, mi.Interaction3f(si), pdf_body, mirror, on & (dr.max(beta) > 0)
