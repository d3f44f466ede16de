"""Tangent direction fields on triangle meshes, and line integral convolution on the surface.

Streamlines are traced on the mesh itself, as Battke, Stalling & Hege (1997) do: a
point is a position inside one triangle; each step moves along the field interpolated
there (barycentric weights of the vertex vectors, projected into the triangle's plane)
and, on reaching an edge, continues into the neighbouring triangle with what is left of
the step. Fields are treated as line fields (the sign of a vector is kept continuous
along a streamline), so principal curvature directions, which have no sign, work too.
Each vertex's value is the mean of 3-D sparse convolution noise sampled along its
streamline, ``length`` forward and backward.

Tracing one streamline per vertex is the reference (``method="per_vertex"``). By default the
streamlines are reused (Stalling & Hege's FastLIC, 1995, which Battke et al. carry to
surfaces): longer streamlines are seeded only at vertices that no earlier one passed within
half a step of, and every vertex that near takes the box average centred where the
streamline passes it, from running sums. On ``examples/brushed_part.toml``'s 684k vertices
that traces 4 points per vertex instead of 41 (``printapp bench surface``). The price is a
shift across the flow of at most half a step, the along-flow sampling's own resolution:
tests/test_surface.py checks the bookkeeping against the reference where streamlines run
through vertices, and the shift's effect where they do not.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from noise.frames import angle_weighted_normals, onb


def face_adjacency(faces: np.ndarray) -> np.ndarray:
    """Neighbour of each face across the edge opposite each of its vertices (-1 on a border).

    Where more than two faces share an edge (not a manifold), they are paired in the order
    of their corners (corner ``i`` of face ``f`` at ``i * m + f``), first with second, third
    with fourth.

    Returns
    -------
    (m, 3) int64 array: ``nbr[f, i]`` shares the edge ``(faces[f, i+1], faces[f, i+2])``.
    """
    tris = np.ascontiguousarray(faces, dtype=np.int64)
    n_v = int(tris.max()) + 1 if tris.size else 0
    return _face_adjacency(tris, n_v)


@njit(cache=True)
def _face_adjacency(tris, n_v):
    # Edges bucketed by their lower vertex (a counting sort, linear in the faces), then
    # matched on the higher one within each bucket (a handful of edges per vertex).
    m = tris.shape[0]
    start = np.zeros(n_v + 1, dtype=np.int64)
    for corner in range(3):
        for f in range(m):
            a, b = tris[f, (corner + 1) % 3], tris[f, (corner + 2) % 3]
            start[min(a, b) + 1] += 1
    for v in range(n_v):
        start[v + 1] += start[v]
    fill = start[:-1].copy()
    hi = np.empty(3 * m, dtype=np.int64)
    slot = np.empty(3 * m, dtype=np.int64)
    for corner in range(3):
        for f in range(m):
            a, b = tris[f, (corner + 1) % 3], tris[f, (corner + 2) % 3]
            k = fill[min(a, b)]
            fill[min(a, b)] += 1
            hi[k] = max(a, b)
            slot[k] = corner * m + f
    nbr = np.full((m, 3), -1, dtype=np.int64)
    matched = np.zeros(3 * m, dtype=np.bool_)
    for v in range(n_v):
        for s in range(start[v], start[v + 1]):
            if matched[s]:
                continue
            for t in range(s + 1, start[v + 1]):
                if not matched[t] and hi[t] == hi[s]:
                    fs, cs = slot[s] % m, slot[s] // m
                    ft, ct = slot[t] % m, slot[t] // m
                    nbr[fs, cs] = ft
                    nbr[ft, ct] = fs
                    matched[s] = True
                    matched[t] = True
                    break
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


@njit(cache=True, parallel=True)
def _start_faces(vertices: np.ndarray, faces: np.ndarray, field: np.ndarray) -> np.ndarray:
    """Per vertex, the incident face that the field (column 0) and its opposite (column 1) point into most.

    The field is written in each corner's edge basis: inside the corner's wedge when both
    weights are >= 0, and the score is the smaller weight over their length. Corners are
    visited corner-major (corner c of face f at c * m + f); a later corner wins a tie.
    """
    n_v, m = vertices.shape[0], faces.shape[0]
    indptr = np.zeros(n_v + 1, dtype=np.int64)
    for corner in range(3):
        for f in range(m):
            indptr[faces[f, corner] + 1] += 1
    for v in range(n_v):
        indptr[v + 1] += indptr[v]
    fill = indptr[:-1].copy()
    corners = np.empty(3 * m, dtype=np.int64)
    for corner in range(3):
        for f in range(m):
            v = faces[f, corner]
            corners[fill[v]] = corner * m + f
            fill[v] += 1
    starts = np.zeros((n_v, 2), dtype=np.int64)
    for v in prange(n_v):
        for column in range(2):
            sign = 1.0 if column == 0 else -1.0
            best = -np.inf
            for k in range(indptr[v], indptr[v + 1]):
                corner, f = corners[k] // m, corners[k] % m
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
                if score >= best:
                    best = score
                    starts[v, column] = f
    return starts


REUSE_REGIONS = 8
"""Streamline reuse runs in this many slabs of the mesh at once (by vertex count along its longest
side), each seeding and taking values only for its own vertices: the result depends on this
number, never on the number of threads."""


def _reuse_lines(verts, tris, face_normals, nbr, field, starts, step, n_window, n_long, tolerance):
    """:func:`_trace_reuse` over :data:`REUSE_REGIONS` slabs in parallel threads, joined in slab order."""
    from concurrent.futures import ThreadPoolExecutor

    import numba

    n_v = len(verts)
    axis = int(np.argmax(np.ptp(verts, axis=0))) if n_v else 0
    order = np.argsort(verts[:, axis], kind="stable")
    regions = [np.sort(part) for part in np.array_split(order, REUSE_REGIONS)]
    live = np.einsum("ij,ij->i", field, field) >= 1e-18
    line_of = np.full(n_v, -1, dtype=np.int64)
    arc_of = np.zeros(n_v)

    def run(members: np.ndarray):
        best = np.full(n_v, -1.0)
        best[members[live[members]]] = np.inf
        return _trace_reuse(
            verts,
            tris,
            face_normals,
            nbr,
            field,
            starts,
            step,
            n_window,
            n_long,
            tolerance**2,
            members,
            best,
            line_of,
            arc_of,
        )

    with ThreadPoolExecutor(max_workers=max(1, min(numba.get_num_threads(), REUSE_REGIONS))) as pool:
        parts = list(pool.map(run, regions))
    line_offset, point_offset = 0, 0
    starts_all, zeros_all = [], []
    for members, (points, line_start, line_zero) in zip(regions, parts, strict=True):
        taken = members[line_of[members] >= 0]
        line_of[taken] += line_offset
        starts_all.append(line_start[:-1] + point_offset)
        zeros_all.append(line_zero + point_offset)
        line_offset += len(line_zero)
        point_offset += len(points)
    starts_all.append(np.array([point_offset], dtype=np.int64))
    points = np.concatenate([p[0] for p in parts]) if parts else np.empty((0, 3))
    return points, np.concatenate(starts_all), np.concatenate(zeros_all), line_of, arc_of


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
    method: str = "reuse",
    reuse_length: float = 4.0,
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
    method : {"reuse", "per_vertex"}
        ``"per_vertex"`` traces one streamline from every vertex (the reference).
        ``"reuse"`` (Stalling & Hege's FastLIC idea, as Battke et al. use it on surfaces):
        streamlines ``reuse_length`` times as long as the kernel's half-length are traced only
        from vertices that no earlier streamline passed within half a ``step`` of; every
        vertex within that distance takes the box average centred where the streamline passes
        it (nearest streamline wins), from running sums along the line. A vertex's window is
        thus its own streamline's, shifted across the flow by at most half a step, the same
        resolution as the samples along it.
    reuse_length : float
        ``"reuse"``: streamline length each way, in kernel half-lengths (> 1).

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
    if method not in ("reuse", "per_vertex"):
        raise ValueError(f"method: expected 'reuse' or 'per_vertex', got {method!r}")
    if not (np.isfinite(reuse_length) and reuse_length > 1.0):
        raise ValueError(f"reuse_length: expected a number above 1, got {reuse_length!r}")
    n_steps = max(1, round(length / step))
    face_normals = np.cross(verts[tris[:, 1]] - verts[tris[:, 0]], verts[tris[:, 2]] - verts[tris[:, 0]])
    face_normals /= np.maximum(np.linalg.norm(face_normals, axis=1, keepdims=True), 1e-300)
    nbr = face_adjacency(tris)
    starts = _start_faces(verts, tris, t)
    out = np.empty(verts.shape[0])
    if method == "reuse":
        n_long = max(n_steps + 2, int(math.ceil(reuse_length * n_steps)))
        points, line_start, line_zero, line_of, arc_of = _reuse_lines(
            verts, tris, face_normals, nbr, t, starts, float(step), n_steps, n_long, 0.5 * step
        )
        lone = np.flatnonzero(line_of < 0)
        values = sparse_convolution(
            np.concatenate([points, verts[lone]]) / noise_scale,
            seed=seed,
            impulses=impulses,
            cell_seed=cell_seed,
        )
        _reuse_values(values[: len(points)], line_start, line_zero, line_of, arc_of, n_steps, out)
        out[lone] = values[len(points) :]
        return out
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


@njit(cache=True, nogil=True)
def _walk_hits(
    V, F, FN, NBR, T, f, px, py, pz, dx, dy, dz, h, n_steps, n_idle, sign, tol_sq, best, out, hits
):
    """As :func:`_walk`, writing step k's point to ``out[k - 1]``, and recording in ``hits``
    (vertex, signed arc in steps, squared distance) every vertex of a face crossed that lies
    within ``sqrt(tol_sq)`` of the segment walked through it and nearer than its ``best``.
    The walk also stops once ``n_idle`` steps have passed without a hit (past step ``n_idle``):
    the streamline then only crosses vertices that have their values. Returns (steps done,
    hits recorded, the hits array, whether the walk ended by itself: a border, a vanishing
    field, or circling a vertex)."""
    prev_x, prev_y, prev_z = dx, dy, dz
    n_hits = 0
    last_hit = 0
    for k in range(1, n_steps + 1):
        remaining = h
        crossings = 0
        while remaining > 1e-12:
            ux, uy, uz, ok = _direction(V, F, FN, T, f, px, py, pz, prev_x, prev_y, prev_z)
            if not ok:
                return k - 1, n_hits, hits, True
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
            # arc (in steps) where this segment starts: k - 1 steps and what was used of step k
            arc0 = (k - 1) + (h - remaining) / h
            for i in range(3):
                w = F[f, i]
                wx, wy, wz = V[w, 0] - px, V[w, 1] - py, V[w, 2] - pz
                s = wx * ux + wy * uy + wz * uz
                s = min(max(s, 0.0), t_exit)
                qx, qy, qz = wx - s * ux, wy - s * uy, wz - s * uz
                d_sq = qx * qx + qy * qy + qz * qz
                if d_sq < tol_sq and d_sq < best[w]:
                    if n_hits == hits.shape[0]:  # (rare: a long streamline meets many vertices)
                        grown = np.empty((2 * hits.shape[0], 3))
                        grown[:n_hits] = hits
                        hits = grown
                    hits[n_hits, 0] = w
                    hits[n_hits, 1] = sign * (arc0 + s / h)
                    hits[n_hits, 2] = d_sq
                    n_hits += 1
                    last_hit = k
            px += t_exit * ux
            py += t_exit * uy
            pz += t_exit * uz
            remaining -= t_exit
            if edge >= 0:
                g = NBR[f, edge]
                crossings += 1
                if g < 0 or crossings > 64:
                    return k - 1, n_hits, hits, True
                f = g
        out[k - 1, 0] = px
        out[k - 1, 1] = py
        out[k - 1, 2] = pz
        if k >= n_idle and k - last_hit > n_idle:
            return k, n_hits, hits, False
    return n_steps, n_hits, hits, False


@njit(cache=True, nogil=True)
def _grow(a, need):
    if need <= a.shape[0]:
        return a
    size = a.shape[0]
    while size < need:
        size *= 2
    grown = np.empty((size,) + a.shape[1:], dtype=a.dtype)
    grown[: a.shape[0]] = a
    return grown


@njit(cache=True, nogil=True)
def _trace_reuse(V, F, FN, NBR, T, starts, h, n_window, n_long, tol_sq, members, best, line_of, arc_of):
    """Streamlines seeded, in order, at the ``members`` that no earlier streamline passed near.

    ``best`` is +inf at the members (their squared distance to the nearest streamline so far)
    and -1 elsewhere (never taken). Returns the streamlines' points (lines end to end, each
    ordered by arc), each line's first point and the index of its seed point; writes, for the
    members, the line (numbered from 0 here) whose value each takes and its arc position on
    it in steps from the seed. A point within ``n_window`` steps of an end where the walk was
    only cut for length (not at a border or where the field vanishes) cannot give a value:
    its window would be short.
    """
    pos = np.empty((1 << 16, 3))
    line_start = np.empty(1024, dtype=np.int64)
    line_zero = np.empty(1024, dtype=np.int64)
    fwd = np.empty((n_long, 3))
    back = np.empty((n_long, 3))
    hits_f = np.empty((1024, 3))
    hits_b = np.empty((1024, 3))
    n_pos = 0
    n_lines = 0
    for v in members:
        if best[v] != np.inf:
            continue
        x, y, z = V[v, 0], V[v, 1], V[v, 2]
        tx, ty, tz = T[v, 0], T[v, 1], T[v, 2]
        idle = n_window + 2
        nf, hf, hits_f, ended_f = _walk_hits(
            V,
            F,
            FN,
            NBR,
            T,
            starts[v, 0],
            x,
            y,
            z,
            tx,
            ty,
            tz,
            h,
            n_long,
            idle,
            1.0,
            tol_sq,
            best,
            fwd,
            hits_f,
        )
        nb, hb, hits_b, ended_b = _walk_hits(
            V,
            F,
            FN,
            NBR,
            T,
            starts[v, 1],
            x,
            y,
            z,
            -tx,
            -ty,
            -tz,
            h,
            n_long,
            idle,
            -1.0,
            tol_sq,
            best,
            back,
            hits_b,
        )
        pos = _grow(pos, n_pos + nb + 1 + nf)
        for j in range(nb):
            pos[n_pos + j] = back[nb - 1 - j]
        pos[n_pos + nb, 0] = x
        pos[n_pos + nb, 1] = y
        pos[n_pos + nb, 2] = z
        for j in range(nf):
            pos[n_pos + nb + 1 + j] = fwd[j]
        line_start = _grow(line_start, n_lines + 2)
        line_zero = _grow(line_zero, n_lines + 1)
        line_start[n_lines] = n_pos
        line_zero[n_lines] = n_pos + nb
        n_pos += nb + 1 + nf
        hi = float(nf) if ended_f else float(nf - n_window - 1)
        lo = -float(nb) if ended_b else -float(nb - n_window - 1)
        best[v] = 0.0
        line_of[v] = n_lines
        arc_of[v] = 0.0
        for hits, count in ((hits_f, hf), (hits_b, hb)):
            for i in range(count):
                w = int(hits[i, 0])
                arc, d_sq = hits[i, 1], hits[i, 2]
                if lo <= arc <= hi and d_sq < best[w]:
                    best[w] = d_sq
                    line_of[w] = n_lines
                    arc_of[w] = arc
        n_lines += 1
    line_start[n_lines] = n_pos
    return pos[:n_pos].copy(), line_start[: n_lines + 1].copy(), line_zero[:n_lines].copy()


@njit(cache=True, parallel=True)
def _reuse_values(samples, line_start, line_zero, line_of, arc_of, n_window, out):
    """Each vertex's box average (trapezoidal rule) over its line's samples within ``n_window``
    steps of its arc position, interpolated between the two sample-centred windows around it."""
    total = np.empty(samples.shape[0] + 1)
    total[0] = 0.0
    for i in range(samples.shape[0]):
        total[i + 1] = total[i] + samples[i]
    for v in prange(line_of.shape[0]):
        line = line_of[v]
        if line < 0:
            continue
        lo, hi = line_start[line], line_start[line + 1] - 1
        centre = line_zero[line] + arc_of[v]
        k0 = min(max(int(math.floor(centre)), lo), hi)
        frac = min(max(centre - k0, 0.0), 1.0)
        value = 0.0
        for k, weight in ((k0, 1.0 - frac), (min(k0 + 1, hi), frac)):
            a, b = max(k - n_window, lo), min(k + n_window, hi)
            if a == b:
                window = samples[a]
            else:
                window = (total[b + 1] - total[a] - 0.5 * (samples[a] + samples[b])) / (b - a)
            value += weight * window
        out[v] = value
