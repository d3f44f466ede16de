"""Two more ways round the CAD previews' noise, measured: the camera vertex by hand, and longer passes.

    .venv/bin/python scripts/preview-estimators.py MODEL.stl [SAMPLES_PER_HALF]

MODEL.stl is a mesh to light, e.g. the ``model.stl`` that ``printapp design
examples/part_relief.toml`` writes; its preview scene is built as ``printapp design`` builds
it (1024 x 768, the coated blue resin under printapp's studio light).

Part 1, estimators, each rendered in two independent halves of SAMPLES_PER_HALF (default
16) samples a pixel over the object's pixels, with the object's mean luminance (they must
agree: each is unbiased), the relative noise, the seconds and the efficiency 1 / (noise^2 s):

- ``path``: Mitsuba's ``path`` integrator, as the preview renders;
- ``vertex by hand``: the camera vertex on the coated resin done here (next-event estimation
  on the body with the power heuristic against the body's sampling density, the mirror drawn
  with the coat's probability, the first hit of the drawn ray's emission weighted as ``path``
  does), the rest of the path by ``path`` with the emitters at its first hit hidden: the
  same estimator as ``path``, the check that the pieces below are right;
- ``glint every sample``: the same, but the mirror ray's first hit is traced for every sample
  and its emission (the soft box's glint) added with weight F, whichever lobe was drawn: the
  glints' variance from the lobe choice taken away.

For ``path`` it also gives where the variance is: the share of it in pixels by their mean
luminance (the soft box's reflections are the band 0.4-0.8).

Part 2, stratification: 20,000 object pixels drawn at random, rendered with 16, 64 and 256
samples a pixel in passes of 1, 4, 16, 64 and 256 (each pass one randomisation of Mitsuba's
``ldsampler``), twice with independent seeds; the mean variance of a pixel's estimate, over all
the pixels and over the glints (mean luminance 0.4-0.8). Whether longer passes (more samples
stratified together) would lower the variance beyond the adaptive rounds' passes.
"""

from __future__ import annotations

import sys
import time
from typing import Any

import numpy as np
from preview_scene import HEIGHT, WIDTH, preview_scene  # (scripts/, beside this file)

from render.convergence import LUMINANCE, _dilate, _lum, relative_noise
from render.mitsuba_shared import fresnel_dr
from render.mitsuba_shared import power_heuristic as _power
from render.progressive import SampleRenderer, passes_of


class CameraVertexByHand:
    """An object with ``path``'s ``sample`` signature whose first vertex on ``coat`` is done here."""

    def __init__(self, coat: Any, max_depth: int, glint_every_sample: bool) -> None:
        import mitsuba as mi

        self.coat, self.glint = coat, glint_every_sample
        self.visible = mi.load_dict({"type": "path", "max_depth": max_depth})
        self.hidden = mi.load_dict({"type": "path", "max_depth": max_depth - 1, "hide_emitters": True})

    def sample(self, scene: Any, sampler: Any, ray: Any, medium: Any, active: Any) -> tuple[Any, Any, list]:
        import drjit as dr
        import mitsuba as mi

        active, ray = mi.Bool(active), mi.Ray3f(ray)
        si = scene.ray_intersect(ray, active)
        cos_i = mi.Frame3f.cos_theta(si.wi)
        on = active & si.is_valid() & (si.bsdf() == mi.BSDFPtr(self.coat)) & (cos_i > 0)
        p, ctx = self.coat.p_mirror, mi.BSDFContext()
        fresnel = fresnel_dr(cos_i, self.coat.eta)
        ray_m = si.spawn_ray(si.to_world(mi.reflect(si.wi)))
        ds, em_weight = scene.sample_emitter_direction(si, sampler.next_2d(on), True, on)
        f_nee, pdf_nee = self.coat.eval_pdf(ctx, si, si.to_local(ds.d), on)
        mis = dr.select(ds.delta, 1.0, _power(ds.pdf, pdf_nee))
        result = dr.select(on, em_weight * f_nee * mis, 0.0)
        pick_mirror = sampler.next_1d(on) < p
        wo_body = mi.warp.square_to_cosine_hemisphere(sampler.next_2d(on))
        f_body, pdf_body = self.coat.eval_pdf(ctx, si, wo_body, on)
        body = on & ~pick_mirror & (pdf_body > 0)
        w_body = dr.select(body, f_body / dr.maximum(pdf_body, 1e-12), 0.0)
        ray_c = dr.select(pick_mirror, ray_m, si.spawn_ray(si.to_world(wo_body)))
        si_c = scene.ray_intersect(ray_c, on)
        emitted = si_c.emitter(scene).eval(si_c, on)
        em_pdf = scene.pdf_emitter_direction(si, mi.DirectionSample3f(scene, si_c, si), body)
        result += dr.select(body, w_body * emitted * _power(pdf_body, em_pdf), 0.0)
        w_mirror = fresnel / p
        if self.glint:
            si_m = scene.ray_intersect(ray_m, on)
            result += dr.select(on, fresnel * si_m.emitter(scene).eval(si_m, on), 0.0)
        else:
            result += dr.select(on & pick_mirror, w_mirror * emitted, 0.0)
        w_c = dr.select(pick_mirror, w_mirror, w_body)
        rest, _, _ = self.hidden.sample(scene, sampler, ray_c, None, on & (dr.max(w_c) > 0))
        result += dr.select(on, w_c * rest, 0.0)
        other, _, _ = self.visible.sample(scene, sampler, ray, None, active & ~on)
        return result + dr.select(active & ~on, other, 0.0), active, []


def _halves(renderer: SampleRenderer, active: np.ndarray, spp: int, integrator: Any) -> list[np.ndarray]:
    out = []
    for which in (0, 1):
        image = np.zeros((HEIGHT * WIDTH, 3))
        total = np.zeros((active.size, 3))
        for k, count in enumerate(passes_of(spp)):
            seed = 1000 * which + k
            # (SampleRenderer's own trace, with another object in the integrator's place.)
            total += count * renderer._trace(
                renderer.scene, count, seed, 3, pixels=active, integrator=integrator
            )
        image[active] = total / spp
        out.append(image.reshape(HEIGHT, WIDTH, 3))
    return out


def main(path: str, spp: int) -> None:
    _, _, scene, _ = preview_scene(path)
    renderer = SampleRenderer(scene, WIDTH, HEIGHT)
    mask = renderer.aovs(4, 0)["coverage"] >= 0.5
    active = np.flatnonzero(_dilate(mask, 2))
    coat = next(s.bsdf() for s in renderer.scene.shapes() if "CoatedResin" in str(s.bsdf()))
    print(f"{mask.sum()} object pixels, two halves of {spp} samples a pixel")
    estimators = {
        "path": renderer.scene.integrator(),
        "vertex by hand": CameraVertexByHand(coat, 8, glint_every_sample=False),
        "glint every sample": CameraVertexByHand(coat, 8, glint_every_sample=True),
    }
    means = None
    for name, integrator in estimators.items():
        renderer._trace(renderer.scene, 1, 0, 3, pixels=active[:256], integrator=integrator)  # compile
        start = time.perf_counter()
        a, b = _halves(renderer, active, spp, integrator)
        seconds = time.perf_counter() - start
        mean = float(np.mean(0.5 * (_lum(a) + _lum(b))[mask]))
        noise = relative_noise(a, b, mask)
        efficiency = 1.0 / (noise**2 * seconds)
        print(f"{name:20s} mean {mean:.5f} noise {noise:7.3%} {seconds:6.2f} s efficiency {efficiency:6.1f}")
        if name == "path":
            means = 0.5 * (_lum(a) + _lum(b)).ravel()
            variance = ((_lum(a) - _lum(b)) ** 2 / 4.0).ravel()
            print(
                "  path's variance by the pixel's mean luminance: share of object pixels, share of variance"
            )
            for low, high in ((0.0, 0.1), (0.1, 0.2), (0.2, 0.4), (0.4, 0.8), (0.8, np.inf)):
                band = mask.ravel() & (means >= low) & (means < high)
                pixels_share, variance_share = band.sum() / mask.sum(), variance[band].sum() / variance.sum()
                print(f"    {low:.1f}-{high:.1f}: {pixels_share:6.1%} {variance_share:6.1%}")
    assert means is not None
    print("\nstratification: mean variance of a pixel's estimate (all / glints), seconds")
    pixels = np.sort(np.random.default_rng(0).choice(np.flatnonzero(mask.ravel()), 20_000, replace=False))
    glints = (means[pixels] > 0.4) & (means[pixels] < 0.8)
    for total in (16, 64, 256):
        for per_pass in (1, 4, 16, 64, 256):
            if per_pass > total:
                continue
            start = time.perf_counter()
            estimates = []
            for base in (100_000, 200_000):
                sums = sum(renderer.render(per_pass, base + k, pixels) for k in range(total // per_pass))
                estimates.append(sums / (total // per_pass) @ LUMINANCE)
            variance = (estimates[0] - estimates[1]) ** 2 / 2.0
            seconds = time.perf_counter() - start
            print(
                f"  {total:4d} spp in passes of {per_pass:4d}: {variance.mean():.3e} / "
                f"{variance[glints].mean():.3e}  {seconds:6.2f} s"
            )


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 16)
