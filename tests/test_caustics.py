"""The lamps' caustics light-traced beside the camera's paths (render.caustics): the light tracer
against the camera's own estimate of the same paths, the two parts against Mitsuba's ``path``,
determinism, and where the split is declined. Statistical, with fixed seeds."""

import numpy as np
import pytest

from render.convergence import LUMINANCE
from tests.scenes import v_grooves

WIDTH, HEIGHT = 96, 72


def _scene(depth_mm: float = 2.0):
    from render.mitsuba_adapter import choose_variant, resin_scene_dict
    from render.progressive import SampleRenderer

    variant = choose_variant()
    if variant.variant.startswith("scalar"):
        pytest.skip("the light tracer runs on Mitsuba's vectorised variants")
    vertices, faces = v_grooves(depth_mm)
    scene_dict, frame = resin_scene_dict(
        vertices,
        faces,
        body_albedo=(0.25, 0.45, 0.75),
        refractive_index=1.5,
        width_px=WIDTH,
        height_px=HEIGHT,
    )
    renderer = SampleRenderer(scene_dict, WIDTH, HEIGHT)
    mask = renderer.aovs(4, 0)["coverage"] >= 0.5
    return renderer, frame, mask


def _light(renderer, frame, n, seed, guide=None, learn=False):
    from render.caustics import caustic_image, coat_of, lamps_of

    d = renderer.scene_dict
    return caustic_image(
        renderer.scene,
        coat_of(d),
        lamps_of(renderer.scene, d),
        n,
        seed,
        centre_mm=frame.centre,
        radius_mm=frame.radius_mm,
        width_px=WIDTH,
        height_px=HEIGHT,
        guide=guide,
        learn=learn,
    )


def _camera(renderer, integrator, spp, seeds):
    """Mean and variance of the mean, per pixel (luminance), over independent renders."""
    images = np.stack([renderer.render(spp, s, integrator=integrator) @ LUMINANCE for s in seeds])
    return images.mean(0), images.var(0, ddof=1) / len(seeds)


def _blocks(image: np.ndarray, mask: np.ndarray, size: int = 12) -> np.ndarray:
    """Sums over size x size blocks of the object's pixels: where the caustics fall, coarsely."""
    h, w = image.shape
    m = np.where(mask, image, 0.0)
    return m[: h // size * size, : w // size * size].reshape(h // size, size, w // size, size).sum((1, 3))


def test_light_traced_caustics_are_the_cameras_estimate_of_the_same_paths():
    from render.caustics import coat_of
    from render.coated_path import CoatedPath

    renderer, frame, mask = _scene()
    only = CoatedPath(coat_of(renderer.scene_dict), caustics="only")
    images = np.stack([renderer.render(64, s, integrator=only) @ LUMINANCE for s in range(24)])
    camera, camera_means = images.mean(0), images[:, mask].mean(1)
    camera_mean = camera[mask].mean()
    # The caustics are real on this relief: more than 1 % of its light.
    everything = renderer.render(16, 99)[mask] @ LUMINANCE
    assert camera_mean > 0.01 * everything.mean()
    _, guide = _light(renderer, frame, 200_000, 12345, learn=True)
    for which in (None, guide):  # without a guide and with a learned one: the same image
        runs = np.stack([_light(renderer, frame, 400_000, s, guide=which)[0] @ LUMINANCE for s in range(4)])
        light = runs.mean(0).reshape(HEIGHT, WIDTH)
        # over the object, within four standard errors of the two (the camera's about 1.2 %)
        light_means = runs.reshape(len(runs), HEIGHT, WIDTH)[:, mask].mean(1)
        se = np.sqrt(
            camera_means.var(ddof=1) / camera_means.size + light_means.var(ddof=1) / light_means.size
        )
        assert abs(light_means.mean() - camera_mean) < 4 * se
        assert se < 0.02 * camera_mean
        # and where they fall: block by block
        a, b = _blocks(camera, mask), _blocks(light, mask)
        lit = a > 0.05 * a.max()
        assert np.corrcoef(a[lit], b[lit])[0, 1] > 0.95


def test_the_two_parts_add_up_to_mitsubas_path():
    from render.caustics import coat_of
    from render.coated_path import CoatedPath

    renderer, frame, mask = _scene()
    path, path_var = _camera(renderer, None, 64, range(4))
    rest, rest_var = _camera(renderer, CoatedPath(coat_of(renderer.scene_dict)), 64, range(10, 14))
    light = _light(renderer, frame, 1_000_000, 5)[0] @ LUMINANCE
    split = rest + light.reshape(HEIGHT, WIDTH)
    n = mask.sum()
    se = np.sqrt((path_var[mask].sum() + rest_var[mask].sum()) / n**2)
    assert abs(split[mask].mean() - path[mask].mean()) < 4 * se + 0.005 * path[mask].mean()
    a, b = _blocks(path, mask), _blocks(split, mask)
    assert np.corrcoef(a.ravel(), b.ravel())[0, 1] > 0.99
    # and the camera's part without the caustics is the less noisy for it
    assert rest_var[mask].mean() < 0.9 * path_var[mask].mean()


def test_the_camera_vertex_done_apart_is_mitsubas_path_whatever_the_first_mirror_probability():
    """The camera's vertex done apart (render.coated_path: the mirror's light split off, each lamp
    sampled, the body's density as drawn there) changes no expectation: with the caustics kept,
    and as the caustic-free part plus the camera's own caustics, it is Mitsuba's ``path`` to
    within four standard errors of a twentieth of a percent (a density left as the coat's, not
    as drawn, was 10 % off; weights that did not sum to one, 0.45 %)."""
    from render.caustics import coat_of
    from render.coated_path import CoatedPath

    renderer, _, mask = _scene()
    coat = coat_of(renderer.scene_dict)

    def means(integrator, seeds):
        return np.array(
            [(renderer.render(64, s, integrator=integrator) @ LUMINANCE)[mask].mean() for s in seeds]
        )

    path = means(None, range(16))
    for p_first in (0.3, 0.7):
        whole = means(CoatedPath(coat, caustics="camera", first_mirror_probability=p_first), range(300, 316))
        rest = means(CoatedPath(coat, first_mirror_probability=p_first), range(100, 116))
        only = means(CoatedPath(coat, caustics="only", first_mirror_probability=p_first), range(200, 216))
        se_whole = np.sqrt((path.var(ddof=1) + whole.var(ddof=1)) / 16)
        se_parts = np.sqrt((path.var(ddof=1) + rest.var(ddof=1) + only.var(ddof=1)) / 16)
        assert max(se_whole, se_parts) < 0.001 * path.mean()
        assert abs(whole.mean() - path.mean()) < 4 * se_whole
        assert abs(rest.mean() + only.mean() - path.mean()) < 4 * se_parts


def test_a_light_sample_below_the_coat_loses_nothing_against_mitsubas_own():
    """``light_sample`` against Mitsuba's own ``sample_emitter_direction`` with its visibility test,
    on the same samples at the grooves' visible points: the same light (weight times the coat's
    value) on every lane, the same weight and density wherever the direction is above the
    surface, and enough lanes below it (lamps behind a groove's wall, the sky's lower half) that
    skipping their rays is exercised."""
    import drjit as dr
    import mitsuba as mi

    from render.caustics import coat_of
    from render.coated_path import light_sample

    renderer, _, _ = _scene()
    scene, coat = renderer.scene, coat_of(renderer.scene_dict)
    n = WIDTH * HEIGHT * 4
    index = dr.arange(mi.UInt32, n)
    column, row = mi.Float(index % (2 * WIDTH)), mi.Float(index // (2 * WIDTH))
    film = mi.Point2f((column + 0.5) / (2 * WIDTH), (row + 0.5) / (2 * HEIGHT))
    ray, _ = scene.sensors()[0].sample_ray(0.0, 0.5, film, mi.Point2f(0.5, 0.5))
    si = scene.ray_intersect(ray)
    on = si.is_valid() & (si.bsdf() == mi.BSDFPtr(coat)) & (mi.Frame3f.cos_theta(si.wi) > 0)
    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(11, n)
    sample = sampler.next_2d()
    theirs, their_weight = scene.sample_emitter_direction(si, sample, True, on)
    ours, our_weight = light_sample(scene, si, sample, on)
    f = coat.eval(mi.BSDFContext(), si, si.to_local(theirs.d), on)
    light_theirs, light_ours = np.array(their_weight * f), np.array(our_weight * f)
    above = np.array(mi.Frame3f.cos_theta(si.to_local(theirs.d)) > 0)
    drawn = np.array(on & (scene.sample_emitter_direction(si, sample, False, on)[0].pdf > 0))
    assert np.array_equal(np.array(ours.d), np.array(theirs.d))
    assert np.array_equal(light_ours, light_theirs)
    assert np.array_equal(np.array(our_weight)[:, above], np.array(their_weight)[:, above])
    assert np.array_equal(np.array(ours.pdf)[above], np.array(theirs.pdf)[above])
    assert np.all(np.array(our_weight)[:, ~above] == 0.0)
    assert np.count_nonzero(drawn) > n // 10  # the grooves fill a fifth of the frame
    below = np.count_nonzero(drawn & ~above) / np.count_nonzero(drawn)
    assert 0.05 < below < 0.95, below  # (about 9 % here)
    assert np.count_nonzero(light_theirs.max(axis=0) > 0) > n // 20  # and light is found above


def test_a_new_resin_or_object_traces_the_same_kernels():
    """What a design sets (the coat's body colour and index, the object's size and so the camera's
    and the lamps' places, the light tracer's sphere) is held in memory, not written into the
    traced code: a new design renders with the kernels already compiled. As literals, a new
    colour compiled the preview's kernels anew (seven, about two seconds here) and so did a new
    object size (five). Compared by the kernels' hashes in Dr.Jit's history."""
    import drjit as dr

    from render.caustics import coat_of
    from render.coated_path import CoatedPath
    from render.mitsuba_adapter import Framing, resin_scene_dict
    from render.progressive import SampleRenderer

    _scene()  # (the variant, or a skip)

    def kernels(albedo, ior, depth_mm):
        vertices, faces = v_grooves(depth_mm)
        scene_dict, frame = resin_scene_dict(
            vertices, faces, body_albedo=albedo, refractive_index=ior, width_px=WIDTH, height_px=HEIGHT
        )
        assert isinstance(frame, Framing)
        r = SampleRenderer(scene_dict, WIDTH, HEIGHT)
        dr.kernel_history()  # (emptied)
        r.render(4, 3, integrator=CoatedPath(coat_of(r.scene_dict), caustics="light"))
        r.render(1, 3)  # the scene's own integrator (Mitsuba's path), as the light sweep renders
        _light(r, frame, 20_000, 5)
        return frame.radius_mm, {k["hash"] for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT}

    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        radius, first = kernels((0.25, 0.45, 0.75), 1.5, 2.0)
        other_radius, other = kernels((0.7, 0.2, 0.1), 1.58, 3.0)
        assert other_radius != radius  # (a different framing)
        assert first == other
        assert len(first) >= 3  # the camera's paths, Mitsuba's path and the light paths
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)


def test_the_light_tracer_is_deterministic_and_its_seeds_independent():
    renderer, frame, _ = _scene()
    one, guide = _light(renderer, frame, 50_000, 3, learn=True)
    two, guide_again = _light(renderer, frame, 50_000, 3, learn=True)
    other, _ = _light(renderer, frame, 50_000, 4)
    assert np.array_equal(one, two) and np.array_equal(guide.cells, guide_again.cells)
    assert not np.array_equal(one, other)
    assert guide.cells.sum() == pytest.approx(1.0, abs=1e-9) and (guide.cells > 0).all()


def test_the_split_is_taken_on_grooves_and_declined_on_a_flat_tile():
    from render.caustics import caustic_split, preview_estimators

    renderer, _, mask = _scene(2.0)
    split = caustic_split(renderer, mask, 7)
    assert split is not None
    render, caustics = split
    assert render(1, 0, None).shape == (HEIGHT, WIDTH, 3)
    assert caustics(1000, 0).shape == (HEIGHT, WIDTH, 3)
    flat, _, flat_mask = _scene(0.0)
    assert caustic_split(flat, flat_mask, 7) is None
    # where it is declined, the preview still does the camera's vertex apart, with no light paths
    render, caustics = preview_estimators(flat, flat_mask, 7)
    assert caustics is None and render(1, 0, None).shape == (HEIGHT, WIDTH, 3)


def test_only_the_coated_resin_gets_the_camera_vertex_done_apart():
    """A relief wearing a BRDF representation, or a medium, keeps the scene's own integrator."""
    import trimesh

    from render.coated_path import CoatedPath, camera_estimator
    from render.mitsuba_adapter import resin_scene_dict
    from render.mitsuba_bsdfs import CompactSurface
    from render.progressive import SampleRenderer
    from render.translucency import MediumRGB

    _scene()  # (the variant, or a skip)
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=5.0)

    def estimator(**kwargs):
        scene_dict, _ = resin_scene_dict(
            np.asarray(sphere.vertices), np.asarray(sphere.faces), body_albedo=(0.5, 0.5, 0.5),
            refractive_index=1.5, width_px=16, height_px=12, **kwargs,
        )  # fmt: skip
        return camera_estimator(SampleRenderer(scene_dict, 16, 12))

    assert isinstance(estimator(), CoatedPath)
    assert estimator(surface=CompactSurface("ggx", 0.2, 0.2, 0.0, 1.5, (0.5, 0.5, 0.5))) is None
    medium = MediumRGB(sigma_s_per_mm=(1.0, 1.0, 1.0), sigma_a_per_mm=(0.01, 0.01, 0.01), g=0.0)
    assert estimator(medium=medium) is None
