"""Slow reference: the first hit of a ray with a triangle mesh, by testing every triangle in float64.

Moller & Trumbore (1997), "Fast, minimum storage ray-triangle intersection", written
from the paper in plain numpy, independent of the height-field tracer and of Embree.
Edges count as inside, so a ray through a shared edge hits (one of) its triangles.
"""

import numpy as np


def first_hits(
    vertices: np.ndarray, faces: np.ndarray, origins: np.ndarray, dirs: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Distance ``t > 0`` to the nearest triangle (inf if none) and its index (-1 if none), per ray."""
    v0 = vertices[faces[:, 0]].astype(np.float64)
    e1 = vertices[faces[:, 1]] - v0
    e2 = vertices[faces[:, 2]] - v0
    t_best = np.full(origins.shape[0], np.inf)
    index = np.full(origins.shape[0], -1, dtype=np.int64)
    for k in range(origins.shape[0]):
        d = dirs[k]
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        ok = det != 0.0
        inv = np.zeros_like(det)
        inv[ok] = 1.0 / det[ok]
        s = origins[k] - v0
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = (q @ d) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
        hit = ok & (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0) & (t > 0.0)
        if np.any(hit):
            j = int(np.flatnonzero(hit)[np.argmin(t[hit])])
            t_best[k], index[k] = t[j], j
    return t_best, index
