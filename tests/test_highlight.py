"""The anisotropic highlight: its predicted place and stretch on the screen, its moments, the verdict."""

import math
from dataclasses import replace

import numpy as np
import pytest

from render.highlight import (
    PinholeCamera,
    SlopeLobe,
    axis_difference_deg,
    highlight_shape,
    predicted_highlight,
)

ELEVATION = math.radians(40.0)


def _mirror_scene(distance=200.0, size=(384, 384)):
    """Camera at -60 deg azimuth, 40 deg elevation; the light at its mirror image; both ``distance`` away."""
    az = math.radians(-60.0)

    def on(a, r):
        return (
            r * math.cos(ELEVATION) * math.cos(a),
            r * math.cos(ELEVATION) * math.sin(a),
            r * math.sin(ELEVATION),
        )

    camera = PinholeCamera(on(az, distance), (0.0, 0.0, 0.0), 20.0, *size)
    return camera, on(az + math.pi, distance)


def test_a_gaussian_ellipse_gives_back_its_axis_and_ratio():
    rows, cols = np.indices((200, 300), dtype=float)
    x, y = cols + 0.5 - 150.0, -(rows + 0.5 - 100.0)
    angle = math.radians(35.0)
    u = math.cos(angle) * x + math.sin(angle) * y
    w = -math.sin(angle) * x + math.cos(angle) * y
    image = np.exp(-0.5 * ((u / 24.0) ** 2 + (w / 6.0) ** 2))
    shape = highlight_shape(image, np.ones(image.shape, bool), quantile=0.5)
    # The level sets of a Gaussian are similar ellipses: thresholding keeps the axis ratio.
    assert shape.angle_deg == pytest.approx(35.0, abs=0.5)
    assert shape.elongation == pytest.approx(4.0, rel=0.02)
    assert shape.centroid_px == pytest.approx((150.0, 100.0), abs=0.1)
    assert highlight_shape(np.zeros((8, 8)), np.ones((8, 8), bool)) is None


def test_a_pixel_ray_lands_on_the_point_that_projects_back_to_it():
    camera, _ = _mirror_scene(size=(64, 48))
    rays = camera.pixel_rays()
    for row, col in ((0, 0), (10, 50), (47, 63)):
        point = np.asarray(camera.eye) + 123.0 * rays[row, col]
        assert camera.project(point) == pytest.approx((col + 0.5, row + 0.5), abs=1e-9)
    # Image x runs right: a point to the camera's right (east of a camera looking north) is right of centre.
    assert camera.project(np.array([0.0, 0.0, 0.0])) == pytest.approx((32.0, 24.0), abs=1e-9)


@pytest.mark.parametrize(
    ("lobe_azimuth_deg", "screen_deg", "expected"),
    [
        # The slopes' long axis in the plane of incidence (the camera's azimuth, -60 deg, i.e. 120 deg):
        # on the screen the highlight is ratio / sin(elevation) times taller than wide (first order).
        (120.0, 90.0, 3.0 / math.sin(ELEVATION)),
        # Across the plane of incidence: ratio * sin(elevation) times wider than tall.
        (30.0, 0.0, 3.0 * math.sin(ELEVATION)),
    ],
)
def test_the_highlight_stretches_as_the_first_order_mapping_says(lobe_azimuth_deg, screen_deg, expected):
    camera, light = _mirror_scene()
    lobe = SlopeLobe(0.03, 0.01, math.radians(lobe_azimuth_deg))
    image, mask = predicted_highlight(
        camera, light, 0.01, lobe, 0.0, (-60.0, 60.0, -60.0, 60.0), light_samples=1
    )
    shape = highlight_shape(image, mask, quantile=0.5)
    assert axis_difference_deg(shape.angle_deg, screen_deg) < 1.0
    assert shape.elongation == pytest.approx(expected, rel=0.05)
    # The light at the camera's mirror image: the highlight is centred on the tile.
    assert shape.centroid_px == pytest.approx((192.0, 192.0), abs=3.0)


def test_a_round_lobe_is_stretched_by_the_view_alone():
    camera, light = _mirror_scene()
    lobe = SlopeLobe(0.02, 0.02, 0.0)
    image, mask = predicted_highlight(
        camera, light, 0.01, lobe, 0.0, (-60.0, 60.0, -60.0, 60.0), light_samples=1
    )
    shape = highlight_shape(image, mask, quantile=0.5)
    assert axis_difference_deg(shape.angle_deg, 90.0) < 1.0
    assert shape.elongation == pytest.approx(1.0 / math.sin(ELEVATION), rel=0.05)


def test_the_verdict_asks_for_the_axis_and_a_share_of_the_stretch():
    from printapp.highlight_check import verdict
    from render.highlight import HighlightShape

    lobe = SlopeLobe(0.09, 0.015, math.radians(120.0))
    predicted = HighlightShape(90.0, 4.0, (10.0, 10.0), 100)
    ok, sentence, record = verdict(HighlightShape(105.0, 2.1, (10.0, 10.0), 90), predicted, lobe)
    assert ok and record["elongation_floor"] == pytest.approx(2.0)  # 1 + (4 - 1) / 3
    assert "105.0 deg" in sentence and "90.0 deg" in sentence and "120.0 deg on the tile" in sentence
    assert not verdict(HighlightShape(111.0, 3.0, (10.0, 10.0), 90), predicted, lobe)[0]  # 21 deg off
    assert not verdict(HighlightShape(90.0, 1.9, (10.0, 10.0), 90), predicted, lobe)[0]  # too round
    ok, sentence, _ = verdict(None, predicted, lobe)
    assert not ok and "no highlight" in sentence


def test_axis_difference():
    assert axis_difference_deg(5.0, 175.0) == pytest.approx(10.0)
    assert axis_difference_deg(0.0, 90.0) == pytest.approx(90.0)
    assert axis_difference_deg(100.0, 280.0) == pytest.approx(0.0)


# -- The check on a rendered tile ----------------------------------------------------------------


def _tile(stretch: float):
    from printapp.design import design_from_dict

    return design_from_dict(
        {
            "name": "small brushed tile",
            "base": {"width_mm": 12.0, "depth_mm": 8.0, "thickness_mm": 1.0},
            "texture": {
                "kind": "scn",
                "feature_size_mm": 1.5,
                "stretch": stretch,
                "angle_deg": 30.0,
                "seed": 3,
            },
            "relief": {"amplitude_um": 200},
            "printer": {"name": "prusa-sl1s-speed"},
            "material": {"refractive_index": 1.52, "body_albedo": [0.55, 0.58, 0.62]},
            "brdf": {"rays": 20_000, "seed": 1},
            "render": {"width_px": 256, "height_px": 192, "mode": "geometry", "seed": 1},
        }
    )


@pytest.fixture(scope="module")
def brushed():
    from printapp.relief import build_relief
    from printapp.rendering import highlight_frame, predict_for_design

    design = _tile(8.0)
    relief = build_relief(design)
    predicted = predict_for_design(design, relief.patch)
    frame = highlight_frame(design, relief, relief.mesh, predicted, relief.patch)
    # Same design, same seeds: the same frame, bit for bit.
    again = highlight_frame(design, relief, relief.mesh, predicted, relief.patch)
    assert frame is not None and np.array_equal(frame, again)
    return design, relief, predicted, frame


@pytest.mark.slow
def test_a_brushed_tile_shows_its_streak_where_the_lobe_says(brushed):
    from printapp.highlight_check import check_highlight, preview_light

    design, relief, predicted, frame = brushed
    assert predicted.metrics["highlight"]["anisotropy"] > 3.0
    # The preview's spot stands at the camera's mirror image.
    light = preview_light(design, predicted.metrics)
    assert light.highlight_azimuth_rad == pytest.approx(design.render.azimuth_rad + math.pi)
    assert light.highlight_elevation_rad == pytest.approx(design.render.elevation_rad)
    result = check_highlight(design, relief, relief.mesh, predicted.metrics, frame)
    assert result.applied and result.ok, result.sentence
    r = result.record
    assert r["angle_difference_deg"] <= 20.0 and r["measured_elongation"] >= r["elongation_floor"] > 1.5
    assert f"{r['measured_angle_deg']:.1f} deg" in result.sentence
    assert f"{r['predicted_angle_deg']:.1f} deg" in result.sentence
    unrendered = check_highlight(design, relief, relief.mesh, predicted.metrics, None)
    assert not unrendered.applied and "rendering is off" in unrendered.sentence


@pytest.mark.slow
def test_the_check_fails_when_the_predicted_direction_is_turned(brushed):
    from printapp.highlight_check import check_highlight, lobe_of

    design, relief, predicted, frame = brushed
    lobe = lobe_of(predicted.metrics)
    turned = SlopeLobe(lobe.alpha_long, lobe.alpha_short, lobe.azimuth_rad + math.pi / 2)
    result = check_highlight(design, relief, relief.mesh, predicted.metrics, frame, lobe=turned)
    assert result.applied and not result.ok
    assert result.record["angle_difference_deg"] > 20.0
    assert "more than 20" in result.sentence


def test_an_isotropic_tile_is_not_checked_and_keeps_the_studio_light():
    from printapp.highlight_check import check_highlight, preview_light
    from printapp.relief import build_relief
    from printapp.rendering import highlight_frame, predict_for_design
    from render.mitsuba_adapter import StudioLight

    design = _tile(1.0)
    relief = build_relief(design)
    predicted = predict_for_design(design, relief.patch)
    assert predicted.metrics["highlight"]["anisotropy"] < 3.0
    assert preview_light(design, predicted.metrics) == StudioLight()
    assert highlight_frame(design, relief, relief.mesh, predicted, relief.patch) is None
    result = check_highlight(design, relief, relief.mesh, predicted.metrics, None)
    assert not result.applied and result.ok
    assert "not checked" in result.sentence and "below 3" in result.sentence


def test_a_brdf_surface_s_azimuth_zero_is_the_world_x_on_every_triangle_of_the_top():
    # Without UVs Mitsuba takes each triangle's first edge as the tangent: the two triangles of a
    # 24 x 16 mm slab's top then disagree by atan(16 / 24) = 33.7 deg, and an anisotropic BRDF turns
    # with them (a seam along the diagonal, the highlight off its predicted direction).
    import mitsuba as mi

    from noise.heightfield import HeightField
    from printapp.mesh import slab_from_heightfield
    from render.mitsuba_adapter import choose_variant, resin_scene_dict
    from render.mitsuba_bsdfs import CompactSurface

    choose_variant()
    slab = slab_from_heightfield(HeightField(np.full((2, 2), 0.5), 24.0, 16.0, 0.0, 0.0), 1.5)
    surface = CompactSurface("beckmann", 0.2, 0.05, 0.5, 1.5, (0.5, 0.5, 0.5))
    scene_dict, _ = resin_scene_dict(
        np.asarray(slab.vertices),
        np.asarray(slab.faces),
        body_albedo=(0.5, 0.5, 0.5),
        refractive_index=1.5,
        width_px=16,
        height_px=16,
        surface=surface,
    )
    scene = mi.load_dict(scene_dict)
    for x, y in ((3.0, 12.0), (20.0, 3.0), (12.0, 8.1), (12.0, 7.9)):  # both triangles of the top
        si = scene.ray_intersect(mi.Ray3f(mi.Point3f(x, y, 10.0), mi.Vector3f(0.0, 0.0, -1.0)))
        assert np.array(si.sh_frame.s).ravel() == pytest.approx([1.0, 0.0, 0.0], abs=1e-6)
        assert np.array(si.sh_frame.n).ravel() == pytest.approx([0.0, 0.0, 1.0], abs=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["geometry", "model"])
def test_the_light_sweep_moves_the_lamps_of_one_loaded_scene(brushed, mode):
    """The sweep loads its scene once and moves the soft box between frames: each frame is the one
    a freshly loaded scene under that light gives (the same passes, seeds and denoiser guides)."""
    from printapp.rendering import light_sweep, render_preview, sweep_azimuths_rad
    from render.mitsuba_adapter import StudioLight

    design, relief, predicted, _ = brushed
    design = design.model_copy(update={"render": design.render.model_copy(update={"mode": mode})})
    strip = light_sweep(
        design, relief, relief.mesh, predicted, relief.patch, frames=3, width_px=48, height_px=36
    )
    small = design.model_copy(
        update={"render": design.render.model_copy(update={"width_px": 48, "height_px": 36, "spp": 8})}
    )
    for k, azimuth in enumerate(sweep_azimuths_rad(design.render.azimuth_rad, 3)):
        light = replace(StudioLight(), azimuth_rad=azimuth, highlight_radiance=0.0)
        fresh = render_preview(small, relief, relief.mesh, predicted, relief.patch, light=light, fixed_spp=8)
        np.testing.assert_allclose(strip[:, 48 * k : 48 * (k + 1)], fresh.image, rtol=0, atol=1e-5)
    assert strip.std() > 0.01  # the frames differ: the lamp moved
