"""Cellular noise: distances to the nearest and second-nearest feature points (Worley 1996).

S. Worley, "A cellular texture basis function", SIGGRAPH 1996: feature points are
scattered over the plane, and ``F1(p)``, ``F2(p)`` are the distances from ``p`` to the
nearest and second-nearest of them. ``F2 - F1`` is zero on the edges of the Voronoi
cells and grows towards their centres: a network of thin, straight-sided cracks with
Y-junctions, which is what crazed marble and dried mud look like.

Here each unit cell of the integer lattice holds one feature point (Worley draws a
Poisson number per cell; one point per cell is the common simplification, as in
Gustavson's and Quílez's versions), placed at ``cell + 1/2 + jitter (u - 1/2)`` with
``u`` two uniform numbers from the project's counter-based hash of the cell
(:mod:`noise.hashing`), so any point is evaluated independently of the others. The
search is exact: rings of cells around the point's cell are visited until no farther
ring can hold a point closer than the current second-nearest.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from noise.hashing import hash_cell, seed_key, stream_uniform


@njit(cache=True, inline="always")
def _feature(key: np.uint64, i: np.int64, j: np.int64, jitter: float) -> tuple[float, float]:
    h = hash_cell(key, i, j, np.int64(0))
    u = stream_uniform(h, np.uint64(0))
    v = stream_uniform(h, np.uint64(1))
    return i + 0.5 + jitter * (u - 0.5), j + 0.5 + jitter * (v - 0.5)


@njit(cache=True, nogil=True)
def _fill_block(key: np.uint64, ci: np.int64, cj: np.int64, jitter: float, block: np.ndarray) -> None:
    """Feature points of the 5 x 5 cells around (ci, cj): block[di + 2, dj + 2] = (x, y)."""
    for di in range(-2, 3):
        for dj in range(-2, 3):
            fx, fy = _feature(key, ci + di, cj + dj, jitter)
            block[di + 2, dj + 2, 0] = fx
            block[di + 2, dj + 2, 1] = fy


@njit(cache=True, nogil=True, inline="always")
def _nearer(d: float, d1: float, d2: float) -> tuple[float, float]:
    if d < d1:
        return d, d1
    if d < d2:
        return d1, d
    return d1, d2


@njit(cache=True, nogil=True)
def _f1_f2_point(
    x: float, y: float, ci: np.int64, cj: np.int64, key: np.uint64, jitter: float, block: np.ndarray
) -> tuple[float, float]:
    d1, d2 = np.inf, np.inf
    # Rings 0 and 1 (the 3 x 3 cells), then ring 2, from the cached block.
    for a in range(1, 4):
        for b in range(1, 4):
            dx = block[a, b, 0] - x
            dy = block[a, b, 1] - y
            d1, d2 = _nearer(dx * dx + dy * dy, d1, d2)
    # A cell of ring r + 1 is r whole cells away along some axis, and its point keeps
    # (1 - jitter) / 2 from the cell's sides: no unvisited point is nearer than this.
    margin = 0.5 * (1.0 - jitter)
    if d2 <= (1.0 + margin) ** 2:
        return math.sqrt(d1), math.sqrt(d2)
    for a in range(5):
        for b in range(5):
            if 1 <= a <= 3 and 1 <= b <= 3:
                continue
            dx = block[a, b, 0] - x
            dy = block[a, b, 1] - y
            d1, d2 = _nearer(dx * dx + dy * dy, d1, d2)
    ring = 2
    while d2 > (ring + margin) ** 2:
        ring += 1
        for di in range(-ring, ring + 1):
            for dj in range(-ring, ring + 1):
                if max(abs(di), abs(dj)) != ring:
                    continue
                fx, fy = _feature(key, ci + di, cj + dj, jitter)
                d1, d2 = _nearer((fx - x) * (fx - x) + (fy - y) * (fy - y), d1, d2)
    return math.sqrt(d1), math.sqrt(d2)


@njit(cache=True, nogil=True)
def _cellular_kernel(
    points: np.ndarray, key: np.uint64, jitter: float, f1: np.ndarray, f2: np.ndarray
) -> None:
    # Points in a row often share a cell: its 5 x 5 neighbourhood of feature points is
    # computed once and kept until the cell changes (the result is the same either way).
    block = np.empty((5, 5, 2))
    have_i = np.int64(0)
    have_j = np.int64(0)
    valid = False
    for k in range(points.shape[0]):
        x, y = points[k, 0], points[k, 1]
        ci, cj = np.int64(math.floor(x)), np.int64(math.floor(y))
        if not valid or ci != have_i or cj != have_j:
            _fill_block(key, ci, cj, jitter, block)
            have_i, have_j, valid = ci, cj, True
        f1[k], f2[k] = _f1_f2_point(x, y, ci, cj, key, jitter, block)


def cellular(points: np.ndarray, *, seed: int = 0, jitter: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Worley's ``F1`` and ``F2`` at points in the plane (one feature point per unit cell).

    Parameters
    ----------
    points : (n, 2) float array
        Positions in noise units (one lattice cell, and on average one feature point, per unit).
    seed : int
        Seed of the feature points (the cell hash of :mod:`noise.hashing`).
    jitter : float
        In [0, 1]: how far a feature point may stray from its cell's centre, as a
        fraction of the cell (1: anywhere in the cell; 0: a square lattice).

    Returns
    -------
    f1, f2 : (n,) float64 arrays
        Distances (noise units) to the nearest and the second-nearest feature point;
        ``f2 - f1`` is 0 on the Voronoi edges (Worley 1996, eq. 1 and fig. 3).
    """
    pts = np.ascontiguousarray(np.asarray(points, dtype=np.float64))
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points: expected an (n, 2) array, got shape {pts.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points: expected finite coordinates, found NaN or infinity")
    if not (isinstance(seed, (int, np.integer)) and not isinstance(seed, bool)):
        raise ValueError(f"seed: expected an integer, got {seed!r}")
    if not (math.isfinite(jitter) and 0.0 <= jitter <= 1.0):
        raise ValueError(f"jitter: expected a number in [0, 1], got {jitter!r}")
    f1 = np.empty(pts.shape[0])
    f2 = np.empty(pts.shape[0])
    if pts.shape[0]:
        _cellular_kernel(pts, seed_key(int(seed)), float(jitter), f1, f2)
    return f1, f2


def feature_points(i0: int, i1: int, j0: int, j1: int, *, seed: int = 0, jitter: float = 1.0) -> np.ndarray:
    """The feature points of the cells ``i0 <= i < i1``, ``j0 <= j < j1``, shaped (cells, 2).

    For references and tests: the same points :func:`cellular` measures distances to.
    """
    key = seed_key(int(seed))
    out = [
        _feature(key, np.int64(i), np.int64(j), float(jitter)) for i in range(i0, i1) for j in range(j0, j1)
    ]
    return np.array(out, dtype=np.float64).reshape(-1, 2)
