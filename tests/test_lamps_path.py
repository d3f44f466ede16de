"""render.lamps_path (every lamp sampled at the camera's vertex) against Mitsuba's ``path``, and
which estimator a preview scene gets (render.coated_path.camera_estimator). Statistical, with
fixed seeds."""

import numpy as np
import pytest
import trimesh

from render.convergence import LUMINANCE

WIDTH, HEIGHT = 96, 72


def _renderer(surface=None, medium=None):
    from render.mitsuba_adapter import choose_variant, resin_scene_dict
    from render.progressive import SampleRenderer

    if choose_variant().variant.startswith("scalar"):
        pytest.skip("printapp's estimators run on Mitsuba's vectorised variants")
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=5.0)
    scene_dict, _ = resin_scene_dict(
        np.asarray(sphere.vertices), np.asarray(sphere.faces), body_albedo=(0.25, 0.45, 0.75),
        refractive_index=1.5, width_px=WIDTH, height_px=HEIGHT, surface=surface, medium=medium,
    )  # fmt: skip
    return SampleRenderer(scene_dict, WIDTH, HEIGHT)


def _means(renderer, integrator, mask, seeds):
    return np.array([(renderer.render(64, s, integrator=integrator) @ LUMINANCE)[mask].mean() for s in seeds])


@pytest.mark.parametrize(
    "surface",
    [("ggx", 0.05, 0.3, 0.4), ("beckmann", 0.3, 0.3, 0.0)],
    ids=["sharp anisotropic ggx", "rough beckmann"],
)
def test_every_lamp_sampled_is_mitsubas_path(surface):
    """The same expectation as ``path`` over a glossy sphere under both lamps and the sky, to
    within four standard errors of under a tenth of a percent; and less noisy."""
    from render.coated_path import camera_estimator
    from render.mitsuba_bsdfs import CompactSurface

    distribution, alpha_u, alpha_v, azimuth = surface
    renderer = _renderer(CompactSurface(distribution, alpha_u, alpha_v, azimuth, 1.5, (0.25, 0.45, 0.75)))
    mask = renderer.aovs(4, 0)["coverage"] >= 0.5
    lamps = camera_estimator(renderer)
    assert type(lamps).__name__ == "LampsPath"
    path = _means(renderer, None, mask, range(16))
    ours = _means(renderer, lamps, mask, range(100, 116))
    se = np.sqrt((path.var(ddof=1) + ours.var(ddof=1)) / 16)
    assert se < 0.001 * path.mean()
    assert abs(ours.mean() - path.mean()) < 4 * se
    one = renderer.render(16, 7, integrator=lamps) @ LUMINANCE
    two = renderer.render(16, 8, integrator=lamps) @ LUMINANCE
    a, b = renderer.render(16, 7) @ LUMINANCE, renderer.render(16, 8) @ LUMINANCE
    assert np.mean((one - two)[mask] ** 2) < 0.8 * np.mean((a - b)[mask] ** 2)


def test_each_preview_scene_gets_its_estimator():
    from render.coated_path import CoatedPath, camera_estimator
    from render.mitsuba_bsdfs import CompactSurface
    from render.translucency import MediumRGB

    assert isinstance(camera_estimator(_renderer()), CoatedPath)
    assert camera_estimator(_renderer(CompactSurface("ggx", 0.2, 0.2, 0.0, 1.5, (0.5, 0.5, 0.5)))) is not None
    medium = MediumRGB(sigma_s_per_mm=(1.0, 1.0, 1.0), sigma_a_per_mm=(0.01, 0.01, 0.01), g=0.0)
    assert camera_estimator(_renderer(medium=medium)) is None  # volpath serves
