"""Streamlines on triangle meshes: the walk of :mod:`noise.surface` (Battke, Stalling & Hege 1997)
and its reuse across vertices (Stalling & Hege's FastLIC idea), as numba kernels.

The public entry point is :func:`noise.surface.lic_surface`; the walk is described there.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


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


@njit(cache=True, inline="always")
def _exit(V, F, f, px, py, pz, ux, uy, uz, remaining):
    """How far (at most ``remaining``) p moves along unit u inside face f, and the edge it leaves
    by (index of the opposite corner, or -1 if it stays inside)."""
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
    return t_exit, edge


@njit(cache=True, parallel=True)
def _trace_batch(V, F, FN, NBR, T, start_face, h, n_steps, begin, positions, counts_fwd, counts_back):
    """Trace the streamlines of vertices begin, begin + 1, ... into positions[k, n_steps +- j]."""
    no_best, no_hits = np.zeros(1), np.zeros((1, 3))  # (never read: no vertex is met)
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
        # The reuse walk with no vertex to meet (tolerance 0) and no idle stop: step j forward
        # lands in positions[k, n_steps + j], backward in positions[k, n_steps - j].
        fwd, back = positions[k, n_steps + 1 :], positions[k, n_steps - 1 :: -1]
        counts_fwd[k] = _walk_hits(
            V,
            F,
            FN,
            NBR,
            T,
            start_face[v, 0],
            x,
            y,
            z,
            tx,
            ty,
            tz,
            h,
            n_steps,
            n_steps + 1,
            1.0,
            0.0,
            no_best,
            fwd,
            no_hits,
        )[0]
        counts_back[k] = _walk_hits(
            V,
            F,
            FN,
            NBR,
            T,
            start_face[v, 1],
            x,
            y,
            z,
            -tx,
            -ty,
            -tz,
            h,
            n_steps,
            n_steps + 1,
            -1.0,
            0.0,
            no_best,
            back,
            no_hits,
        )[0]


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
            t_exit, edge = _exit(V, F, f, px, py, pz, ux, uy, uz, remaining)
            # arc (in steps) where this segment starts: k - 1 steps and what was used of step k
            arc0 = (k - 1) + (h - remaining) / h
            for i in range(3 if tol_sq > 0.0 else 0):
                w = F[f, i]
                wx, wy, wz = V[w, 0] - px, V[w, 1] - py, V[w, 2] - pz
                s = wx * ux + wy * uy + wz * uz
                s = min(max(s, 0.0), t_exit)
                qx, qy, qz = wx - s * ux, wy - s * uy, wz - s * uz
                d_sq = qx * qx + qy * qy + qz * qz
                if d_sq < tol_sq and d_sq < best[w]:
                    if n_hits == hits.shape[0]:  # (rare: a long streamline meets many vertices)
                        hits = _grow(hits, 2 * hits.shape[0])
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
    # Copied element by element over flat views (both C-contiguous): a slice assignment
    # compiles numba's shape checks and their error messages, seconds of the warm-up.
    flat, into = a.reshape(a.size), grown.reshape(grown.size)
    for i in range(a.size):
        into[i] = flat[i]
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
        # Component by component: a row assignment compiles numba's shape checks (seconds).
        for j in range(nb):
            for c in range(3):
                pos[n_pos + j, c] = back[nb - 1 - j, c]
        pos[n_pos + nb, 0] = x
        pos[n_pos + nb, 1] = y
        pos[n_pos + nb, 2] = z
        for j in range(nf):
            for c in range(3):
                pos[n_pos + nb + 1 + j, c] = fwd[j, c]
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
