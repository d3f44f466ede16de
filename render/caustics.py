"""The lamps' caustics on a coated resin traced from the lamps, the rest of the image from the camera.

A geometry preview of a relief is smooth resin: a diffuse pigmented body under a smooth
dielectric coat, whose reflection is a mirror (a delta lobe). Light from a lamp that the coat of
one face reflects onto the body of another (the path ``E D S L`` in Heckbert's notation: eye,
diffuse body, specular coat, lamp) cannot be reached by a light sample from the body, only by a
body direction that happens to land where a neighbouring face mirrors the lamp. On the
``part_relief`` example those paths carry 1 % of the image's brightness and half of its
variance (``scripts/preview-estimators.py``), and they are what makes the CAD previews need
hundreds of samples a pixel.

Traced from the lamps they are cheap: a point on a lamp and a direction towards the object,
the coat's mirror reflection (weight: Fresnel), and where the reflected ray meets the body,
a connection to the camera (Veach 1997, ch. 10, light tracing; Mitsuba's ``ptracer`` does the
same for all paths). So the image is split by path, with nothing counted twice or left out:

* :class:`render.coated_path.CoatedPath` is Mitsuba's ``path`` estimator (next-event
  estimation, the power heuristic), its camera vertex done apart, which here drops exactly the
  paths whose first vertex took the body's lobe, whose second took the coat's mirror, and
  whose next hit is a lamp (the environment's reflections stay: they are smooth and cheap);
* :func:`caustic_image` estimates exactly those paths by light tracing: an unbiased image,
  its own pixel by pixel, summed in a fixed order (``np.bincount`` over the light paths in
  their order), so that the same seed gives the same bytes.

The two add up to the same expected image as ``path`` on the same scene, with the lamps'
faces black (a lamp's face reflects nothing; with Mitsuba's default grey face the light it
sends back was below 5e-6 of ``part_relief``'s mean). ``tests/test_caustics.py`` holds the
light-traced caustic to the path tracer's own estimate of the same paths, and the sum to
``path``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from render.coated_path import CoatedPath, _fresnel, camera_estimator, coat_of

LIGHT_PATHS_PER_CALL = 2_000_000
"""Light paths traced in one Dr.Jit call (a few hundred bytes a lane)."""
PILOT_PATHS = 500_000
"""Light paths a preview traces first: to learn its guide (:class:`Guide`), and to weigh its caustics."""
MIN_CAUSTIC_SHARE = 0.001
"""The split is taken where the lamps' caustics bring at least this share of the object's mean
luminance. Their share of the camera's variance follows it: on ``part_relief`` and
``brushed_part_fbm`` 1 % of the light and half the variance, on the demo's tile 0.2 % and a
quarter, on ``brushed_cylinder`` 0.03 % and 3 % (where the split's cost, its light paths and a
by-hand path loop some 10 % slower than Mitsuba's, is not paid back)."""


@dataclass(frozen=True)
class Lamp:
    """An area light the caustics are traced from: its rectangle (a Mitsuba shape), its radiance
    (linear RGB) and its centre (mm)."""

    shape: Any
    radiance: tuple[float, float, float]
    centre: tuple[float, float, float]


def lamps_of(scene: Any, scene_dict: dict[str, Any]) -> list[Lamp]:
    """The area lights of a loaded scene whose dictionary gives them an RGB ``radiance``."""
    out = []
    for shape in scene.shapes():
        entry = scene_dict.get(shape.id())
        if not shape.is_emitter() or not isinstance(entry, dict):
            continue
        radiance = entry["emitter"]["radiance"]["value"]
        centre = np.asarray(entry["to_world"].matrix, dtype=np.float64)[:3, 3]
        out.append(Lamp(shape, tuple(float(x) for x in radiance), tuple(float(x) for x in centre)))
    return out


def _lamp_probabilities(lamps: list[Lamp], centre: np.ndarray, radius: float) -> np.ndarray:
    """Each lamp's share of the light paths: luminance x area x the object's solid angle from it."""
    from render.convergence import LUMINANCE

    power = []
    for lamp in lamps:
        d2 = float(np.sum((np.asarray(lamp.centre) - centre) ** 2))
        omega = 2.0 * np.pi * (1.0 - np.sqrt(max(1.0 - radius * radius / d2, 0.0)))
        power.append(float(np.dot(lamp.radiance, LUMINANCE)) * float(lamp.shape.surface_area()[0]) * omega)
    total = float(sum(power))
    if not total > 0.0:
        raise ValueError("lamps: none sends light towards the object")
    return np.asarray(power) / total


GUIDE_CELLS = 32
"""The light paths' directions are drawn from a guide of this many cells a side per lamp, over the
square that Mitsuba's uniform-cone warp maps onto the cone holding the object."""
GUIDE_UNIFORM = 0.25
"""The guide's share of cells drawn as without it: no direction gets zero density (unbiased)."""


@dataclass(frozen=True)
class Guide:
    """Where the light paths leave from: a probability per lamp and cone cell, ``(lamps, n, n)``."""

    cells: np.ndarray

    @classmethod
    def uniform(cls, probabilities: np.ndarray, n: int = GUIDE_CELLS) -> Guide:
        per_cell = np.asarray(probabilities, dtype=np.float64)[:, None, None] / (n * n)
        return cls(np.broadcast_to(per_cell, (len(probabilities), n, n)).copy())

    def learned(self, cell: np.ndarray, contribution: np.ndarray) -> Guide:
        """This guide refined by light paths drawn from it: each path's cell and what it brought
        (luminance), the cells then in proportion to their estimated share of the caustics,
        mixed with this guide (:data:`GUIDE_UNIFORM`)."""
        flat = self.cells.ravel()
        share = np.bincount(cell, weights=contribution, minlength=flat.size)
        if not share.sum() > 0.0:
            return self
        mixed = (1.0 - GUIDE_UNIFORM) * share / share.sum() + GUIDE_UNIFORM * flat / flat.sum()
        return Guide(mixed.reshape(self.cells.shape))


def _splats(
    scene: Any,
    coat: Any,
    lamps: list[Lamp],
    guide: Guide,
    n: int,
    seed: int,
    centre: np.ndarray,
    radius: float,
    width: int,
    height: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` light paths lamp -> coat's mirror -> body -> camera: each one's pixel (-1: none), RGB
    and guide cell."""
    import drjit as dr
    import mitsuba as mi

    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(seed, n)
    side = guide.cells.shape[1]
    table = mi.DiscreteDistribution(mi.Float(np.ascontiguousarray(guide.cells.ravel(), dtype=np.float32)))
    index, _, pmf = table.sample_reuse_pmf(sampler.next_1d())
    which, cell = index // (side * side), index % (side * side)
    jitter = sampler.next_2d()
    towards = mi.Point2f(
        (mi.Float(cell % side) + jitter.x) / side, (mi.Float(cell // side) + jitter.y) / side
    )
    on_lamp = sampler.next_2d()
    p, normal = mi.Point3f(0.0), mi.Normal3f(0.0)
    pdf_area, radiance = mi.Float(0.0), mi.Color3f(0.0)
    for k, lamp in enumerate(lamps):
        pick = which == k
        ps = lamp.shape.sample_position(0.0, on_lamp, pick)
        p, normal = dr.select(pick, ps.p, p), dr.select(pick, ps.n, normal)
        pdf_area = dr.select(pick, ps.pdf, pdf_area)
        radiance = dr.select(pick, mi.Color3f(*[dr.opaque(mi.Float, c) for c in lamp.radiance]), radiance)
    # A direction in the cone that holds the object's bounding sphere, from the guide's cell.
    # The design's numbers held in memory: as literals, every object compiled its own kernel.
    to_centre = mi.Point3f(*[dr.opaque(mi.Float, float(x)) for x in centre]) - p
    distance = dr.norm(to_centre)
    cos_max = dr.safe_sqrt(1.0 - dr.square(dr.opaque(mi.Float, float(radius)) / distance))
    local = mi.warp.square_to_uniform_cone(towards, cos_max)
    pdf_dir = pmf * (side * side) * mi.warp.square_to_uniform_cone_pdf(local, cos_max)
    d = mi.Frame3f(to_centre / distance).to_world(local)
    cos_e = dr.dot(normal, d)
    leaves = (cos_e > 0) & (pmf > 0)
    beta = dr.select(leaves, radiance * cos_e / dr.maximum(pdf_area * pdf_dir, 1e-30), 0.0)
    coat_ptr = mi.BSDFPtr(coat)
    # Spawned off the lamp's face (a ray from the face itself hits it again at t = 0).
    start = mi.Interaction3f(mi.Float(0.0), mi.Float(0.0), dr.zeros(mi.Color0f), p, normal)
    si1 = scene.ray_intersect(start.spawn_ray(d), leaves)
    ok = leaves & si1.is_valid() & (si1.bsdf() == coat_ptr) & (mi.Frame3f.cos_theta(si1.wi) > 0)
    beta *= _fresnel(mi.Frame3f.cos_theta(si1.wi), coat.eta_held)
    si2 = scene.ray_intersect(si1.spawn_ray(si1.to_world(mi.reflect(si1.wi))), ok)
    ok &= si2.is_valid() & (si2.bsdf() == coat_ptr) & (mi.Frame3f.cos_theta(si2.wi) > 0)
    sensor = scene.sensors()[0]
    ds, importance = sensor.sample_direction(si2, mi.Point2f(0.5, 0.5), ok)
    ok &= (ds.pdf > 0) & (dr.max(importance) > 0)
    x, y = mi.Int32(dr.floor(ds.uv.x)), mi.Int32(dr.floor(ds.uv.y))
    # The visibility ray only where the body can send light to a pixel: towards the camera above
    # the surface (the coat reflects only), and into the frame.
    ok &= (x >= 0) & (x < width) & (y >= 0) & (y < height) & (mi.Frame3f.cos_theta(si2.to_local(ds.d)) > 0)
    ok &= ~scene.ray_test(si2.spawn_ray_to(ds.p), ok)
    body = coat.eval(mi.BSDFContext(mi.TransportMode.Importance), si2, si2.to_local(ds.d), ok)
    value = beta * body * importance
    ok &= dr.max(value) > 0
    pixel = dr.select(ok, y * width + x, -1)
    value = dr.select(ok, value, 0.0)
    dr.eval(pixel, value, index)
    dr.sync_thread()
    return (
        np.array(pixel, dtype=np.int64),
        np.array(value, dtype=np.float64).T,
        np.array(index, dtype=np.int64),
    )


def caustic_image(
    scene: Any,
    coat: Any,
    lamps: list[Lamp],
    n_paths: int,
    seed: int,
    *,
    centre_mm: np.ndarray,
    radius_mm: float,
    width_px: int,
    height_px: int,
    guide: Guide | None = None,
    learn: bool = False,
) -> tuple[np.ndarray, Guide]:
    """The lamps' ``E D S L`` caustics on the coat, by light tracing (module doc).

    Parameters
    ----------
    scene : mitsuba.Scene
        The loaded preview scene (one perspective sensor whose film is ``width_px`` x
        ``height_px``, box-filtered pixels as :class:`render.progressive.SampleRenderer` takes
        them).
    coat : mitsuba.BSDF
        The relief's coated resin.
    lamps : list of Lamp
        The area lights to trace from (:func:`lamps_of`).
    n_paths : int
        Light paths; the variance of a pixel falls as ``1 / n_paths``.
    seed : int
        Independent images for different seeds; the same seed gives the same bytes.
    centre_mm, radius_mm
        A sphere holding the object: the light paths leave each lamp inside the cone that holds it.
    guide : Guide, optional
        Where the paths leave from (default: each lamp by its power towards the object, every
        direction of the cone alike). Any guide gives an unbiased image; one learned from
        paths that found caustics (``learn``) gives a less noisy one.
    learn : bool
        Also return the guide refined by these paths (:meth:`Guide.learned`).

    Returns
    -------
    ``(image, guide)``: a ``(height_px * width_px, 3)`` float64 array of linear RGB, each
    pixel's mean radiance over its area from these paths (an unbiased estimate), and the guide
    (refined with ``learn``, else the one used).
    """
    from render.convergence import LUMINANCE
    from render.progressive import _mix

    if n_paths < 1:
        raise ValueError(f"n_paths: expected at least 1, got {n_paths}")
    centre = np.asarray(centre_mm, dtype=np.float64)
    if guide is None:
        guide = Guide.uniform(_lamp_probabilities(lamps, centre, float(radius_mm)))
    pixels = width_px * height_px
    image = np.zeros((pixels, 3))
    cells, brought = [], []
    for k, first in enumerate(range(0, n_paths, LIGHT_PATHS_PER_CALL)):
        count = min(LIGHT_PATHS_PER_CALL, n_paths - first)
        pixel, value, cell = _splats(
            scene, coat, lamps, guide, count, _mix(seed, k, 7), centre, float(radius_mm), width_px, height_px
        )
        keep = pixel >= 0
        for channel in range(3):
            image[:, channel] += np.bincount(pixel[keep], weights=value[keep, channel], minlength=pixels)
        if learn:
            cells.append(cell[keep])
            brought.append(value[keep] @ LUMINANCE)
    # A light path's importance is normalised over the whole film; a pixel is 1/pixels of it.
    image *= pixels / n_paths
    if learn and cells:
        guide = guide.learned(np.concatenate(cells), np.concatenate(brought))
    return image, guide


def caustic_split(
    renderer: Any, mask: np.ndarray, seed: int
) -> tuple[Callable[..., np.ndarray], Callable[[int, int], np.ndarray]] | None:
    """The camera's part and the light-traced part of a coated relief's preview (module doc).

    ``renderer`` is a :class:`render.progressive.SampleRenderer` of a preview scene
    (:func:`render.mitsuba_adapter.resin_scene_dict`), ``mask`` its object's pixels. Returns
    ``(render, caustics)`` for :func:`render.convergence.converge`: ``render(spp, seed,
    pixels)`` traces the camera's samples without the lamps' ``E D S L`` paths,
    ``caustics(n_paths, seed)`` light-traces those paths, ``(height, width, 3)``. None where
    the split does not apply (Mitsuba's scalar variant, a relief that is not the coated resin,
    no lamp) or does not pay: a pilot of light paths (which also learns the guide) and one
    camera sample a pixel find the caustics under :data:`MIN_CAUSTIC_SHARE` of the light.
    """
    from render.convergence import LUMINANCE

    if renderer.scalar:
        return None
    scene_dict = renderer.scene_dict
    coat = coat_of(scene_dict)
    spec = scene_dict.get("integrator", {})
    if coat is None or spec.get("type") != "path" or not np.any(mask):
        return None
    lamps = lamps_of(renderer.scene, scene_dict)
    if not lamps:
        return None
    integrator = CoatedPath(coat, int(spec.get("max_depth", 8)))
    relief = next(s for s in renderer.scene.shapes() if not s.is_emitter())
    box = relief.bbox()
    centre = np.array([float(box.center()[i]) for i in range(3)])
    radius = 0.5 * float(np.linalg.norm([float(box.extents()[i]) for i in range(3)]))
    width, height = renderer.width, renderer.height
    frame = {"centre_mm": centre, "radius_mm": radius, "width_px": width, "height_px": height}
    # The pilots: seeds of their own, so that no image the preview keeps depends on them.
    pilot, guide = caustic_image(
        renderer.scene, coat, lamps, PILOT_PATHS, seed ^ 0x5F3759DF, learn=True, **frame
    )
    caustic_mean = float(np.mean(pilot[mask.ravel()] @ LUMINANCE))
    camera = renderer.render(1, seed ^ 0x2545F491, np.flatnonzero(mask.ravel()))
    if not caustic_mean >= MIN_CAUSTIC_SHARE * float(np.mean(camera @ LUMINANCE)):
        return None

    def render(spp: int, seed: int, pixels: np.ndarray | None = None) -> np.ndarray:
        return renderer.render(spp, seed, pixels, integrator=integrator)

    def caustics(n_paths: int, seed: int) -> np.ndarray:
        image, _ = caustic_image(renderer.scene, coat, lamps, n_paths, seed, guide=guide, **frame)
        return image.reshape(height, width, 3)

    return render, caustics


def preview_estimators(
    renderer: Any, mask: np.ndarray, seed: int
) -> tuple[Callable[..., np.ndarray], Callable[[int, int], np.ndarray] | None] | None:
    """``(render, caustics)`` for a preview's :func:`render.convergence.converge`.

    The split of :func:`caustic_split` where it applies and pays. Where the relief is the
    coated resin but the split is declined (its caustics too faint to pay for the light
    paths), the camera's estimator of :mod:`render.coated_path` with the caustics kept in it,
    and no light tracing (``caustics`` None). None elsewhere: the scene's own integrator
    (Mitsuba's ``path``, ``volpath`` for a medium) serves.
    """
    split = caustic_split(renderer, mask, seed)
    if split is not None:
        return split
    integrator = camera_estimator(renderer)
    if integrator is None:
        return None

    def render(spp: int, seed: int, pixels: np.ndarray | None = None) -> np.ndarray:
        return renderer.render(spp, seed, pixels, integrator=integrator)

    return render, None
