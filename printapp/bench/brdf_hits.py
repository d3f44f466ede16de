"""First hits of the gonioreflectometer's own primary rays: by its tracer, by Embree, by Mitsuba 3.

For ``printapp bench brdf``: the estimator's primary rays regenerated bit for bit
(:func:`primary_rays`), the tracer's surface as a triangle mesh with a ring of periodic
copies (:func:`periodic_mesh`, :func:`face_cells`), the numba tracer's first-hit query
alone (:class:`TracerFirstHit`), and the optional peers over that mesh (:class:`Peers`),
with how often they agree with the tracer (:func:`hit_agreement`).
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from numba import njit, prange

from noise.hashing import mix64, seed_key
from render.gonio import first_hit, max_mipmap, primary_origin
from render.gonio import lit_window as gonio_lit_window


def lit_window(heights: np.ndarray, px: float, py: float, wis: np.ndarray, periodic: bool) -> np.ndarray:
    """First cell and extent (cells) of the estimator's lit window per direction, x then y.

    :func:`render.gonio.lit_window`, the estimator's own rule.
    """
    return gonio_lit_window(heights - heights.mean(), px, py, wis, periodic)


@njit(cache=True, parallel=True)
def _primary_origins(wis, starts, counts, window, px, py, zmax, period_x, period_y, key, out):
    # Keyed exactly as render.gonio.estimate_brdf keys its rays, and placed by its own
    # function, so that the origins are bit for bit the estimator's.
    for d_idx in range(wis.shape[0]):
        wix, wiy, wiz = wis[d_idx, 0], wis[d_idx, 1], wis[d_idx, 2]
        for k in prange(counts[d_idx]):
            ray_key = mix64(key ^ (np.uint64(d_idx) << np.uint64(40)) ^ np.uint64(k))
            x0, y0 = primary_origin(ray_key, window, d_idx, px, py, wix, wiy, wiz, zmax, period_x, period_y)
            row = starts[d_idx] + k
            out[row, 0] = x0
            out[row, 1] = y0
            out[row, 2] = zmax


def primary_rays(
    heights: np.ndarray,
    px: float,
    py: float,
    wi: np.ndarray,
    rays: int,
    *,
    seed: int = 0,
    periodic: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """The estimator's primary rays: origins (n, 3) at z = zmax and directions ``-wi`` (n, 3), float64.

    Coordinates are the tracer's: x along columns, y along rows, heights relative to their
    mean; rays are ordered by direction, then by index.
    """
    wis = np.atleast_2d(np.asarray(wi, dtype=np.float64))
    wis = wis / np.linalg.norm(wis, axis=1, keepdims=True)
    h = heights - heights.mean()
    ny, nx = h.shape
    counts = np.full(wis.shape[0], int(rays), dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    origins = np.empty((int(counts.sum()), 3))
    _primary_origins(
        wis,
        starts,
        counts,
        lit_window(heights, px, py, wis, periodic),
        float(px),
        float(py),
        float(h.max()),
        nx * float(px),
        ny * float(py),
        seed_key(seed),
        origins,
    )
    return origins, np.repeat(-wis, counts, axis=0)


def mesh_margin_cells(heights: np.ndarray, pitch_mm: float, max_theta_deg: float) -> int:
    """Cells of periodic copies around the tile that hold every first hit of rays up to ``max_theta_deg``."""
    h = heights - heights.mean()
    travel = float(h.max() - h.min()) * math.tan(math.radians(max_theta_deg))
    return int(math.ceil(travel / pitch_mm)) + 2


def periodic_mesh(
    heights: np.ndarray, px: float, py: float, margin_x: int, margin_y: int
) -> tuple[np.ndarray, np.ndarray]:
    """The tracer's surface as a triangle mesh: vertices (float64, mm) and faces (int32).

    Cells ``-margin .. n + margin - 1`` in each direction, heights wrapped (relative to
    their mean, as the tracer holds them). Each cell is four triangles around a centre
    vertex at the mean of its corners, as the tracer cuts it; face ``k`` of ``C`` cells
    (row-major over the extended grid) is triangle ``k // C`` (0 bottom (v00, v10, c),
    1 right (v10, v11, c), 2 top (v11, v01, c), 3 left (v01, v00, c)) of cell ``k % C``.
    All face up. See :func:`face_cells`.
    """
    h = heights - heights.mean()
    ny, nx = h.shape
    cols = np.arange(-margin_x, nx + margin_x + 1)
    rows = np.arange(-margin_y, ny + margin_y + 1)
    z = h[np.ix_(rows % ny, cols % nx)]
    xx, yy = np.meshgrid(cols * float(px), rows * float(py))
    corners = np.column_stack([xx.ravel(), yy.ravel(), z.ravel()])
    # Centres, computed as the tracer computes them (the same sums in the same order).
    zc = 0.25 * ((z[:-1, :-1] + z[1:, 1:]) + (z[:-1, 1:] + z[1:, :-1]))
    centres = np.column_stack(
        [
            (0.5 * (xx[:-1, :-1] + xx[:-1, 1:])).ravel(),
            (0.5 * (yy[:-1, :-1] + yy[1:, :-1])).ravel(),
            zc.ravel(),
        ]
    )
    vertices = np.vstack([corners, centres])
    vx = cols.size
    r, c = np.meshgrid(np.arange(rows.size - 1), np.arange(vx - 1), indexing="ij")
    v00 = (r * vx + c).ravel()
    v10, v01 = v00 + 1, v00 + vx
    v11 = v01 + 1
    vc = corners.shape[0] + (r * (vx - 1) + c).ravel()
    faces = np.concatenate(
        [
            np.column_stack([v00, v10, vc]),
            np.column_stack([v10, v11, vc]),
            np.column_stack([v11, v01, vc]),
            np.column_stack([v01, v00, vc]),
        ]
    )
    return vertices, faces.astype(np.int32)


def face_cells(
    prim: np.ndarray, shape: tuple[int, int], margin_x: int, margin_y: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unwrapped cell (ci along x, cj along y) and triangle (0 bottom, 1 right, 2 top, 3 left) of faces."""
    ny, nx = shape
    width = nx + 2 * margin_x
    n_cells = (ny + 2 * margin_y) * width
    prim = np.asarray(prim, dtype=np.int64)
    tri = prim // n_cells
    cell = prim - tri * n_cells
    return cell % width - margin_x, cell // width - margin_y, tri


@njit(cache=True, parallel=True)
def _first_hits(h, px, py, mip, mip_off, mip_nx, n_levels, zmax, zmin, origins, dirs, t_out, cell_out):
    for k in prange(origins.shape[0]):
        status, t, _nx, _ny, _nz, ci, cj, tri, steps = first_hit(
            h,
            px,
            py,
            mip,
            mip_off,
            mip_nx,
            n_levels,
            zmax,
            zmin,
            origins[k, 0],
            origins[k, 1],
            origins[k, 2],
            dirs[k, 0],
            dirs[k, 1],
            dirs[k, 2],
        )
        t_out[k] = t if status == 1 else np.inf
        cell_out[k, 0] = ci
        cell_out[k, 1] = cj
        cell_out[k, 2] = tri if status == 1 else -1
        cell_out[k, 3] = steps


class TracerFirstHit:
    """The numba height-field tracer's first-hit query alone (no Fresnel, no bounces, no bins)."""

    def __init__(self, heights: np.ndarray, px: float, py: float) -> None:
        self.h = np.ascontiguousarray(heights - heights.mean())
        self.px, self.py = float(px), float(py)
        self.mip = max_mipmap(self.h)
        self.zmax, self.zmin = float(self.h.max()), float(self.h.min())

    def __call__(self, origins: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distances (inf where none) and (ci, cj, tri, steps) per ray."""
        t = np.empty(origins.shape[0])
        cells = np.empty((origins.shape[0], 4), dtype=np.int64)
        mip, off, lnx, n_levels = self.mip
        _first_hits(
            self.h, self.px, self.py, mip, off, lnx, n_levels, self.zmax, self.zmin, origins, dirs, t, cells
        )
        return t, cells


class Peers:
    """embreex and Mitsuba 3 first-hit queries over one mesh, each optional.

    Parameters
    ----------
    vertices : ndarray of float64, shape (n, 3)
        Mesh vertices (mm), as :func:`periodic_mesh` builds them.
    faces : ndarray of int32, shape (m, 3)
        Triangles.
    notes : list of str
        Where to say which peer is missing, and why.

    Attributes
    ----------
    embree, mitsuba : object or None
        The Embree and Mitsuba scenes, ``None`` where that peer is not usable here;
        ``embree_build_s`` and ``mitsuba_build_s`` are their build times (s).
    variant : str or None
        The Mitsuba variant in use.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, notes: list[str]) -> None:
        self.embree = None
        self.mitsuba = None
        self.variant = None
        try:
            from embreex import rtcore_scene
            from embreex.mesh_construction import TriangleMesh
        except ImportError:
            notes.append("embreex is not installed (pip install embreex): no Embree peer in this run")
        else:
            start = time.perf_counter()
            scene = rtcore_scene.EmbreeScene()
            TriangleMesh(scene, np.ascontiguousarray(vertices, dtype=np.float32), faces)
            # The BVH is built on the first query (rtcCommit): count it in the build time.
            scene.run(np.zeros((1, 3), np.float32), np.array([[0, 0, -1]], np.float32), output=1)
            self.embree_build_s = time.perf_counter() - start
            self.embree = scene
        try:
            from render.mitsuba_adapter import choose_variant, mesh_object

            choice = choose_variant()
            if choice.variant == "scalar_rgb":
                notes.append(f"Mitsuba runs only scalar_rgb here ({choice.warning}): no Mitsuba peer")
                return
            import drjit as dr
            import mitsuba as mi
        except Exception as exc:  # an optional peer: any failure to load it only drops it
            notes.append(f"Mitsuba 3 is not usable here ({exc}): no Mitsuba peer in this run")
            return
        start = time.perf_counter()
        mesh = mesh_object(vertices, faces, mi.load_dict({"type": "diffuse"}))
        self.mitsuba = mi.load_dict({"type": "scene", "relief": mesh})
        self.mitsuba_build_s = time.perf_counter() - start
        self.variant = choice.variant
        self.mi, self.dr = mi, dr

    def embree_hits(self, o32: np.ndarray, d32: np.ndarray) -> dict[str, np.ndarray]:
        """Embree's first hits of float32 rays: ``tfar`` (mm, inf if none) and ``primID`` (-1 if none)."""
        return self.embree.run(o32, d32, output=1)

    def mitsuba_ray(self, origins: np.ndarray, dirs: np.ndarray) -> Any:
        """The rays (origins in mm, unit directions) as one evaluated ``mitsuba.Ray3f``, built untimed."""
        mi, dr = self.mi, self.dr
        o = origins.astype(np.float32)
        d = dirs.astype(np.float32)
        ray = mi.Ray3f(mi.Point3f(o[:, 0], o[:, 1], o[:, 2]), mi.Vector3f(d[:, 0], d[:, 1], d[:, 2]))
        dr.eval(ray)
        dr.sync_thread()
        return ray

    def mitsuba_hits(self, ray: Any) -> Any:
        """Mitsuba's first hits of :meth:`mitsuba_ray`'s rays: the evaluated ``SurfaceInteraction3f``."""
        si = self.mitsuba.ray_intersect(ray)
        self.dr.eval(si.t, si.prim_index, si.n)
        self.dr.sync_thread()
        return si


def hit_agreement(
    t_ref: np.ndarray,
    cells_ref: np.ndarray,
    t: np.ndarray,
    prim: np.ndarray,
    shape: tuple[int, int],
    mx: int,
    my: int,
) -> tuple[float, float]:
    """Fraction of rays whose peer hit is the tracer's triangle, and the median relative |dt|.

    Parameters
    ----------
    t_ref, cells_ref : ndarray
        The tracer's distances (mm, inf if none) and ``(ci, cj, tri, steps)`` per ray
        (:class:`TracerFirstHit`).
    t, prim : ndarray
        The peer's distances (mm) and face indices (-1 if none) for the same rays.
    shape : tuple of int
        The tile's ``(ny, nx)``.
    mx, my : int
        The mesh's ring of periodic cells along x and y (:func:`periodic_mesh`).

    Returns
    -------
    same : float
        Fraction of rays whose peer hit is the tracer's (cell, triangle).
    median_rel_dt : float
        Median of ``|t - t_ref| / t_ref`` where both hit (nan if none).
    """
    ci, cj, tri = face_cells(prim, shape, mx, my)
    valid = prim >= 0
    same = valid & (ci == cells_ref[:, 0]) & (cj == cells_ref[:, 1]) & (tri == cells_ref[:, 2])
    both = valid & np.isfinite(t_ref)
    rel = np.abs(t[both].astype(np.float64) - t_ref[both]) / t_ref[both]
    return float(np.mean(same)), float(np.median(rel)) if rel.size else math.nan
