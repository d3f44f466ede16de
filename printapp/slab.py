"""A closed slab from a height field: the printable solid of a relief tile (no trimesh needed)."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from noise.heightfield import HeightField


def _boundary_ring(ny: int, nx: int) -> np.ndarray:
    """Indices of the grid's border vertices, counter-clockwise seen from +z, starting at (0, 0)."""
    bottom = np.arange(0, nx)  # row 0, left to right
    right = np.arange(1, ny) * nx + (nx - 1)  # last column, upwards
    top = (ny - 1) * nx + np.arange(nx - 2, -1, -1)  # last row, right to left
    left = np.arange(ny - 2, 0, -1) * nx  # first column, downwards
    return np.concatenate([bottom, right, top, left])


def slab_arrays(field: HeightField, base_thickness_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """A closed, outward-oriented slab whose top is the displaced height field.

    The top is the height field triangulated two triangles per cell at
    ``z = base_thickness_mm + h``; every border edge of the top is joined to the
    ``z = 0`` plane by a vertical wall, and the bottom is a fan around its centre.
    Each edge is therefore shared by exactly two triangles with opposite
    directions: the mesh is watertight and consistently wound by construction.

    Parameters
    ----------
    field : HeightField
        Relief heights (mm), all >= 0 is not required but ``base_thickness_mm + h`` must stay > 0.
    base_thickness_mm : float
        Thickness under the relief's zero level (mm).

    Returns
    -------
    vertices : (n, 3) float64 array (mm)
    faces : (m, 3) int64 array
        ``2(nx-1)(ny-1) + 3 L`` triangles for a border of ``L`` edges.
    """
    h = field.heights_mm
    if base_thickness_mm <= 0 or float(h.min()) + base_thickness_mm <= 0:
        raise ValueError("base_thickness_mm: the slab's top must stay above z = 0")
    ny, nx = h.shape
    xx, yy = field.grid_points()
    top = np.column_stack([xx.ravel(), yy.ravel(), (h + base_thickness_mm).ravel()])

    idx = np.arange(ny * nx).reshape(ny, nx)
    v00 = idx[:-1, :-1].ravel()
    v10 = idx[:-1, 1:].ravel()
    v01 = idx[1:, :-1].ravel()
    v11 = idx[1:, 1:].ravel()
    top_faces = np.concatenate([np.column_stack([v00, v10, v11]), np.column_stack([v00, v11, v01])])

    ring = _boundary_ring(ny, nx)
    n_ring = ring.size
    bottom_ring = top[ring].copy()
    bottom_ring[:, 2] = 0.0
    centre = np.array([[xx[0, 0] + field.width_mm / 2, yy[0, 0] + field.depth_mm / 2, 0.0]])
    n_top = top.shape[0]
    a = ring
    b = np.roll(ring, -1)
    a_low = n_top + np.arange(n_ring)
    b_low = np.roll(a_low, -1)
    c = n_top + n_ring
    walls = np.concatenate([np.column_stack([a_low, b_low, b]), np.column_stack([a_low, b, a])])
    floor = np.column_stack([np.full(n_ring, c), b_low, a_low])

    vertices = np.concatenate([top, bottom_ring, centre])
    faces = np.concatenate([top_faces, walls, floor]).astype(np.int64)
    return vertices, faces


# ---------------------------------------------------------------------------------------------
# Error-bounded adaptive top: a right-triangulated irregular network (RTIN)
#
# The square grid of (2^k + 1)^2 samples is split recursively into right isosceles
# triangles along their hypotenuses (Evans, Kirkpatrick & Townsend 2001; the "Martini"
# scheme). The error of a split is stored at the hypotenuse's midpoint, which the two
# triangles sharing that hypotenuse also share, and each midpoint carries the largest
# error below it; so splitting wherever the error exceeds the bound never leaves a crack.


@njit(cache=True, inline="always")
def _put(arr, i, ax, ay, bx, by, cx, cy) -> None:
    arr[i, 0], arr[i, 1], arr[i, 2], arr[i, 3], arr[i, 4], arr[i, 5] = ax, ay, bx, by, cx, cy


@njit(cache=True)
def _rtin_levels(size: int) -> tuple[np.ndarray, np.ndarray]:
    """All triangles (ax, ay, bx, by, cx, cy) of the full RTIN hierarchy, root first, and level starts.

    Right angle at c, hypotenuse a-b. For size = 2^k there are 2k + 1 levels; level L
    holds 2^(L + 1) triangles, and the legs of the last level are one sample long.
    """
    k = 0
    while (1 << k) < size:
        k += 1
    n_levels = 2 * k + 1
    starts = np.empty(n_levels + 1, dtype=np.int64)
    starts[0] = 0
    for level in range(n_levels):
        starts[level + 1] = starts[level] + (2 << level)
    tris = np.empty((starts[n_levels], 6), dtype=np.int64)
    _put(tris, 0, 0, 0, size, size, size, 0)
    _put(tris, 1, size, size, 0, 0, 0, size)
    write = 2
    for level in range(1, n_levels):
        for t in range(starts[level - 1], starts[level]):
            ax, ay, bx, by, cx, cy = tris[t]
            mx, my = (ax + bx) // 2, (ay + by) // 2
            _put(tris, write, cx, cy, ax, ay, mx, my)
            _put(tris, write + 1, bx, by, cx, cy, mx, my)
            write += 2
    return tris, starts


@njit(cache=True, inline="always")
def _triangle_error(h, ax, ay, bx, by, cx, cy) -> float:
    """Largest |sample - plane through the corners| over the samples inside the triangle."""
    worst = 0.0
    det = (by - cy) * (ax - cx) + (cx - bx) * (ay - cy)
    for y in range(min(ay, by, cy), max(ay, by, cy) + 1):
        for x in range(min(ax, bx, cx), max(ax, bx, cx) + 1):
            l1 = ((by - cy) * (x - cx) + (cx - bx) * (y - cy)) / det
            l2 = ((cy - ay) * (x - cx) + (ax - cx) * (y - cy)) / det
            l3 = 1.0 - l1 - l2
            if l1 >= -1e-12 and l2 >= -1e-12 and l3 >= -1e-12:
                worst = max(worst, abs(l1 * h[ay, ax] + l2 * h[by, bx] + l3 * h[cy, cx] - h[y, x]))
    return worst


@njit(cache=True, parallel=True)
def _rtin_errors(h: np.ndarray, tris: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Per hypotenuse midpoint: the largest exact error of the triangles split there and below.

    Each triangle's own error is measured over all the samples it covers (not only at its
    midpoint), which makes the bound strict: a triangle that is not split is within it.
    """
    errors = np.zeros(h.shape)
    own = np.zeros(tris.shape[0])
    n_levels = starts.shape[0] - 1
    for t in prange(tris.shape[0]):
        ax, ay, bx, by, cx, cy = tris[t, 0], tris[t, 1], tris[t, 2], tris[t, 3], tris[t, 4], tris[t, 5]
        if abs(ax - cx) + abs(ay - cy) > 1:
            own[t] = _triangle_error(h, ax, ay, bx, by, cx, cy)
    for level in range(n_levels - 1, -1, -1):
        for t in range(starts[level], starts[level + 1]):
            ax, ay, bx, by, cx, cy = tris[t, 0], tris[t, 1], tris[t, 2], tris[t, 3], tris[t, 4], tris[t, 5]
            if abs(ax - cx) + abs(ay - cy) <= 1:
                continue  # a leaf: nothing inside but its corners
            mx, my = (ax + bx) // 2, (ay + by) // 2
            e = max(own[t], errors[(cy + ay) // 2, (cx + ax) // 2], errors[(by + cy) // 2, (bx + cx) // 2])
            errors[my, mx] = max(errors[my, mx], e)
    return errors


@njit(cache=True)
def _rtin_extract(errors: np.ndarray, size: int, max_error: float) -> np.ndarray:
    stack = np.empty((64 * 2 + 8, 6), dtype=np.int64)
    out = []
    _put(stack, 0, 0, 0, size, size, size, 0)
    _put(stack, 1, size, size, 0, 0, 0, size)
    top = 2
    while top > 0:
        top -= 1
        ax, ay, bx, by, cx, cy = stack[top]
        mx, my = (ax + bx) // 2, (ay + by) // 2
        if abs(ax - cx) + abs(ay - cy) > 1 and errors[my, mx] > max_error:
            _put(stack, top, cx, cy, ax, ay, mx, my)
            _put(stack, top + 1, bx, by, cx, cy, mx, my)
            top += 2
        else:
            out.append((ax, ay, bx, by, cx, cy))
    result = np.empty((len(out), 6), dtype=np.int64)
    for i in range(len(out)):
        ax, ay, bx, by, cx, cy = out[i]
        _put(result, i, ax, ay, bx, by, cx, cy)
    return result


def adaptive_slab_arrays(
    heights_mm: np.ndarray, width_mm: float, depth_mm: float, base_thickness_mm: float, max_error_mm: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """A closed slab whose top uses as few triangles as keep every sample within ``max_error_mm``.

    Parameters
    ----------
    heights_mm : (2^k + 1, 2^k + 1) float array
        Relief heights on a square sample grid spanning ``width_mm`` by ``depth_mm``.
    max_error_mm : float
        Bound on the vertical distance between any sample and the triangulated top.

    Returns
    -------
    vertices, faces : arrays as :func:`slab_arrays`
    max_error_mm : float
        The largest error actually left at the samples (<= the bound).
    """
    h = np.ascontiguousarray(heights_mm, dtype=np.float64)
    n = h.shape[0]
    size = n - 1
    if h.shape != (n, n) or size < 1 or size & (size - 1):
        raise ValueError(f"heights: expected a square grid of 2^k + 1 samples, got shape {h.shape}")
    tris, starts = _rtin_levels(size)
    errors = _rtin_errors(h, tris, starts)
    picked = _rtin_extract(errors, size, float(max_error_mm))
    corners = picked.reshape(-1, 3, 2)  # (x, y) grid corners of each triangle: a, b, c
    grid_index = corners[:, :, 1].astype(np.int64) * n + corners[:, :, 0]
    used, inverse = np.unique(grid_index.ravel(), return_inverse=True)
    top_faces = inverse.reshape(-1, 3)
    ux, uy = used % n, used // n
    dx, dy = width_mm / size, depth_mm / size
    top = np.column_stack([ux * dx, uy * dy, base_thickness_mm + h[uy, ux]])
    # Counter-clockwise seen from above.
    e1 = top[top_faces[:, 1]] - top[top_faces[:, 0]]
    e2 = top[top_faces[:, 2]] - top[top_faces[:, 0]]
    flip = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] < 0
    top_faces[flip] = top_faces[flip][:, [0, 2, 1]]
    # The border vertices the top uses, in counter-clockwise order, carry the walls.
    on_border = (ux == 0) | (ux == size) | (uy == 0) | (uy == size)
    border = np.nonzero(on_border)[0]
    bx, by = ux[border], uy[border]
    key = np.where(
        by == 0, bx, np.where(bx == size, size + by, np.where(by == size, 3 * size - bx, 4 * size - by))
    )
    ring = border[np.argsort(key, kind="stable")]
    m = ring.size
    n_top = top.shape[0]
    bottom = top[ring].copy()
    bottom[:, 2] = 0.0
    centre = np.array([[width_mm / 2, depth_mm / 2, 0.0]])
    a, b = ring, np.roll(ring, -1)
    a_low = n_top + np.arange(m)
    b_low = np.roll(a_low, -1)
    walls = np.concatenate([np.column_stack([a_low, b_low, b]), np.column_stack([a_low, b, a])])
    floor = np.column_stack([np.full(m, n_top + m), b_low, a_low])
    vertices = np.concatenate([top, bottom, centre])
    faces = np.concatenate([top_faces, walls, floor]).astype(np.int64)
    return vertices, faces, _max_sample_error(h, picked)


@njit(cache=True, parallel=True)
def _max_sample_error(h: np.ndarray, picked: np.ndarray) -> float:
    """Largest |sample - plane of its triangle| over every grid sample (each lies in a triangle)."""
    per = np.zeros(picked.shape[0])
    for t in prange(picked.shape[0]):
        per[t] = _triangle_error(
            h, picked[t, 0], picked[t, 1], picked[t, 2], picked[t, 3], picked[t, 4], picked[t, 5]
        )
    return per.max() if per.size else 0.0
