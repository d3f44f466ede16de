"""Tangent direction fields on triangle meshes, and line integral convolution on the surface.

Streamlines are traced on the mesh itself, as Battke, Stalling & Hege (1997) do: a
point is a position inside one triangle; each step moves along the field interpolated
there (barycentric weights of the vertex vectors, projected into the triangle's plane)
and, on reaching an edge, continues into the neighbouring triangle with what is left of
the step. Fields are treated as line fields (the sign of a vector is kept continuous
along a streamline), so principal curvature directions, which have no sign, work too.
Each vertex's value is the mean of 3-D sparse convolution noise sampled along its
streamline, ``length`` forward and backward.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from noise.frames import angle_weighted_normals, onb


def face_adjacency(faces: np.ndarray) -> np.ndarray:
    """Neighbour of each face across the edge opposite each of its vertices (-1 on a border).

    Returns
    -------
    (m, 3) int64 array: ``nbr[f, i]`` shares the edge ``(faces[f, i+1], faces[f, i+2])``.
    """
    tris = np.asarray(faces, dtype=np.int64)
    m = tris.shape[0]
    a = np.concatenate([tris[:, 1], tris[:, 2], tris[:, 0]])
    b = np.concatenate([tris[:, 2], tris[:, 0], tris[:, 1]])
    owner = np.tile(np.arange(m), 3)
    corner = np.repeat(np.arange(3), m)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    order = np.lexsort((hi, lo))
    lo, hi, owner, corner = lo[order], hi[order], owner[order], corner[order]
    nbr = np.full((m, 3), -1, dtype=np.int64)
    same = (lo[1:] == lo[:-1]) & (hi[1:] == hi[:-1])
    first = np.nonzero(same)[0]
    nbr[owner[first], corner[first]] = owner[first + 1]
    nbr[owner[first + 1], corner[first + 1]] = owner[first]
    return nbr


def _project_to_tangent(vectors: np.ndarray, normals: np.ndarray) -> np.ndarray:
    t = vectors - np.einsum("ij,ij->i", vectors, normals)[:, None] * normals
    length = np.linalg.norm(t, axis=1, keepdims=True)
    return np.where(length > 1e-9, t / np.maximum(length, 1e-300), 0.0)


def _vertex_normals(vertices, faces, normals) -> np.ndarray:
    if normals is None:
        return angle_weighted_normals(vertices, faces)
    n = np.asarray(normals, dtype=np.float64)
    if n.shape != np.shape(vertices):
        raise ValueError(f"normals: expected one per vertex, shape {np.shape(vertices)}, got {n.shape}")
    return n


def field_constant(vertices: np.ndarray, faces: np.ndarray, direction, normals=None) -> np.ndarray:
    """A constant world direction projected into each vertex's tangent plane (unit, or 0 where normal).

    ``normals``: the vertices' angle-weighted normals when already computed.
    """
    d = np.asarray(direction, dtype=np.float64)
    if d.shape != (3,) or not np.all(np.isfinite(d)) or np.linalg.norm(d) == 0:
        raise ValueError(f"direction: expected a finite non-zero 3-vector, got {direction!r}")
    n = _vertex_normals(vertices, faces, normals)
    return _project_to_tangent(np.broadcast_to(d, n.shape), n)


def field_rotation(vertices: np.ndarray, faces: np.ndarray, axis, centre, normals=None) -> np.ndarray:
    """Circles about an axis through ``centre``: ``axis x (p - centre)`` in the tangent plane.

    ``normals``: the vertices' angle-weighted normals when already computed.
    """
    a = np.asarray(axis, dtype=np.float64)
    c = np.asarray(centre, dtype=np.float64)
    if a.shape != (3,) or c.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
        raise ValueError("axis, centre: expected a finite non-zero axis and a finite centre")
    n = _vertex_normals(vertices, faces, normals)
    return _project_to_tangent(np.cross(a / np.linalg.norm(a), np.asarray(vertices) - c), n)


@njit(cache=True, parallel=True)
def _principal(vertices, indptr, neighbours, normals, b1, b2, use_max: bool, out) -> None:
    for v in prange(vertices.shape[0]):
        start, end = indptr[v], indptr[v + 1]
        # Least squares z = a x^2 + b x y + c y^2 + d x + e y in the vertex's frame
        # (the linear terms absorb error in the normal).
        ata = np.zeros((5, 5))
        atz = np.zeros(5)
        for k in range(start, end):
            q = neighbours[k]
            dx = vertices[q, 0] - vertices[v, 0]
            dy = vertices[q, 1] - vertices[v, 1]
            dz = vertices[q, 2] - vertices[v, 2]
            x = dx * b1[v, 0] + dy * b1[v, 1] + dz * b1[v, 2]
            y = dx * b2[v, 0] + dy * b2[v, 1] + dz * b2[v, 2]
            z = dx * normals[v, 0] + dy * normals[v, 1] + dz * normals[v, 2]
            row = np.array([x * x, x * y, y * y, x, y])
            for i in range(5):
                atz[i] += row[i] * z
                for j in range(5):
                    ata[i, j] += row[i] * row[j]
        out[v, :] = 0.0
        if end - start < 5:
            continue
        scale = 0.0
        for i in range(5):
            scale = max(scale, ata[i, i])
        for i in range(5):
            ata[i, i] += 1e-12 * scale + 1e-300
        coef = np.linalg.solve(ata, atz)
        h = np.array([[2 * coef[0], coef[1]], [coef[1], 2 * coef[2]]])
        values, vectors = np.linalg.eigh(h)
        pick = 1 if (abs(values[1]) >= abs(values[0])) == use_max else 0
        if abs(values[1] - values[0]) < 1e-9 * (abs(values[0]) + abs(values[1]) + 1e-300):
            continue  # umbilic: no preferred direction
        ex, ey = vectors[0, pick], vectors[1, pick]
        for i in range(3):
            out[v, i] = ex * b1[v, i] + ey * b2[v, i]


def field_principal_curvature(vertices: np.ndarray, faces: np.ndarray, which: str = "max") -> np.ndarray:
    """Principal curvature directions per vertex (unit; 0 at umbilics and where undetermined).

    A quadric height function is fitted by least squares to the 2-ring of each vertex in
    its tangent frame; its Hessian is the shape operator (e.g. Goldfeather & Interrante
    2004). ``which="max"`` follows the direction of largest absolute curvature (around a
    cylinder), ``"min"`` the smallest (along it). Directions have no sign.
    """
    if which not in ("max", "min"):
        raise ValueError(f"which: expected 'max' or 'min', got {which!r}")
    verts = np.ascontiguousarray(vertices, dtype=np.float64)
    tris = np.asarray(faces, dtype=np.int64)
    n = angle_weighted_normals(verts, tris)
    b1, b2 = onb(n, normalize=True)
    indptr, neighbours = _two_ring(verts.shape[0], tris)
    out = np.zeros_like(verts)
    _principal(verts, indptr, neighbours, n, b1, b2, which == "max", out)
    return out


def _two_ring(n_vertices: int, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    import scipy.sparse as sp

    rows = np.concatenate([faces[:, 0], faces[:, 1], faces[:, 2], faces[:, 1], faces[:, 2], faces[:, 0]])
    cols = np.concatenate([faces[:, 1], faces[:, 2], faces[:, 0], faces[:, 0], faces[:, 1], faces[:, 2]])
    adjacency = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n_vertices, n_vertices))
    two = (adjacency + adjacency @ adjacency).tocsr()
    two.setdiag(0)
    two.eliminate_zeros()
    two.sort_indices()
    return two.indptr.astype(np.int64), two.indices.astype(np.int64)


def field_from_angle_map(
    vertices: np.ndarray,
    faces: np.ndarray,
    parent_face: np.ndarray,
    base_vertices: np.ndarray,
    base_faces: np.ndarray,
    base_face_uv: np.ndarray,
    angles_rad: np.ndarray,
) -> np.ndarray:
    """A line field from an angle map laid on the surface through a UV layout.

    Each vertex of a refined mesh lies in a triangle of the base mesh (``parent_face``
    of one of its triangles); its UV position is interpolated from that triangle's
    corner UVs (``base_face_uv``, per face so that seams are respected), the angle map
    is sampled there (bilinear; row 0 at v = 0, column 0 at u = 0), and the angle's UV
    direction (cos a, sin a) is mapped to 3-D by the triangle's Jacobian dP/d(u, v).

    Returns
    -------
    (n, 3) float64 array of unit tangents (zero where the UV map is degenerate).
    """
    verts = np.asarray(vertices, dtype=np.float64)
    tris = np.asarray(faces, dtype=np.int64)
    parents = np.asarray(parent_face, dtype=np.int64)
    if parents.shape != (tris.shape[0],):
        raise ValueError(f"parent_face: expected one base face per face, got shape {parents.shape}")
    angles = np.asarray(angles_rad, dtype=np.float64)
    if angles.ndim != 2 or not np.all(np.isfinite(angles)):
        raise ValueError("angles_rad: expected a finite 2-D array")
    owner = np.zeros(verts.shape[0], dtype=np.int64)
    owner[tris.ravel()] = np.repeat(parents, 3)
    bv = np.asarray(base_vertices, dtype=np.float64)[np.asarray(base_faces, dtype=np.int64)[owner]]
    buv = np.asarray(base_face_uv, dtype=np.float64)[owner]
    e1, e2 = bv[:, 1] - bv[:, 0], bv[:, 2] - bv[:, 0]
    w = verts - bv[:, 0]
    d00, d01, d11 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
    d20, d21 = (w * e1).sum(1), (w * e2).sum(1)
    den = np.maximum(d00 * d11 - d01 * d01, 1e-300)
    l1 = (d11 * d20 - d01 * d21) / den
    l2 = (d00 * d21 - d01 * d20) / den
    uv = buv[:, 0] + l1[:, None] * (buv[:, 1] - buv[:, 0]) + l2[:, None] * (buv[:, 2] - buv[:, 0])
    h, wdt = angles.shape
    x = np.clip(uv[:, 0] * (wdt - 1), 0, wdt - 1)
    y = np.clip(uv[:, 1] * (h - 1), 0, h - 1)
    i0, j0 = np.minimum(x.astype(int), max(wdt - 2, 0)), np.minimum(y.astype(int), max(h - 2, 0))
    i1, j1 = np.minimum(i0 + 1, wdt - 1), np.minimum(j0 + 1, h - 1)
    fx, fy = x - i0, y - j0
    # Orientations, not angles, are interpolated: average the doubled-angle vectors.
    c2, s2 = np.cos(2 * angles), np.sin(2 * angles)

    def bilinear(img: np.ndarray) -> np.ndarray:
        top = img[j0, i0] * (1 - fx) + img[j0, i1] * fx
        bottom = img[j1, i0] * (1 - fx) + img[j1, i1] * fx
        return top * (1 - fy) + bottom * fy

    a = 0.5 * np.arctan2(bilinear(s2), bilinear(c2))
    # Jacobian of the base triangle: [e1 e2] = J [duv1 duv2]  =>  J = [e1 e2] inv([duv1 duv2])
    duv1, duv2 = buv[:, 1] - buv[:, 0], buv[:, 2] - buv[:, 0]
    det = duv1[:, 0] * duv2[:, 1] - duv1[:, 1] * duv2[:, 0]
    ok = np.abs(det) > 1e-15
    det = np.where(ok, det, 1.0)
    dp_du = (e1 * duv2[:, 1:2] - e2 * duv1[:, 1:2]) / det[:, None]
    dp_dv = (e2 * duv1[:, 0:1] - e1 * duv2[:, 0:1]) / det[:, None]
    t = dp_du * np.cos(a)[:, None] + dp_dv * np.sin(a)[:, None]
    n = angle_weighted_normals(verts, tris)
    return _project_to_tangent(np.where(ok[:, None], t, 0.0), n)


# ---------------------------------------------------------------------------------------------
# Streamlines on the surface


@njit(cache=True, inline="always")
def _barycentric(V, F, f, px, py, pz):
    a, b, c = F[f, 0], F[f, 1], F[f, 2]
    e0x, e0y, e0z = V[b, 0] - V[a, 0], V[b, 1] - V[a, 1], V[b, 2] - V[a, 2]
    e1x, e1y, e1z = V[c, 0] - V[a, 0], V[c, 1] - V[a, 1], V[c, 2] - V[a, 2]
    wx, wy, wz = px - V[a, 0], py - V[a, 1], pz - V[a, 2]
    d00 = e0x * e0x + e0y * e0y + e0z * e0z
    d01 = e0x * e1x + e0y * e1y + e0z * e1z
    d11 = e1x * e1x + e1y * e1y + e1z * e1z
    d20 = wx * e0x + wy * e0y + wz * e0z
    d21 = wx * e1x + wy * e1y + wz * e1z
    den = d00 * d11 - d01 * d01
    if den <= 0:
        return 1.0 / 3, 1.0 / 3, 1.0 / 3
    l1 = (d11 * d20 - d01 * d21) / den
    l2 = (d00 * d21 - d01 * d20) / den
    return 1.0 - l1 - l2, l1, l2


@njit(cache=True, inline="always")
def _direction(V, F, FN, T, f, px, py, pz, prev_x, prev_y, prev_z):
    """Unit field direction in face f at p, sign-matched to the previous direction."""
    l0, l1, l2 = _barycentric(V, F, f, px, py, pz)
    a, b, c = F[f, 0], F[f, 1], F[f, 2]
    # Vertex vectors are aligned to the previous direction before blending: a line
    # field (no sign) must not cancel itself inside a triangle.
    dx = dy = dz = 0.0
    for vert, w in ((a, l0), (b, l1), (c, l2)):
        tx, ty, tz = T[vert, 0], T[vert, 1], T[vert, 2]
        if tx * prev_x + ty * prev_y + tz * prev_z < 0:
            tx, ty, tz = -tx, -ty, -tz
        dx += w * tx
        dy += w * ty
        dz += w * tz
    nd = dx * FN[f, 0] + dy * FN[f, 1] + dz * FN[f, 2]
    dx -= nd * FN[f, 0]
    dy -= nd * FN[f, 1]
    dz -= nd * FN[f, 2]
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    if not norm > 1e-9:
        return 0.0, 0.0, 0.0, False
    return dx / norm, dy / norm, dz / norm, True


@njit(cache=True)
def _walk(V, F, FN, NBR, T, f, px, py, pz, dx, dy, dz, h, n_steps, out, out_start, sign_step):
    """Walk n_steps steps of length h into out[out_start + sign_step * k]; return the steps done."""
    prev_x, prev_y, prev_z = dx, dy, dz
    for k in range(1, n_steps + 1):
        remaining = h
        crossings = 0
        while remaining > 1e-12:
            ux, uy, uz, ok = _direction(V, F, FN, T, f, px, py, pz, prev_x, prev_y, prev_z)
            if not ok:
                return k - 1
            prev_x, prev_y, prev_z = ux, uy, uz
            l0, l1, l2 = _barycentric(V, F, f, px, py, pz)
            m0, m1, m2 = _barycentric(V, F, f, px + ux, py + uy, pz + uz)
            m0 -= l0
            m1 -= l1
            m2 -= l2
            t_exit = remaining
            edge = -1
            for i, (lam, mu) in enumerate(((l0, m0), (l1, m1), (l2, m2))):
                if mu < -1e-15:
                    t = -max(lam, 0.0) / mu
                    if t < t_exit:
                        t_exit = t
                        edge = i
            px += t_exit * ux
            py += t_exit * uy
            pz += t_exit * uz
            remaining -= t_exit
            if edge >= 0:
                g = NBR[f, edge]
                crossings += 1
                if g < 0 or crossings > 64:
                    return k - 1  # a border, or stuck circling a vertex
                f = g
        idx = out_start + sign_step * k
        out[idx, 0] = px
        out[idx, 1] = py
        out[idx, 2] = pz
    return n_steps


@njit(cache=True, parallel=True)
def _trace_batch(V, F, FN, NBR, T, start_face, h, n_steps, begin, positions, counts_fwd, counts_back):
    """Trace the streamlines of vertices begin, begin + 1, ... into positions[k, n_steps +- j]."""
    for k in prange(positions.shape[0]):
        v = begin + k
        positions[k, n_steps, 0] = V[v, 0]
        positions[k, n_steps, 1] = V[v, 1]
        positions[k, n_steps, 2] = V[v, 2]
        tx, ty, tz = T[v, 0], T[v, 1], T[v, 2]
        if tx * tx + ty * ty + tz * tz < 1e-18:
            counts_fwd[k] = 0
            counts_back[k] = 0
            continue
        x, y, z = V[v, 0], V[v, 1], V[v, 2]
        out = positions[k]
        counts_fwd[k] = _walk(
            V, F, FN, NBR, T, start_face[v, 0], x, y, z, tx, ty, tz, h, n_steps, out, n_steps, 1
        )
        counts_back[k] = _walk(
            V, F, FN, NBR, T, start_face[v, 1], x, y, z, -tx, -ty, -tz, h, n_steps, out, n_steps, -1
        )


@njit(cache=True)
def _start_faces(vertices: np.ndarray, faces: np.ndarray, field: np.ndarray) -> np.ndarray:
    """Per vertex, the incident face that the field (column 0) and its opposite (column 1) point into most.

    The field is written in each corner's edge basis: inside the corner's wedge when both
    weights are >= 0, and the score is the smaller weight over their length. Corners are
    visited corner-major (corner c of face f at c * m + f); a later corner wins a tie.
    """
    n_v, m = vertices.shape[0], faces.shape[0]
    starts = np.zeros((n_v, 2), dtype=np.int64)
    best = np.full((n_v, 2), -np.inf)
    for column in range(2):
        sign = 1.0 if column == 0 else -1.0
        for corner in range(3):
            for f in range(m):
                v = faces[f, corner]
                a, b = faces[f, (corner + 1) % 3], faces[f, (corner + 2) % 3]
                e1x, e1y, e1z = (
                    vertices[a, 0] - vertices[v, 0],
                    vertices[a, 1] - vertices[v, 1],
                    vertices[a, 2] - vertices[v, 2],
                )
                e2x, e2y, e2z = (
                    vertices[b, 0] - vertices[v, 0],
                    vertices[b, 1] - vertices[v, 1],
                    vertices[b, 2] - vertices[v, 2],
                )
                tx, ty, tz = sign * field[v, 0], sign * field[v, 1], sign * field[v, 2]
                g11 = e1x * e1x + e1y * e1y + e1z * e1z
                g12 = e1x * e2x + e1y * e2y + e1z * e2z
                g22 = e2x * e2x + e2y * e2y + e2z * e2z
                det = max(g11 * g22 - g12 * g12, 1e-300)
                r1 = tx * e1x + ty * e1y + tz * e1z
                r2 = tx * e2x + ty * e2y + tz * e2z
                w1 = (g22 * r1 - g12 * r2) / det
                w2 = (g11 * r2 - g12 * r1) / det
                score = min(w1, w2) / max(math.hypot(w1, w2), 1e-300)
                if score >= best[v, column]:
                    best[v, column] = score
                    starts[v, column] = f
    return starts


def lic_surface(
    vertices: np.ndarray,
    faces: np.ndarray,
    field: np.ndarray,
    *,
    length: float,
    step: float,
    noise_scale: float = 1.0,
    seed: int = 0,
    impulses: int = 30,
    cell_seed: str = "hash",
    batch: int = 65536,
) -> np.ndarray:
    """Line integral convolution of 3-D sparse convolution noise along a tangent field on a mesh.

    Battke, Stalling & Hege (1997), "Fast line integral convolution for arbitrary surfaces
    in 3D"; the streamline walk is described in the module docstring. Box kernel.

    Parameters
    ----------
    vertices : (n, 3) float array
        Vertex positions (mm, or any unit used consistently below).
    faces : (m, 3) int array
        Triangles, consistently oriented.
    field : (n, 3) float array
        Tangent vectors per vertex (any length; zero where the field vanishes). Treated
        as a line field: only the direction up to sign matters.
    length : float
        Half-length of each streamline (same unit as the vertices).
    step : float
        Step along the streamline; about the printer's pixel pitch is enough.
    noise_scale : float
        Size of one noise cell (same unit): noise is sampled at ``p / noise_scale``.
    seed, impulses, cell_seed
        As for :func:`noise.sparse_convolution`.

    Returns
    -------
    (n,) float64 array: the mean noise along each vertex's streamline (the noise at the
    vertex itself where the field vanishes).
    """
    from noise.scn import sparse_convolution

    verts = np.ascontiguousarray(vertices, dtype=np.float64)
    tris = np.ascontiguousarray(faces, dtype=np.int64)
    t = np.ascontiguousarray(field, dtype=np.float64)
    if verts.ndim != 2 or verts.shape[1] != 3 or tris.ndim != 2 or tris.shape[1] != 3:
        raise ValueError("vertices, faces: expected (n, 3) and (m, 3) arrays")
    if t.shape != verts.shape:
        raise ValueError(f"field: expected shape {verts.shape} like the vertices, got {t.shape}")
    if not (np.all(np.isfinite(verts)) and np.all(np.isfinite(t))):
        raise ValueError("vertices, field: expected finite values")
    for name, value in (("length", length), ("step", step), ("noise_scale", noise_scale)):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name}: expected a positive number, got {value!r}")
    n_steps = max(1, round(length / step))
    face_normals = np.cross(verts[tris[:, 1]] - verts[tris[:, 0]], verts[tris[:, 2]] - verts[tris[:, 0]])
    face_normals /= np.maximum(np.linalg.norm(face_normals, axis=1, keepdims=True), 1e-300)
    nbr = face_adjacency(tris)
    starts = _start_faces(verts, tris, t)
    out = np.empty(verts.shape[0])
    width = 2 * n_steps + 1
    offsets = np.arange(width) - n_steps
    for begin in range(0, verts.shape[0], batch):
        end = min(begin + batch, verts.shape[0])
        count = end - begin
        positions = np.empty((count, width, 3))
        fwd = np.empty(count, dtype=np.int64)
        back = np.empty(count, dtype=np.int64)
        _trace_batch(
            verts, tris, face_normals, nbr, t, starts, float(step), n_steps, begin, positions, fwd, back
        )
        valid = (offsets[None, :] <= fwd[:, None]) & (offsets[None, :] >= -back[:, None])
        values = np.zeros((count, width))
        values[valid] = sparse_convolution(
            positions[valid] / noise_scale, seed=seed, impulses=impulses, cell_seed=cell_seed
        )
        # The trapezoidal rule over the streamline (its two end samples weigh a half): second
        # order in the step, where equal weights are first order (8.5 % of the texture's
        # spread at a quarter-feature step on a plane, against 1 % this way).
        weights = valid.astype(np.float64)
        rows = np.arange(count)
        ends = (fwd + back) > 0
        weights[rows[ends], n_steps + fwd[ends]] = 0.5
        weights[rows[ends], n_steps - back[ends]] = 0.5
        out[begin:end] = (values * weights).sum(axis=1) / weights.sum(axis=1)
    return out
