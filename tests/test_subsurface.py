"""The BSSRDF of translucent tiles: diffusion in a box (render.diffusion) against a random walk in
a slab, the light entering a surface against closed forms, the glowing tile's energy balance
(render.subsurface)."""

import math

import numpy as np
import pytest

from printapp.bench.reference.slab_walk import slab_exit_radii
from render.diffusion import diffuse_box
from render.fresnel import diffuse_fresnel_reflectance, fresnel_dielectric
from render.subsurface import SceneLights, box_cells, resolves, subsurface_tile, transmitted_irradiance
from render.translucency import MediumRGB


@pytest.mark.parametrize(("albedo", "eta"), [(1.0, 1.3), (0.95, 1.4)])
def test_box_diffusion_against_a_random_walk_in_a_slab(albedo, eta):
    # sigma_t' = 1/mm, 3 mm thick, wide enough that the walls see nothing: a slab
    args = (albedo, 1.0 - albedo, 0.0, eta)
    photons = 40_000
    top, bottom = slab_exit_radii(photons, *args, thickness_mm=3.0, seed=4)
    h, n, nz = 0.5, 81, 6
    source = np.zeros((n, n))
    source[n // 2, n // 2] = 1.0
    out = diffuse_box((nz, n, n), h, *args, {"top": source})
    reflected = out.top.sum() * h * h
    # light that crosses without scattering leaves by the bottom, outside diffusion
    transmitted = out.bottom.sum() * h * h + math.exp(-3.0)
    walls = (out.x0.sum() + out.x1.sum() + out.y0.sum() + out.y1.sum()) * h * h
    # measured: 0.569 / 0.431 against the walk's 0.570 / 0.430; 0.356 / 0.263 against 0.349 / 0.261
    assert reflected == pytest.approx(top.size / photons, rel=0.04)
    assert transmitted == pytest.approx(bottom.size / photons, rel=0.04)
    assert walls < 1e-3
    # what goes in comes out or is absorbed (in the medium, or at the first interaction)
    first = (1.0 - albedo) * (1.0 - math.exp(-3.0))
    assert reflected + transmitted + walls + out.absorbed + first == pytest.approx(1.0, abs=1e-6)


def test_box_diffusion_is_symmetric_and_sends_light_to_the_walls_it_reaches():
    n, nz, h = 13, 4, 0.5
    source = np.zeros((n, n))
    source[n // 2, 1] = 1.0  # near the x0 wall, halfway along it
    out = diffuse_box((nz, n, n), h, 1.0, 0.0, 0.0, 1.5, {"top": source})
    assert out.x0.sum() > 5 * out.x1.sum()
    np.testing.assert_allclose(out.y0, out.y1, rtol=1e-6)  # the walls at y0 and y1 are mirror images
    np.testing.assert_allclose(out.x0, out.x0[:, ::-1], rtol=1e-6)
    with pytest.raises(ValueError, match="unknown face"):
        diffuse_box((2, 2, 2), 1.0, 1.0, 0.0, 0.0, 1.5, {"side": np.ones((2, 2))})


def test_transmitted_irradiance_against_closed_forms():
    # a 0.2 mm square 100 mm overhead, radiance 1e4: E = L A / d^2 (1 - F(1)) for a facing point
    lights = SceneLights(
        centres=np.array([[0.0, 0.0, 100.0]]),
        half_u=np.array([[0.1, 0.0, 0.0]]),
        half_v=np.array([[0.0, -0.1, 0.0]]),  # u x v = -z: it faces down, at the point
        radiance=np.array([[1e4, 1e4, 1e4]]),
        environment=np.zeros(3),
    )
    e = transmitted_irradiance(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), lights, 1.5)
    expected = 1e4 * 0.04 / 100.0**2 * (1.0 - float(fresnel_dielectric(1.0, 1.5)))
    np.testing.assert_allclose(e, expected, rtol=1e-4)
    # tilted by 60 degrees: cos 60 and the Fresnel transmittance at 60 degrees
    tilted = np.array([[math.sin(math.pi / 3), 0.0, 0.5]])
    e = transmitted_irradiance(np.zeros((1, 3)), tilted, lights, 1.5)
    expected = 1e4 * 0.04 / 100.0**2 * 0.5 * (1.0 - float(fresnel_dielectric(0.5, 1.5)))
    np.testing.assert_allclose(e, expected, rtol=1e-3)
    # a constant environment: pi L (1 - F_dr), whatever the orientation; a light behind gives nothing
    env = SceneLights(
        lights.centres, lights.half_u, lights.half_v, lights.radiance, np.array([0.2, 0.3, 0.4])
    )
    e = transmitted_irradiance(np.zeros((1, 3)), np.array([[0.0, 0.0, -1.0]]), env, 1.5)
    np.testing.assert_allclose(
        e[0], math.pi * np.array([0.2, 0.3, 0.4]) * (1 - diffuse_fresnel_reflectance(1.5))
    )


def test_glowing_tile_gives_back_what_enters_and_glows_where_lit():
    # a flat 6 x 6 x 2 mm tile of a resin that does not absorb, under the environment and a lamp
    # over its x1 side: what its faces emit is what entered, less what crossed without scattering
    medium = MediumRGB((2.0, 2.0, 2.0), (0.0, 0.0, 0.0), 0.0)
    lights = SceneLights(
        centres=np.array([[30.0, 3.0, 20.0]]),
        half_u=np.array([[0.0, 5.0, 0.0]]),
        half_v=np.array([[2.0, 0.0, -3.0]]),  # u x v points at the tile
        radiance=np.array([[10.0, 10.0, 10.0]]),
        environment=np.array([0.1, 0.1, 0.1]),
    )
    n = 61
    pitch = 6.0 / (n - 1)
    v, f, radiance = subsurface_tile(np.zeros((n, n)), pitch, pitch, 0.0, 0.0, 2.0, medium, 1.5, lights)
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    # outward-wound: the normals point away from the tile's centre
    assert np.all(np.einsum("ij,ij->i", normal, tri.mean(axis=1) - [3.0, 3.0, 1.0]) > 0)
    emitted = float(np.sum(area * np.pi * radiance[f][:, :, 1].mean(axis=1)))
    # entering: sample each face's transmitted irradiance finely
    entered = 0.0
    for centre, normal_f, size in [
        ((3, 3, 2), (0, 0, 1), (6, 6)),
        ((3, 3, 0), (0, 0, -1), (6, 6)),
        ((0, 3, 1), (-1, 0, 0), (6, 2)),
        ((6, 3, 1), (1, 0, 0), (6, 2)),
        ((3, 0, 1), (0, -1, 0), (6, 2)),
        ((3, 6, 1), (0, 1, 0), (6, 2)),
    ]:
        a, b = (np.arange(40) + 0.5) / 40 - 0.5, (np.arange(40) + 0.5) / 40 - 0.5
        aa, bb = (g.ravel() for g in np.meshgrid(a * size[0], b * size[1]))
        axes = [i for i in range(3) if normal_f[i] == 0]
        pts = np.tile(np.asarray(centre, dtype=float), (aa.size, 1))
        pts[:, axes[0]] += aa
        pts[:, axes[1]] += bb
        e = transmitted_irradiance(pts, np.tile(normal_f, (aa.size, 1)), lights, 1.5)[:, 1]
        entered += float(e.mean()) * size[0] * size[1]
    # less the unscattered light straight through the 2 mm (exp(-4) of the top's, at most 2 %)
    assert emitted == pytest.approx(entered, rel=0.04)
    # the wall facing the lamp glows more than the one away from it
    x1 = radiance[np.isclose(v[:, 0], 6.0) & (v[:, 2] < 1.9) & (v[:, 2] > 0.1)]
    x0 = radiance[np.isclose(v[:, 0], 0.0) & (v[:, 2] < 1.9) & (v[:, 2] > 0.1)]
    assert x1.mean() > 1.5 * x0.mean()
    # seen from straight above, the top's radiance carries the Fresnel transmittance at normal
    # exit over its hemispherical mean (the exit's shape for isotropic light inside)
    _, _, seen = subsurface_tile(
        np.zeros((n, n)), pitch, pitch, 0.0, 0.0, 2.0, medium, 1.5, lights, np.array([3.0, 3.0, 1e6])
    )
    top = slice(0, n * n)
    ratio = (1 - float(fresnel_dielectric(1.0, 1.5))) / (1 - diffuse_fresnel_reflectance(1.5))
    np.testing.assert_allclose(seen[top], radiance[top] * ratio, rtol=1e-6)


def test_box_cells_and_resolution():
    assert box_cells((3.0, 12.0, 12.0), 1.2) == (8, 32, 32)
    assert resolves((3.0, 12.0, 12.0), 1.2)
    # 0.04 mm in a 30 x 30 x 2 mm tile would need 10^8 cells
    assert not resolves((2.0, 30.0, 30.0), 0.04)
