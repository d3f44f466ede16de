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
    n_top = ny * nx
    ring = _boundary_ring(ny, nx)
    n_ring = ring.size
    # Filled in place (no column_stack): this is most of `printapp emboss` on a large map.
    vertices = np.empty((n_top + n_ring + 1, 3))
    top = vertices[:n_top].reshape(ny, nx, 3)
    top[:, :, 0] = field.origin_x_mm + np.arange(nx) * field.pitch_x_mm
    top[:, :, 1] = (field.origin_y_mm + np.arange(ny) * field.pitch_y_mm)[:, None]
    np.add(h, base_thickness_mm, out=top[:, :, 2])
    vertices[n_top : n_top + n_ring] = vertices[ring]
    vertices[n_top : n_top + n_ring, 2] = 0.0
    vertices[-1] = (field.origin_x_mm + field.width_mm / 2, field.origin_y_mm + field.depth_mm / 2, 0.0)

    n_cells = (ny - 1) * (nx - 1)
    faces = np.empty((2 * n_cells + 3 * n_ring, 3), dtype=np.int64)
    v00 = (np.arange(ny - 1)[:, None] * nx + np.arange(nx - 1)).ravel()
    first, second = faces[:n_cells], faces[n_cells : 2 * n_cells]
    first[:, 0], first[:, 1], first[:, 2] = v00, v00 + 1, v00 + nx + 1
    second[:, 0], second[:, 1], second[:, 2] = v00, v00 + nx + 1, v00 + nx

    a = ring
    b = np.roll(ring, -1)
    a_low = n_top + np.arange(n_ring)
    b_low = np.roll(a_low, -1)
    walls = faces[2 * n_cells : 2 * n_cells + 2 * n_ring]
    walls[:n_ring, 0], walls[:n_ring, 1], walls[:n_ring, 2] = a_low, b_low, b
    walls[n_ring:, 0], walls[n_ring:, 1], walls[n_ring:, 2] = a_low, b, a
    floor = faces[2 * n_cells + 2 * n_ring :]
    floor[:, 0], floor[:, 1], floor[:, 2] = n_top + n_ring, b_low, a_low
    return vertices, faces


# ---------------------------------------------------------------------------------------------
# Error-bounded adaptive top: a right-triangulated irregular network (RTIN)
#
# The square grid of (2^k + 1)^2 samples is split recursively into right isosceles
# triangles along their hypotenuses (Evans, Kirkpatrick & Townsend 2001; the "Martini"
# scheme). The error of a split is stored at the hypotenuse's midpoint, which the two
# triangles sharing that hypotenuse also share, and each midpoint carries the largest
# error below it; so splitting wherever the error exceeds the bound never leaves a crack.
