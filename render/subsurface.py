"""A translucent relief tile rendered with a BSSRDF: the light it takes in, diffused, as a glow.

For media whose light wanders over a few pixels (render.translucency's chooser), path tracing
the medium is costly and noisy: light reaches it only through a smooth dielectric, which
next-event estimation cannot see through (the example tile was 19 % noisy after 60 s). Here,
as in texture-space diffusion (Borshukov & Lewis 2003; d'Eon, Luebke & Enderton 2007), the
light that enters the tile is computed on grids and spread by diffusion:

1. ``E_t``: the irradiance transmitted through the smooth interface, at each sample of the
   top's relief grid and at the centres of the walls' and bottom's cells, from the scene's own
   emitters (its rectangles, by a midpoint rule over their area, and its constant environment),
   each direction weighted by the Fresnel transmittance ``1 - F``
   (:func:`transmitted_irradiance`). The relief's shadows on itself are left out.
2. The diffusion equation with Jensen et al.'s boundary condition, solved in the tile's box
   (:func:`render.diffusion.diffuse_box`), the entering flux its source: the exitance through
   every face. The dipole and the slab's multipole (:mod:`render.bssrdf`) are this equation's
   solutions for a half-space and an infinite slab; the example tile (transport mean free path
   1.2-1.4 mm, 12 x 12 x 3 mm, no absorption) sends most of its light into its walls, where
   they say it goes on: with the multipole its top came out 20-45 % darker than the path-traced
   medium, with the box 0-10 %.
3. The tile is rendered as a black-bodied smooth resin (Mitsuba ``plastic``: its Fresnel
   reflection, as before) that emits the exitance, interpolated from its vertices, with the
   Fresnel transmittance towards the camera (:func:`subsurface_tile`). The camera then sees
   the subsurface light without Monte Carlo noise.

Approximations: diffusion leaves out single scattering and is poor within about a transport
mean free path of the entry point; the box is the tile's footprint at its mean thickness (the
relief changes the light that enters, not the distances it travels); the light inside is
taken as isotropic at the surface (the exit's angular shape is the Fresnel transmittance's
alone), baked for the preview's camera (its reflections in the surface see the same values);
the relief does not shadow itself. ``printapp bench
translucency`` measures the resulting error against the path-traced medium.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.interpolate import RegularGridInterpolator

from render.diffusion import diffuse_box
from render.fresnel import diffuse_fresnel_reflectance, fresnel_dielectric
from render.translucency import MediumRGB

LIGHT_SAMPLES = 12
"""Midpoint-rule samples along each side of a rectangular light (``LIGHT_SAMPLES**2`` in all)."""


@dataclass(frozen=True)
class SceneLights:
    """A scene's emitters, read from its Mitsuba dictionary: rectangles and a constant environment."""

    centres: np.ndarray
    """(k, 3) centres of the rectangles (mm)."""
    half_u: np.ndarray
    """(k, 3) half-edge vectors of the rectangles, first side."""
    half_v: np.ndarray
    """(k, 3) half-edge vectors, second side."""
    radiance: np.ndarray
    """(k, 3) linear-RGB radiance of each rectangle (towards its +z side)."""
    environment: np.ndarray
    """(3,) radiance of the constant environment."""


def eye_of(scene_dict: dict[str, Any]) -> np.ndarray:
    """The position of a scene dictionary's sensor (the origin of its ``to_world``)."""
    return np.array(scene_dict["sensor"]["to_world"].matrix, dtype=np.float64)[:3, 3]


def lights_of(scene_dict: dict[str, Any]) -> SceneLights:
    """The rectangular area lights and constant environment of a scene dictionary.

    A ``rectangle`` spans ``[-1, 1]^2`` of its ``to_world`` frame and emits towards local
    +z (Mitsuba's convention); other emitters are not read.
    """
    centres, us, vs, radiance = [], [], [], []
    environment = np.zeros(3)
    for value in scene_dict.values():
        if not isinstance(value, dict):
            continue
        if value.get("type") == "constant":
            environment = np.asarray(value["radiance"]["value"], dtype=np.float64)
        elif value.get("type") == "rectangle" and "emitter" in value:
            m = np.array(value["to_world"].matrix, dtype=np.float64)
            centres.append(m[:3, 3])
            us.append(m[:3, 0])
            vs.append(m[:3, 1])
            radiance.append(np.asarray(value["emitter"]["radiance"]["value"], dtype=np.float64))
    shape = (len(centres), 3)
    return SceneLights(
        np.reshape(centres, shape),
        np.reshape(us, shape),
        np.reshape(vs, shape),
        np.reshape(radiance, shape),
        environment,
    )


def transmitted_irradiance(
    points_mm: np.ndarray, normals: np.ndarray, lights: SceneLights, eta: float, samples: int = LIGHT_SAMPLES
) -> np.ndarray:
    """``E_t`` (linear RGB, per mm^2 as the radiance is): irradiance that crosses a smooth interface.

    ``E_t = sum over lights of integral L (1 - F(cos theta)) cos theta d omega`` at each point,
    ``F`` the unpolarised Fresnel reflectance into relative index ``eta``; rectangles by a
    ``samples`` x ``samples`` midpoint rule over their area (``dA cos theta_l / d^2``), the
    constant environment in closed form, ``pi L (1 - F_dr(eta))`` (the whole hemisphere sees it).
    No shadowing.

    Returns
    -------
    (n, 3) float64 array.
    """
    p = np.asarray(points_mm, dtype=np.float64).reshape(-1, 3)
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    env_t = math.pi * (1.0 - diffuse_fresnel_reflectance(eta))
    out = np.tile(lights.environment * env_t, (p.shape[0], 1))
    s = (np.arange(samples) + 0.5) / samples * 2.0 - 1.0
    su, sv = (a.ravel() for a in np.meshgrid(s, s))
    for c, u, v, rad in zip(lights.centres, lights.half_u, lights.half_v, lights.radiance, strict=True):
        normal_l = np.cross(u, v)
        area = 4.0 * float(np.linalg.norm(normal_l))
        normal_l = normal_l / np.linalg.norm(normal_l)
        total = np.zeros(p.shape[0])
        for a, b in zip(su, sv, strict=True):
            w = c + a * u + b * v - p
            dist2 = np.einsum("ij,ij->i", w, w)
            w = w / np.sqrt(dist2)[:, None]
            cos_p = np.clip(np.einsum("ij,ij->i", w, n), 0.0, 1.0)
            cos_l = np.clip(-(w @ normal_l), 0.0, None)
            total += cos_p * cos_l / dist2 * (1.0 - fresnel_dielectric(cos_p, eta))
        out += np.outer(total * area / (samples * samples), rad)
    return out


def _top_normals(heights: np.ndarray, px: float, py: float) -> np.ndarray:
    gy, gx = np.gradient(heights, py, px)
    n = np.stack([-gx, -gy, np.ones_like(heights)], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


MAX_CELLS = 150_000
"""Most cells of the diffusion grid (the solve takes about a second at this size on one core)."""


def box_cells(size_mm: tuple[float, float, float], transport_mfp_mm: float) -> tuple[int, int, int]:
    """Cells ``(nz, ny, nx)`` for a box of ``size_mm = (depth along z, y, x)``: sides of at most a
    third of the transport mean free path and an eighth of the thickness, at least two cells a
    side, at most :data:`MAX_CELLS` in all (coarser then)."""
    h = min(transport_mfp_mm / 3.0, size_mm[0] / 8.0)
    volume = size_mm[0] * size_mm[1] * size_mm[2]
    h = max(h, (volume / MAX_CELLS) ** (1.0 / 3.0))
    return tuple(max(2, round(s / h)) for s in size_mm)  # type: ignore[return-value]


COARSEST_CELL_OVER_MFP = 1.75
"""The coarsest diffusion cell, in transport mean free paths, at which the BSSRDF is rendered:
``printapp bench translucency`` measured 5.0 % error against the converged medium at 1.73
(cells of 0.142 mm for 0.082 mm) and 3.1 % at 0.52; coarser was not measured."""


def resolves(size_mm: tuple[float, float, float], transport_mfp_mm: float) -> bool:
    """Whether :func:`box_cells` can make cells of at most :data:`COARSEST_CELL_OVER_MFP`
    transport mean free paths for a box of ``size_mm``."""
    cells = box_cells(size_mm, transport_mfp_mm)
    return (
        max(s / c for s, c in zip(size_mm, cells, strict=True)) <= COARSEST_CELL_OVER_MFP * transport_mfp_mm
    )


def _cell_of(coords: np.ndarray, lo: float, length: float, cells: int) -> np.ndarray:
    """Indices of the cells (``cells`` equal parts of ``[lo, lo + length]``) that ``coords`` fall in."""
    k = np.floor((coords - lo) / length * cells).astype(np.int64)
    return np.clip(k, 0, cells - 1)


def _interpolate(
    values: np.ndarray, centres: tuple[np.ndarray, np.ndarray], points: tuple[np.ndarray, np.ndarray]
) -> np.ndarray:
    """Bilinear interpolation on cell centres, held constant beyond the outer centres."""
    c0, c1 = centres
    interp = RegularGridInterpolator((c0, c1), values, bounds_error=False, fill_value=None)
    p0 = np.clip(points[0], c0[0], c0[-1])
    p1 = np.clip(points[1], c1[0], c1[-1])
    return interp(np.column_stack([p0.ravel(), p1.ravel()])).reshape(p0.shape)


def subsurface_tile(
    heights_mm: np.ndarray,
    pitch_x_mm: float,
    pitch_y_mm: float,
    origin_x_mm: float,
    origin_y_mm: float,
    base_thickness_mm: float,
    medium: MediumRGB,
    eta: float,
    lights: SceneLights,
    eye_mm: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A tile's mesh with the radiance its body sends out at each vertex (module doc).

    With ``eye_mm`` (the camera's position) the radiance each vertex sends towards the camera
    carries the Fresnel transmittance of the way out: the light inside is nearly isotropic,
    so the radiance leaving at angle ``theta`` is proportional to ``1 - F(cos theta)``,
    normalised to the exitance, ``L = M (1 - F(cos theta)) / (pi (1 - F_dr))`` (by reciprocity
    ``F`` is the reflectance from outside at ``theta``); without it, Lambertian ``M / pi``.

    The top is the height field at ``base_thickness_mm + h`` on its grid, two triangles a
    cell; each wall and the bottom have vertices of their own (so that their radiance does
    not blend with the top's); the walls have a row of vertices per diffusion cell in z.
    Outward-wound.

    Returns
    -------
    vertices (n, 3) mm, faces (m, 3), radiance (n, 3) linear RGB (exitance / pi).
    """
    h = np.asarray(heights_mm, dtype=np.float64)
    ny, nx = h.shape
    x = origin_x_mm + np.arange(nx) * pitch_x_mm
    y = origin_y_mm + np.arange(ny) * pitch_y_mm
    xx, yy = np.meshgrid(x, y)
    z = h + base_thickness_mm
    width, depth, thick = x[-1] - x[0], y[-1] - y[0], float(z.mean())
    cz, cy, cx = box_cells((thick, depth, width), min(medium.transport_mfp_mm))
    hz, hy, hx = thick / cz, depth / cy, width / cx
    top_pts = np.stack([xx, yy, z], axis=-1).reshape(-1, 3)
    top_normals = _top_normals(h, pitch_x_mm, pitch_y_mm).reshape(-1, 3)
    e_top = transmitted_irradiance(top_pts, top_normals, lights, eta)
    # the flux entering each top cell: each grid sample stands for pitch_x * pitch_y (less at the borders)
    weight = np.ones((ny, nx))
    weight[[0, -1], :] *= 0.5
    weight[:, [0, -1]] *= 0.5
    weight = (weight * pitch_x_mm * pitch_y_mm).ravel()
    ky = _cell_of(yy.ravel(), y[0], depth, cy)  # type: ignore[arg-type]
    kx = _cell_of(xx.ravel(), x[0], width, cx)  # type: ignore[arg-type]
    flat = ky * cx + kx
    centres_x = x[0] + (np.arange(cx) + 0.5) * hx
    centres_y = y[0] + (np.arange(cy) + 0.5) * hy
    centres_z = (np.arange(cz) + 0.5) * hz
    gy, gx = np.meshgrid(centres_y, centres_x, indexing="ij")
    gz_y, gx_y = np.meshgrid(centres_z, centres_x, indexing="ij")
    gz_x, gy_x = np.meshgrid(centres_z, centres_y, indexing="ij")
    face_points = {
        "bottom": (np.stack([gx, gy, np.zeros_like(gx)], -1), (0.0, 0.0, -1.0), hx * hy),
        "y0": (np.stack([gx_y, np.full_like(gx_y, y[0]), gz_y], -1), (0.0, -1.0, 0.0), hx * hz),
        "y1": (np.stack([gx_y, np.full_like(gx_y, y[-1]), gz_y], -1), (0.0, 1.0, 0.0), hx * hz),
        "x0": (np.stack([np.full_like(gy_x, x[0]), gy_x, gz_x], -1), (-1.0, 0.0, 0.0), hy * hz),
        "x1": (np.stack([np.full_like(gy_x, x[-1]), gy_x, gz_x], -1), (1.0, 0.0, 0.0), hy * hz),
    }
    entering_rgb = {}
    for name, (pts, normal, cell_area) in face_points.items():
        flat_pts = pts.reshape(-1, 3)
        e = transmitted_irradiance(flat_pts, np.tile(normal, (flat_pts.shape[0], 1)), lights, eta)
        entering_rgb[name] = e.reshape(*pts.shape[:2], 3) * cell_area
    exits = []
    for ch in range(3):
        top_flux = np.bincount(flat, weights=e_top[:, ch] * weight, minlength=cy * cx).reshape(cy, cx)
        entering = {name: v[..., ch] for name, v in entering_rgb.items()} | {"top": top_flux}
        exits.append(
            diffuse_box(
                (cz, cy, cx),
                (hz, hy, hx),
                medium.sigma_s_per_mm[ch],
                medium.sigma_a_per_mm[ch],
                medium.g,
                eta,
                entering,
            )
        )

    def channels(name: str) -> np.ndarray:
        return np.stack([getattr(e, name) for e in exits], axis=-1)

    idx = np.arange(ny * nx).reshape(ny, nx)
    v00, v10, v01, v11 = (
        idx[:-1, :-1].ravel(),
        idx[:-1, 1:].ravel(),
        idx[1:, :-1].ravel(),
        idx[1:, 1:].ravel(),
    )
    verts = [top_pts]
    faces = [np.concatenate([np.column_stack([v00, v10, v11]), np.column_stack([v00, v11, v01])])]
    top_exit = channels("top")
    normals = [top_normals]
    radiance = [
        np.stack(
            [_interpolate(top_exit[..., c], (centres_y, centres_x), (yy, xx)) for c in range(3)], -1
        ).reshape(-1, 3)
    ]
    count = top_pts.shape[0]
    rows = np.linspace(0.0, 1.0, cz + 1)  # the walls' vertex rows, as fractions of the height
    walls = (
        ("y0", x, np.full(nx, y[0]), z[0, :], centres_x, False),
        ("y1", x, np.full(nx, y[-1]), z[-1, :], centres_x, True),
        ("x0", np.full(ny, x[0]), y, z[:, 0], centres_y, True),
        ("x1", np.full(ny, x[-1]), y, z[:, -1], centres_y, False),
    )
    for name, wx, wy, zt, centres_along, flip in walls:
        m = zt.size
        along = wx if name.startswith("y") else wy
        zz = rows[:, None] * zt[None, :]  # (cz + 1, m)
        pts = np.stack([np.broadcast_to(wx, zz.shape), np.broadcast_to(wy, zz.shape), zz], -1).reshape(-1, 3)
        exit_w = channels(name)  # (cz, n_along, 3)
        aa = np.broadcast_to(along, zz.shape)
        values = np.stack(
            [_interpolate(exit_w[..., c], (centres_z, centres_along), (zz, aa)) for c in range(3)], -1
        )
        grid = count + np.arange((cz + 1) * m).reshape(cz + 1, m)
        a, b = grid[:-1, :-1].ravel(), grid[:-1, 1:].ravel()
        a_up, b_up = grid[1:, :-1].ravel(), grid[1:, 1:].ravel()
        quad = [np.column_stack([a, b, b_up]), np.column_stack([a, b_up, a_up])]
        if flip:
            quad = [f[:, ::-1] for f in quad]
        verts.append(pts)
        faces += quad
        radiance.append(values.reshape(-1, 3))
        normals.append(np.tile(face_points[name][1], (pts.shape[0], 1)))
        count += pts.shape[0]
    lo_x, hi_x, lo_y, hi_y = x[0], x[-1], y[0], y[-1]
    verts.append(np.array([[lo_x, lo_y, 0.0], [hi_x, lo_y, 0.0], [hi_x, hi_y, 0.0], [lo_x, hi_y, 0.0]]))
    faces.append(np.array([[count, count + 2, count + 1], [count, count + 3, count + 2]]))
    radiance.append(np.tile(channels("bottom").mean(axis=(0, 1)), (4, 1)))
    normals.append(np.tile([0.0, 0.0, -1.0], (4, 1)))
    vertices = np.concatenate(verts)
    out = np.concatenate(radiance) / math.pi
    if eye_mm is not None:
        n = np.concatenate(normals)
        view = np.asarray(eye_mm, dtype=np.float64)[None, :] - vertices
        cos = np.clip(np.einsum("ij,ij->i", n, view) / np.linalg.norm(view, axis=1), 0.0, 1.0)
        out *= ((1.0 - fresnel_dielectric(cos, eta)) / (1.0 - diffuse_fresnel_reflectance(eta)))[:, None]
    return vertices, np.concatenate(faces).astype(np.int64), out
