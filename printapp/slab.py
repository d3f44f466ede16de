"""A closed slab from a height field: the printable solid of a relief tile (no trimesh needed).

The adaptive slab of ``emboss --max-error-um`` is :mod:`printapp.adaptive_slab`.
"""

from __future__ import annotations

import numpy as np

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
