"""The printed surface's three representations in Mitsuba: furnace, Fresnel, plugins against Mitsuba's own.

Renders are tiny and compared statistically (means over regions, with tolerances
above the Monte Carlo noise), never byte for byte.
"""

import math

import numpy as np
import pytest
import trimesh

from render.brdf_model import MicrofacetBRDF
from render.fresnel import fresnel_dielectric
from render.mitsuba_adapter import StudioLight, choose_variant, render_resin_mesh
from render.mitsuba_bsdfs import MIRROR_PROBABILITY, CompactSurface, TableSurface
from render.representation import Choice, body_tint, choose_representation, compact_surface, tolerance_for

UNIFORM = StudioLight(radiance=0.0, environment=1.0, highlight_radiance=0.0)  # a uniform white world


def render(
    mesh,
    surface=None,
    *,
    body=(0.0, 0.0, 0.0),
    spp=64,
    elevation_deg=40.0,
    size=(64, 48),
    light=UNIFORM,
    seed=0,
):
    choose_variant()
    return render_resin_mesh(
        np.asarray(mesh.vertices),
        np.asarray(mesh.faces),
        body_albedo=body,
        refractive_index=1.5,
        width_px=size[0],
        height_px=size[1],
        spp=spp,
        elevation_rad=math.radians(elevation_deg),
        light=light,
        surface=surface,
        seed=seed,
    )


def sphere():
    return trimesh.creation.icosphere(subdivisions=4, radius=5.0)


def object_mask(shape, frac=0.25):
    """The central part of the frame, where the framed sphere certainly is."""
    h, w = shape[:2]
    mask = np.zeros((h, w), dtype=bool)
    mask[int(h * (0.5 - frac)) : int(h * (0.5 + frac)), int(w * 0.5 - h * frac) : int(w * 0.5 + h * frac)] = (
        True
    )
    return mask


# --- The chooser ----------------------------------------------------------------------------


def test_chooser_takes_geometry_where_features_span_pixels_and_a_brdf_where_they_do_not():
    assert choose_representation(2.0, 0.05, 0.05).mode == "geometry"
    far = choose_representation(2.0, 20.0, 0.05)
    assert far.mode == "model" and "5.0%" in far.reason
    assert choose_representation(2.0, 20.0, 0.40).mode == "table"
    assert choose_representation(2.0, 20.0, math.nan).mode == "table"
    assert isinstance(far, Choice) and far.pixels_per_feature == pytest.approx(0.1)
    with pytest.raises(ValueError):
        choose_representation(0.0, 1.0, 0.1)


def test_the_model_stands_in_for_the_table_within_max_10_percent_and_three_times_the_noise():
    assert tolerance_for(0.01) == pytest.approx(0.10)  # a quiet table: 10 %
    assert tolerance_for(0.05) == pytest.approx(0.15)  # a noisy one: what its noise could make
    assert tolerance_for(math.nan) == pytest.approx(0.10)
    # 12 % misses a quiet table, not one whose own noise is 5 %.
    assert choose_representation(2.0, 20.0, 0.12, table_noise=0.01).mode == "table"
    near = choose_representation(2.0, 20.0, 0.12, table_noise=0.05)
    assert near.mode == "model" and "12.0%" in near.reason
    miss = choose_representation(2.0, 20.0, 0.16, table_noise=0.05)
    assert miss.mode == "table" and "15.0%" in miss.reason
    assert choose_representation(2.0, 20.0, 0.12, table_noise=0.01, model_tolerance=0.2).mode == "model"


def test_body_tint_turns_the_grey_trace_into_each_channel():
    tint = body_tint((0.8, 0.4, 0.1), 0.4, 1.5)
    assert tint[1] == pytest.approx(1.0)
    assert tint[0] > 2.0 > tint[1] > tint[2]  # 0.8 returns more than twice 0.4 (internal reflections)
    model = MicrofacetBRDF("ggx", 0.2, 0.1, 0.3, 0.4, 1.5)
    surface = compact_surface(model, (0.8, 0.4, 0.1), 0.4)
    assert surface.body_rgb == pytest.approx((0.8, 0.4, 0.1)) and surface.alpha_u == 0.2


# --- Closed forms -----------------------------------------------------------------------------


def test_furnace_white_resin_in_a_white_world_is_white():
    # Geometry's smooth plastic and the compact model, both with a white, non-absorbing body.
    plastic = render(sphere(), body=(1.0, 1.0, 1.0))
    compact = render(
        sphere(), CompactSurface("ggx", 0.05, 0.05, 0.0, 1.5, (1.0, 1.0, 1.0)), body=(1.0, 1.0, 1.0)
    )
    mask = object_mask(plastic.shape)
    assert plastic[mask].mean() == pytest.approx(1.0, abs=0.02)
    assert compact[mask].mean() == pytest.approx(1.0, abs=0.03)  # Smith single scattering loses a little


def test_flat_black_resin_reflects_fresnel_of_the_view_angle():
    plane = trimesh.creation.box(extents=(100.0, 100.0, 0.1))
    for elevation in (20.0, 50.0):
        image = render(plane, elevation_deg=elevation, spp=16, size=(48, 48))
        centre = image[20:28, 20:28].mean()
        expected = float(fresnel_dielectric(math.sin(math.radians(elevation)), 1.5))
        assert centre == pytest.approx(expected, rel=0.05)


# --- The table plugin against Mitsuba's own BSDFs --------------------------------------------


def tabulate(plugin: dict, n_ti=10, n_pi=12, n_to=45, n_po=90, theta_max_deg=85.0, sub=3) -> np.ndarray:
    """Bin averages of a Mitsuba BSDF over the table grid, from its own eval()."""
    import drjit as dr
    import mitsuba as mi

    from render.brdf_model import bin_directions

    choose_variant()
    bsdf = mi.load_dict(plugin)
    theta_i = np.radians(np.linspace(0.0, theta_max_deg, n_ti))
    phi_i = np.arange(n_pi) * 2 * math.pi / n_pi
    dirs = bin_directions(np.linspace(0, math.pi / 2, n_to + 1), np.linspace(0, 2 * math.pi, n_po + 1), sub)
    wo = dirs.reshape(-1, 3)
    out = np.empty((n_ti, n_pi, n_to, n_po))
    for a, t in enumerate(theta_i):
        for b, p in enumerate(phi_i):
            wi = np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])
            si = dr.zeros(mi.SurfaceInteraction3f, wo.shape[0])
            si.wi = mi.Vector3f(*[np.full(wo.shape[0], c, dtype=np.float32) for c in wi])
            si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
            value = bsdf.eval(
                mi.BSDFContext(), si, mi.Vector3f(*[wo[:, c].astype(np.float32) for c in range(3)])
            )
            f = np.asarray(value)[0] if np.asarray(value).ndim == 2 else np.asarray(value.x)
            f = f / np.maximum(wo[:, 2], 1e-9)
            out[a, b] = f.reshape(n_to, n_po, sub * sub).mean(axis=-1)
    return out


@pytest.mark.parametrize(
    ("plugin", "part"),
    [
        (
            {
                "type": "roughplastic",
                "distribution": "ggx",
                "alpha": 0.25,
                "int_ior": 1.5,
                "diffuse_reflectance": {"type": "rgb", "value": 0.0},
            },
            "specular",
        ),
        ({"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.6}}, "body"),
    ],
)
def test_table_of_an_analytic_brdf_renders_like_mitsubas_own_plugin(plugin, part):
    table = tabulate(plugin)
    zeros = np.zeros_like(table)
    spec, body = (table, zeros) if part == "specular" else (zeros, table)
    surface = TableSurface(spec, body, math.radians(85.0))
    light = StudioLight(radiance=12.0, environment=0.15)
    ours = render(sphere(), surface, spp=256, light=light)
    theirs = render(sphere(), plugin, spp=256, light=light)
    mask = object_mask(ours.shape)
    assert ours[mask].mean() == pytest.approx(theirs[mask].mean(), rel=0.05)
    # Region by region (4 x 4 blocks over the object), within noise and the bins' width.
    h, w = ours.shape[:2]
    block = lambda img: img[h // 4 : 3 * h // 4, w // 2 - h // 4 : w // 2 + h // 4].mean(axis=2)  # noqa: E731
    a, b = block(ours), block(theirs)
    blocks_a = a.reshape(4, a.shape[0] // 4, 4, -1).mean(axis=(1, 3))
    blocks_b = b.reshape(4, b.shape[0] // 4, 4, -1).mean(axis=(1, 3))
    assert np.all(np.abs(blocks_a - blocks_b) <= 0.15 * blocks_b + 0.01)


def test_compact_surface_renders_like_mitsubas_roughplastic_where_they_are_the_same_model():
    # Isotropic GGX with a black body: the compact model is Mitsuba's roughplastic up to the
    # masking term (height-correlated Smith here, separable there): within a few percent.
    light = StudioLight(radiance=12.0, environment=0.15)
    ours = render(sphere(), CompactSurface("ggx", 0.2, 0.2, 0.0, 1.5, (0.0, 0.0, 0.0)), spp=256, light=light)
    theirs = render(
        sphere(),
        {
            "type": "roughplastic",
            "distribution": "ggx",
            "alpha": 0.2,
            "int_ior": 1.5,
            "diffuse_reflectance": {"type": "rgb", "value": 0.0},
        },
        spp=256,
        light=light,
    )
    mask = object_mask(ours.shape)
    assert ours[mask].mean() == pytest.approx(theirs[mask].mean(), rel=0.05)


@pytest.mark.parametrize(
    ("params", "wi"),
    [
        ({"distribution": "ggx", "alpha_u": 0.3, "alpha_v": 0.1, "azimuth": 0.5}, (0.0, 0.0, 1.0)),
        (
            {
                "distribution": "beckmann",
                "alpha_u": 0.2,
                "alpha_v": 0.4,
                "azimuth": 1.0,
                "spike_weight": 0.5,
                "spike_alpha": 0.05,
            },
            (0.6, 0.2, math.sqrt(1 - 0.4)),
        ),
    ],
)
def test_compact_bsdf_samples_the_density_it_reports(params, wi):
    # Mitsuba's own chi-square test of a BSDF's sample() against its pdf().
    choose_variant()
    from mitsuba.chi2 import BSDFAdapter, ChiSquareTest, SphericalDomain

    from render.mitsuba_bsdfs import surface_bsdf

    surface_bsdf(CompactSurface("ggx", 0.1, 0.1, 0.0, 1.5, (0.5, 0.5, 0.5)))  # registers the plugin
    plugin = {
        "type": "printapp_compact",
        "ior": 1.5,
        "body": {"type": "rgb", "value": [0.5, 0.5, 0.5]},
        **params,
    }
    sample, pdf = BSDFAdapter("printapp_compact", plugin, wi=list(wi))
    test = ChiSquareTest(domain=SphericalDomain(), sample_func=sample, pdf_func=pdf, sample_dim=3, seed=3)
    assert test.run()


# --- The shading frame does not depend on the triangulation ----------------------------------


@pytest.mark.parametrize("kind", ["table", "compact"])
def test_the_brdf_is_the_same_on_both_triangles_of_a_flat_top(kind):
    # Mitsuba takes a triangle's tangent from its first edge: the two triangles of a tile's top
    # turned an azimuth-dependent BRDF differently, and table previews showed two halves split
    # along the diagonal. Just either side of the diagonal, with the same world directions, the
    # value, density and sample must agree (they differed by 30 % before, in eval_pdf too).
    import mitsuba as mi

    from render.mitsuba_adapter import mesh_object
    from render.mitsuba_bsdfs import surface_bsdf

    choose_variant()
    rng = np.random.default_rng(1)
    if kind == "table":
        shape = (4, 8, 9, 16)
        surface = TableSurface(rng.random(shape), rng.random(shape), math.radians(60.0))
    else:
        surface = CompactSurface("ggx", 0.3, 0.05, math.radians(25.0), 1.5, (0.5, 0.4, 0.3))
    bsdf = surface_bsdf(surface)
    corners = np.array([[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0]], float)
    scene = mi.load_dict(
        {"type": "scene", "top": mesh_object(corners, np.array([[0, 1, 2], [0, 2, 3]]), bsdf)}
    )
    eye = mi.Point3f(-8.0, 3.0, 9.0)
    wo_world = mi.Vector3f(0.6, -0.1, 0.79) / math.sqrt(0.36 + 0.01 + 0.79**2)
    seen = []
    for x, y in ((5.001, 4.999), (4.999, 5.001)):  # below and above the diagonal
        si = scene.ray_intersect(mi.Ray3f(eye, dr_normalize(mi.Point3f(x, y, 0.0) - eye)))
        value, pdf = bsdf.eval_pdf(mi.BSDFContext(), si, si.to_local(wo_world))
        bs, weight = bsdf.sample(mi.BSDFContext(), si, 0.7, mi.Point2f(0.2, 0.7))
        seen.append(
            [
                float(np.asarray(value).ravel()[0]),
                float(np.asarray(pdf).ravel()[0]),
                float(np.asarray(weight).ravel()[0]),
                *np.asarray(si.to_world(bs.wo)).ravel().tolist(),
            ]
        )
    assert seen[0] == pytest.approx(seen[1], rel=2e-3, abs=1e-4)


def dr_normalize(v):
    import drjit as dr

    return dr.normalize(v)


# --- Geometry's smooth resin: Mitsuba's plastic, sampled for its glints -----------------------


def _bsdf_samples(bsdf, cos_i, n, seed):
    import drjit as dr
    import mitsuba as mi

    rng = np.random.default_rng(seed)
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    si.wi = mi.Vector3f(math.sqrt(1.0 - cos_i * cos_i), 0.0, cos_i)
    bs, weight = bsdf.sample(
        mi.BSDFContext(), si, mi.Float(rng.random(n)), mi.Point2f(rng.random(n), rng.random(n))
    )
    mirror = np.array(mi.has_flag(bs.sampled_type, mi.BSDFFlags.DeltaReflection))
    return si, np.array(weight).T, mirror


@pytest.mark.parametrize("cos_i", [0.95, 0.6, 0.2])
def test_the_coated_resin_is_mitsubas_plastic_with_its_mirror_drawn_more_often(cos_i):
    # The same BSDF as Mitsuba's nonlinear plastic (an independent implementation): the same
    # value off the mirror, the same albedo and the same mirror reflectance (Fresnel), by Monte
    # Carlo over 400k samples of each; only how often the mirror is drawn differs.
    choose_variant()
    import mitsuba as mi

    from render.mitsuba_bsdfs import coated_resin_bsdf

    body = (0.25, 0.45, 0.75)
    plastic = mi.load_dict(
        {
            "type": "plastic",
            "int_ior": 1.5,
            "ext_ior": 1.0,
            "diffuse_reflectance": {"type": "rgb", "value": list(body)},
            "nonlinear": True,
        }
    )
    coated = coated_resin_bsdf(body, 1.5)
    n = 400_000
    si_p, w_p, mirror_p = _bsdf_samples(plastic, cos_i, n, seed=1)
    si_c, w_c, mirror_c = _bsdf_samples(coated, cos_i, n, seed=2)
    assert mirror_c.mean() == pytest.approx(MIRROR_PROBABILITY, abs=0.005)
    fresnel = float(fresnel_dielectric(cos_i, 1.5))
    for w, mirror in ((w_p, mirror_p), (w_c, mirror_c)):
        assert w[mirror, 1].sum() / n == pytest.approx(fresnel, rel=0.02)
    # Albedo per channel: Monte Carlo means agree within 4 standard errors.
    se = np.sqrt(w_p.var(axis=0) / n + w_c.var(axis=0) / n)
    assert np.all(np.abs(w_p.mean(axis=0) - w_c.mean(axis=0)) < 4 * se)
    # Off the mirror, the values agree (plastic's F_dr,int is a fitted polynomial: 0.1 %).
    wo = mi.Vector3f(-0.3, 0.2, math.sqrt(1 - 0.13))
    ctx = mi.BSDFContext()
    assert np.array(coated.eval(ctx, si_c, wo))[:, 0] == pytest.approx(
        np.array(plastic.eval(ctx, si_p, wo))[:, 0], rel=2e-3
    )

    # The mirror's share of the estimate varies far less: (1 - p) / p is 0.43 against plastic's
    # 11 at normal incidence, where plastic draws it 8 % of the time.
    def mirror_relative_variance(w, mirror):
        part = np.where(mirror, w[:, 1], 0.0)
        return part.var() / part.mean() ** 2

    p = MIRROR_PROBABILITY
    assert mirror_relative_variance(w_c, mirror_c) == pytest.approx((1 - p) / p, rel=0.05)
    if cos_i > 0.5:
        assert mirror_relative_variance(w_p, mirror_p) > 5.0


def test_a_faceted_part_renders_the_same_with_the_coated_resin_as_with_mitsubas_plastic():
    # The whole image, not just the BSDF: a faceted sphere under the studio light (soft box, spot,
    # environment), whose facets glint, rendered with Mitsuba's plastic and with printapp's
    # coated resin. Their means agree over the object and over its glints (the brightest
    # twentieth of its pixels) within the Monte Carlo noise of both, and the coated resin's
    # two seeds disagree less than plastic's: the variance the change was made for.
    choose_variant()
    faceted = trimesh.creation.icosphere(subdivisions=2, radius=5.0)
    plastic = {
        "type": "plastic",
        "int_ior": 1.5,
        "ext_ior": 1.0,
        "diffuse_reflectance": {"type": "rgb", "value": [0.3, 0.5, 0.7]},
        "nonlinear": True,
    }
    studio = StudioLight()
    kwargs = {"body": (0.3, 0.5, 0.7), "spp": 256, "size": (96, 72), "light": studio}

    def lum(image):
        return np.asarray(image, dtype=np.float64) @ np.array([0.2126, 0.7152, 0.0722])

    ours = [lum(render(faceted, **kwargs, seed=k)) for k in (1, 2)]
    theirs = [lum(render(faceted, plastic, **kwargs, seed=k)) for k in (1, 2)]
    mask = object_mask(ours[0].shape, frac=0.3)
    glints = mask & (0.5 * (ours[0] + ours[1]) >= np.quantile(0.5 * (ours[0] + ours[1])[mask], 0.95))
    for region in (mask, glints):
        a, b = (0.5 * (x[0] + x[1]) for x in (ours, theirs))
        assert a[region].mean() == pytest.approx(b[region].mean(), rel=0.03)
    spread = lambda pair: np.sqrt(np.mean((pair[0] - pair[1])[mask] ** 2))  # noqa: E731
    assert spread(ours) < 0.6 * spread(theirs)  # 0.41 measured: a sixth of the variance


def test_the_coated_resin_samples_the_density_it_reports_for_its_body():
    choose_variant()
    from mitsuba.chi2 import BSDFAdapter, ChiSquareTest, SphericalDomain

    from render.mitsuba_bsdfs import coated_resin_bsdf

    coated_resin_bsdf((0.5, 0.5, 0.5), 1.5)  # registers the plugin
    plugin = {"type": "printapp_coated", "ior": 1.5, "body": {"type": "rgb", "value": [0.5, 0.5, 0.5]}}
    # The chi-square test bins directions: its delta mirror is left out (the Monte Carlo test
    # above checks how often it is drawn and what it carries); the body alone is sampled.
    import mitsuba as mi

    body_only = mi.BSDFContext(mi.TransportMode.Radiance, mi.BSDFFlags.DiffuseReflection)
    sample, pdf = BSDFAdapter("printapp_coated", plugin, wi=[0.48, 0.0, 0.877], ctx=body_only)
    test = ChiSquareTest(domain=SphericalDomain(), sample_func=sample, pdf_func=pdf, sample_dim=3, seed=3)
    assert test.run()


def test_a_mesh_designs_brdf_preview_stands_on_its_base_not_on_its_refinement():
    # The representations render the smooth shape under the relief. For a mesh design that is
    # the closed mesh the relief was refined from: the same surface (the refinement splits
    # triangles in their planes) with the same shading frames (UV = (x, y) is affine on each
    # plane), so the same image, without the refinement's triangles, whose BVH every lamp move
    # of a light sweep rebuilt.
    from dataclasses import replace
    from pathlib import Path

    from printapp.design import design_from_dict
    from printapp.relief import build_relief
    from printapp.rendering import base_shape, predict_for_design, render_preview

    root = Path(__file__).resolve().parents[1]
    design = design_from_dict(
        {
            "base": {"shape": "mesh", "path": str(root / "examples" / "cylinder.stl"), "scale": 0.5},
            "texture": {"kind": "fbm", "feature_size_mm": 1.0, "octaves": 2},
            "relief": {"amplitude_um": 80},
            "brdf": {"rays": 2000},
            "render": {"width_px": 96, "height_px": 72, "mode": "model"},
        }
    )
    relief = build_relief(design)
    base, refined = base_shape(design, relief), relief.undisplaced
    assert len(base.faces) * 5 < len(refined.faces)
    assert base.is_watertight and base.volume == pytest.approx(refined.volume, rel=1e-9)
    assert base.area == pytest.approx(refined.area, rel=1e-9)
    predicted = predict_for_design(design, relief.patch)
    images = [
        render_preview(design, r, r.mesh, predicted, r.patch, fixed_spp=16)
        for r in (relief, replace(relief, base=None))
    ]
    assert [p.mode for p in images] == ["model", "model"]
    on_base, on_refined = (p.image for p in images)
    assert on_refined.mean() > 0.02
    assert np.abs(on_base - on_refined).mean() < 1e-4 * on_refined.mean()  # 5e-7 here
