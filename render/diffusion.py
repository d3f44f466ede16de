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
(the matrix is symmetric positive definite) with a diagonal preconditioner.

Tests compare a wide box with the slab's multipole (:func:`render.bssrdf.slab_totals`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import cg

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
    diag = np.full(n, sigma_a * volume)
    rows, cols, vals = [], [], []
    for axis in range(3):
        a = np.take(idx, range(0, idx.shape[axis] - 1), axis=axis).ravel()
        b = np.take(idx, range(1, idx.shape[axis]), axis=axis).ravel()
        rows += [a, b]
        cols += [b, a]
        vals.append(np.full(2 * a.size, -couple[axis]))
        np.add.at(diag, a, couple[axis])
        np.add.at(diag, b, couple[axis])
    faces = {
        "bottom": idx[0],
        "top": idx[-1],
        "y0": idx[:, 0, :],
        "y1": idx[:, -1, :],
        "x0": idx[:, :, 0],
        "x1": idx[:, :, -1],
    }
    axis_of = {"bottom": 0, "top": 0, "y0": 1, "y1": 1, "x0": 2, "x1": 2}
    for name, cells in faces.items():
        np.add.at(diag, cells.ravel(), leak[axis_of[name]])
    all_r = np.concatenate([np.arange(n), *rows])
    all_c = np.concatenate([np.arange(n), *cols])
    matrix = sp.csr_matrix((np.concatenate([diag, *vals]), (all_r, all_c)), shape=(n, n))

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
    rhs = q.ravel()
    if not np.any(rhs):
        zero = {k: np.zeros(v.shape) for k, v in faces.items()}
        return BoxExitance(**zero, absorbed=0.0)
    precond = sp.diags(1.0 / diag)
    phi, info = cg(matrix, rhs, rtol=tol, atol=0.0, M=precond, maxiter=20 * int(math.sqrt(n)) + 2000)
    if info != 0:
        raise RuntimeError(f"diffusion solve did not converge ({info} iterations)")
    phi = np.clip(phi, 0.0, None)
    out = {k: phi[v] * (leak[axis_of[k]] / area[axis_of[k]]) for k, v in faces.items()}
    return BoxExitance(**out, absorbed=float(sigma_a * volume * phi.sum()))
