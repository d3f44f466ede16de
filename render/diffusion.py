"""Light diffusing through a box of translucent resin: the diffusion equation on a grid.

The dipole (Jensen et al. 2001) and the slab's multipole (Donner & Jensen 2005) in
:mod:`render.bssrdf` are the Green's functions of the diffusion equation

    -div(D grad phi) + sigma_a phi = q,    D = 1 / (3 sigma_t'),

in a half-space and in an infinite slab, with the extrapolated boundary condition
``phi = 2 A D d(phi)/dn`` (inward normal) at the faces, ``A = (1 + F_dr) / (1 - F_dr)``. In a
small part of a resin that absorbs little, light spreads farther than the part is wide: most
of it meets a wall, where the half-space and the slab say it goes on. Here the same equation
with the same boundary condition is solved in the part's own box (finite volumes, cell-centred,
the 7-point stencil), so light entering any face leaves by the faces it really reaches.

Sources: light entering a face with transmitted irradiance ``E_t`` is scattered at depth ``z``
with density ``alpha' sigma_t' E_t exp(-sigma_t' z)`` (the reduced medium's first interactions;
Jensen's dipole concentrates them at ``z = 1 / sigma_t'``); the integral over each cell is
deposited there. Exitance through a boundary face is the diffusion flux
``phi_c / (h / (2 D) + 2 A)`` (half a cell of conduction in series with the boundary condition),
so what goes in comes out, less what is absorbed, exactly. Solved by conjugate gradients
(the matrix is symmetric positive definite) with a diagonal preconditioner, matrix-free in numba.

Tests compare a wide box with the slab's multipole (:func:`render.bssrdf.slab_totals`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from render.bssrdf import fresnel_diffuse_reflectance_fit


@dataclass(frozen=True)
class BoxExitance:
    """Exitance (flux per unit area) through each face of the box, per cell of that face.

    Arrays are indexed by the grid's cells: ``top``, ``bottom`` (ny, nx); ``y0``, ``y1``
    (nz, nx) (the faces at the first and last y); ``x0``, ``x1`` (nz, ny). ``z`` grows upwards:
    row 0 of a wall is at the bottom.
    """

    top: np.ndarray
    bottom: np.ndarray
    y0: np.ndarray
    y1: np.ndarray
    x0: np.ndarray
    x1: np.ndarray
    absorbed: float


@njit(cache=True)
def _apply(phi: np.ndarray, diag: np.ndarray, couple: np.ndarray, out: np.ndarray) -> None:
    """``out = A phi`` for the 7-point stencil: ``diag`` on the diagonal, ``-couple[axis]`` to
    each neighbour along ``axis`` (matrix-free; arrays shaped (nz, ny, nx))."""
    nz, ny, nx = phi.shape
    cz, cy, cx = couple[0], couple[1], couple[2]
    for k in range(nz):
        for j in range(ny):
            for i in range(nx):
                v = diag[k, j, i] * phi[k, j, i]
                if k > 0:
                    v -= cz * phi[k - 1, j, i]
                if k < nz - 1:
                    v -= cz * phi[k + 1, j, i]
                if j > 0:
                    v -= cy * phi[k, j - 1, i]
                if j < ny - 1:
                    v -= cy * phi[k, j + 1, i]
                if i > 0:
                    v -= cx * phi[k, j, i - 1]
                if i < nx - 1:
                    v -= cx * phi[k, j, i + 1]
                out[k, j, i] = v


@njit(cache=True)
def _conjugate_gradients(
    diag: np.ndarray, couple: np.ndarray, rhs: np.ndarray, tol: float, maxiter: int
) -> tuple[np.ndarray, int]:
    """Jacobi-preconditioned conjugate gradients on :func:`_apply`'s matrix, from zero, until
    ``|r| <= tol |rhs|``; sums in a fixed order (the same result whatever the machine's threads).
    Returns the solution and the iterations taken (``-1`` when ``maxiter`` ran out)."""
    # Written as loops over flat views: numba's 3-D array expressions (broadcast checks and
    # their error messages for each) took 14 s of the warm-up's compilation, these under one.
    # The sums run in the same order as np.sum's, so the result is the same to the bit.
    shape = rhs.shape
    n = rhs.size
    b = rhs.reshape(n)
    d = diag.reshape(n)
    x = np.zeros(n)
    r = b.copy()
    z = np.empty(n)
    for i in range(n):
        z[i] = r[i] / d[i]
    p = z.copy()
    ap = np.empty(n)
    rz = _dot(r, z)
    goal = tol * math.sqrt(_dot(b, b))
    for it in range(maxiter):
        _apply(p.reshape(shape), diag, couple, ap.reshape(shape))
        step = rz / _dot(p, ap)
        for i in range(n):
            x[i] += step * p[i]
            r[i] -= step * ap[i]
        if math.sqrt(_dot(r, r)) <= goal:
            return x.reshape(shape), it + 1
        for i in range(n):
            z[i] = r[i] / d[i]
        rz_new = _dot(r, z)
        ratio = rz_new / rz
        for i in range(n):
            p[i] = z[i] + ratio * p[i]
        rz = rz_new
    return x.reshape(shape), -1


@njit(cache=True)
def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """``sum(a * b)`` of two flat arrays, added in index order (as ``np.sum`` adds)."""
    total = 0.0
    for i in range(a.size):
        total += a[i] * b[i]
    return total


def _depth_fractions(sigma_t: float, nz: int, h: float) -> np.ndarray:
    """Share of the first interactions in each of ``nz`` cells from a face: exp(-s z) integrated."""
    edges = np.arange(nz + 1) * h
    return np.exp(-sigma_t * edges[:-1]) - np.exp(-sigma_t * edges[1:])


def diffuse_box(
    shape: tuple[int, int, int],
    cell_mm: float | tuple[float, float, float],
    sigma_s: float,
    sigma_a: float,
    g: float,
    eta: float,
    entering: dict[str, np.ndarray],
    tol: float = 1e-8,
) -> BoxExitance:
    """Solve the diffusion equation in a box of ``shape = (nz, ny, nx)`` cells (module doc).

    Parameters
    ----------
    shape : (nz, ny, nx)
        Cells along z (up), y and x.
    cell_mm : float or (hz, hy, hx)
        The cells' sides (mm).
    sigma_s, sigma_a : float
        Scattering and absorption coefficients (1/mm); ``g`` the phase function's mean cosine
        (the similarity relation reduces ``sigma_s`` to ``sigma_s (1 - g)``).
    eta : float
        The medium's index relative to the outside (the same on every face).
    entering : dict
        Flux entering through each face, per cell of the face (mm^2 already multiplied in:
        ``E_t`` times the face cell's area), keyed ``top``, ``bottom``, ``y0``, ``y1``, ``x0``,
        ``x1`` with the shapes of :class:`BoxExitance`'s arrays; missing faces take none.

    Returns
    -------
    BoxExitance
    """
    nz, ny, nx = (int(v) for v in shape)
    sides = np.broadcast_to(np.asarray(cell_mm, dtype=np.float64), (3,))
    if min(nz, ny, nx) < 1 or not np.all(sides > 0):
        raise ValueError("expected at least one cell along each axis and positive cell sizes")
    reduced = sigma_s * (1.0 - g)
    sigma_t = sigma_a + reduced
    if not sigma_t > 0:
        raise ValueError("expected sigma_s (1 - g) + sigma_a > 0")
    alpha = reduced / sigma_t
    d = 1.0 / (3.0 * sigma_t)
    f_dr = fresnel_diffuse_reflectance_fit(eta)
    a_bc = (1.0 + f_dr) / (1.0 - f_dr)
    volume = float(np.prod(sides))
    area = volume / sides  # the area of a face across each axis
    leak = area / (sides / (2.0 * d) + 2.0 * a_bc)  # boundary face: flux per unit phi, per axis
    couple = d * area / sides  # interior face: D area / distance, per axis

    n = nz * ny * nx
    idx = np.arange(n).reshape(nz, ny, nx)
    diag = np.full((nz, ny, nx), sigma_a * volume)
    for axis, count in enumerate((nz, ny, nx)):
        # each interior face couples the cells on its two sides
        inner = np.full(count, 2.0 * couple[axis])
        inner[[0, -1]] = couple[axis] if count > 1 else 0.0
        diag += inner.reshape([-1 if a == axis else 1 for a in range(3)])
    faces = {
        "bottom": idx[0],
        "top": idx[-1],
        "y0": idx[:, 0, :],
        "y1": idx[:, -1, :],
        "x0": idx[:, :, 0],
        "x1": idx[:, :, -1],
    }
    axis_of = {"bottom": 0, "top": 0, "y0": 1, "y1": 1, "x0": 2, "x1": 2}
    flat_diag = diag.ravel()
    for name, cells in faces.items():
        np.add.at(flat_diag, cells.ravel(), leak[axis_of[name]])

    q = np.zeros((nz, ny, nx))
    depth = {"top": nz, "bottom": nz, "y0": ny, "y1": ny, "x0": nx, "x1": nx}
    for name, flux in entering.items():
        if name not in depth:
            raise ValueError(f"entering: unknown face {name!r}; expected one of {', '.join(depth)}")
        flux = np.asarray(flux, dtype=np.float64)
        frac = alpha * _depth_fractions(sigma_t, depth[name], float(sides[axis_of[name]]))
        if name == "top":
            q += frac[::-1, None, None] * flux[None]
        elif name == "bottom":
            q += frac[:, None, None] * flux[None]
        elif name == "y0":
            q += frac[None, :, None] * flux[:, None, :]
        elif name == "y1":
            q += frac[::-1][None, :, None] * flux[:, None, :]
        elif name == "x0":
            q += frac[None, None, :] * flux[:, :, None]
        else:  # x1
            q += frac[::-1][None, None, :] * flux[:, :, None]
    if not np.any(q):
        zero = {k: np.zeros(v.shape) for k, v in faces.items()}
        return BoxExitance(**zero, absorbed=0.0)
    solution, iterations = _conjugate_gradients(
        diag, np.ascontiguousarray(couple, dtype=np.float64), q, float(tol), 20 * int(math.sqrt(n)) + 2000
    )
    if iterations < 0:
        raise RuntimeError("diffusion solve did not converge")
    phi = np.clip(solution.ravel(), 0.0, None)
    out = {k: phi[v] * (leak[axis_of[k]] / area[axis_of[k]]) for k, v in faces.items()}
    return BoxExitance(**out, absorbed=float(sigma_a * volume * phi.sum()))
