"""Bisecting a closed mesh's long edges until none is longer than a bound (``printapp.mesh`` refines with it).

The templates are trimesh's ``remesh.subdivide_to_size`` (one long edge: two triangles; two: a
corner and the quad cut along its shorter diagonal; three: the 1-to-4 split), so a closed mesh
stays closed, and the same triangles come out in the same order (tests/test_mesh.py holds them
to trimesh's). Each round is two numba passes over the faces the round before made and one
``np.unique`` of its long edges' keys; trimesh, and this module's numpy version before it, made
every round's arrays anew with ``np.roll``, ``np.unique`` and fancy indexing (1.4 of the 2.4 s
that refining ``brushed_part``'s CAD part took on a loaded machine). Its two kernels compile in
about 5 s on a loaded machine (one kernel with numba's own ``argsort`` took 9 s).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


def bisect_long_edges(
    vertices: np.ndarray, faces: np.ndarray, max_edge: float, max_rounds: int = 40
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bisect every edge longer than ``max_edge`` at one midpoint shared by both its faces, until none is.

    Only the faces that have a long edge are looked at each round, and only the long edges
    are made unique (trimesh makes every edge of the mesh unique each round, the last one
    included). Midpoints are numbered in the order of their edges' (lower, higher) vertex pair.

    Parameters
    ----------
    vertices : (n, 3) float array
        Vertex positions (any unit; ``max_edge`` in the same).
    faces : (m, 3) int array
        Triangles.
    max_edge : float
        The longest edge allowed.
    max_rounds : int
        Rounds of bisection before giving up.

    Returns
    -------
    vertices (float64), faces (int64) and ``parent`` (int64, each face's input face).

    Raises
    ------
    ValueError
        If edges are still too long after ``max_rounds`` rounds.
    """
    verts = np.array(vertices, dtype=np.float64, copy=True)
    tris = np.array(faces, dtype=np.int64, copy=True).reshape(-1, 3)
    parent = np.arange(len(tris), dtype=np.int64)
    # A face with no long edge never gets one (its edges stay as they are), so each round
    # looks only at the faces the last one made; the finished ones keep trimesh's order.
    done, done_parent = [], []
    for round_ in range(max_rounds + 1):
        long, count, keys = _long_edges(verts, tris, float(max_edge))
        # Each long edge once per face that has it; midpoints numbered by its key's rank.
        keys, rank = np.unique(keys, return_inverse=True)
        mids, finished, finished_parent, tris, parent = _bisect_round(
            verts, tris, parent, long, count, rank.reshape(-1), len(keys)
        )
        done.append(finished)
        done_parent.append(finished_parent)
        if len(tris) == 0:
            break
        if round_ == max_rounds:
            raise ValueError(f"edges longer than {max_edge} remain after {max_rounds} rounds of bisection")
        verts = np.vstack((verts, mids))
    return verts, np.vstack(done), np.concatenate(done_parent)


@njit(cache=True)
def _long_edges(verts, tris, max_edge):
    """Per face, which edges (corner k to k + 1) are longer than ``max_edge`` and how many; and the
    long edges' keys ``low * len(verts) + high``, face by face, corner by corner."""
    n_verts = verts.shape[0]
    m = tris.shape[0]
    long = np.zeros((m, 3), dtype=np.bool_)
    count = np.zeros(m, dtype=np.int64)
    n_long = 0
    for f in range(m):
        for k in range(3):
            a = tris[f, k]
            b = tris[f, (k + 1) % 3]
            dx = verts[a, 0] - verts[b, 0]
            dy = verts[a, 1] - verts[b, 1]
            dz = verts[a, 2] - verts[b, 2]
            if math.sqrt(dx * dx + dy * dy + dz * dz) > max_edge:
                long[f, k] = True
                count[f] += 1
                n_long += 1
    keys = np.empty(n_long, dtype=np.int64)
    i = 0
    for f in range(m):
        for k in range(3):
            if long[f, k]:
                a = tris[f, k]
                b = tris[f, (k + 1) % 3]
                keys[i] = min(a, b) * n_verts + max(a, b)
                i += 1
    return long, count, keys


@njit(cache=True)
def _bisect_round(verts, tris, parent, long, count, rank, n_mid):
    """One round: ``(midpoints, finished faces, their parents, new faces, their parents)``.

    The finished faces are those with no long edge (:func:`_long_edges`), in their order. The
    ``i``-th long edge gets the midpoint ``len(verts) + rank[i]``. The new faces are trimesh's,
    block by block: the faces with one long edge (two triangles each), those with two (first
    every face's corner triangle, then every face's second, then every face's third), those
    with three (four each).
    """
    n_verts = verts.shape[0]
    m = tris.shape[0]
    mids = np.empty((n_mid, 3), dtype=np.float64)
    mid_of = np.full((m, 3), -1, dtype=np.int64)
    i = 0
    for f in range(m):
        for k in range(3):
            if long[f, k]:
                r = rank[i]
                mid_of[f, k] = n_verts + r
                a = min(tris[f, k], tris[f, (k + 1) % 3])
                b = max(tris[f, k], tris[f, (k + 1) % 3])
                for d in range(3):
                    mids[r, d] = (verts[a, d] + verts[b, d]) / 2.0
                i += 1
    n_one = n_two = n_three = n_done = 0
    for f in range(m):
        if count[f] == 0:
            n_done += 1
        elif count[f] == 1:
            n_one += 1
        elif count[f] == 2:
            n_two += 1
        else:
            n_three += 1
    finished = np.empty((n_done, 3), dtype=np.int64)
    finished_parent = np.empty(n_done, dtype=np.int64)
    out = np.empty((2 * n_one + 3 * n_two + 4 * n_three, 3), dtype=np.int64)
    out_parent = np.empty(out.shape[0], dtype=np.int64)
    e = i1 = i2 = 0
    i3 = 2 * n_one + 3 * n_two
    for f in range(m):
        c = count[f]
        if c == 0:
            finished[e] = tris[f]
            finished_parent[e] = parent[f]
            e += 1
        elif c == 1:
            j = 0
            while not long[f, j]:
                j += 1
            a, b, cc = tris[f, j], tris[f, (j + 1) % 3], tris[f, (j + 2) % 3]
            p = mid_of[f, j]
            _put(out, out_parent, i1, a, p, cc, parent[f])
            _put(out, out_parent, i1 + 1, p, b, cc, parent[f])
            i1 += 2
        elif c == 2:
            j = 0
            while long[f, j]:
                j += 1
            j = (j + 1) % 3
            a, b, cc = tris[f, j], tris[f, (j + 1) % 3], tris[f, (j + 2) % 3]
            p, q = mid_of[f, j], mid_of[f, (j + 1) % 3]
            # The quad (a, p, q, c) is cut along its shorter diagonal (a-q when not longer).
            use_aq = _squared(verts, mids, n_verts, a, q) <= _squared(verts, mids, n_verts, p, cc)
            base = 2 * n_one
            _put(out, out_parent, base + i2, p, b, q, parent[f])
            if use_aq:
                _put(out, out_parent, base + n_two + i2, a, p, q, parent[f])
                _put(out, out_parent, base + 2 * n_two + i2, a, q, cc, parent[f])
            else:
                _put(out, out_parent, base + n_two + i2, a, p, cc, parent[f])
                _put(out, out_parent, base + 2 * n_two + i2, p, q, cc, parent[f])
            i2 += 1
        else:
            v0, v1, v2 = tris[f, 0], tris[f, 1], tris[f, 2]
            n0, n1, n2 = mid_of[f, 0], mid_of[f, 1], mid_of[f, 2]
            _put(out, out_parent, i3, v0, n0, n2, parent[f])
            _put(out, out_parent, i3 + 1, n0, v1, n1, parent[f])
            _put(out, out_parent, i3 + 2, n2, n1, v2, parent[f])
            _put(out, out_parent, i3 + 3, n0, n1, n2, parent[f])
            i3 += 4
    return mids, finished, finished_parent, out, out_parent


@njit(cache=True, inline="always")
def _put(out, out_parent, row, a, b, c, face_parent):
    out[row, 0] = a
    out[row, 1] = b
    out[row, 2] = c
    out_parent[row] = face_parent


@njit(cache=True, inline="always")
def _squared(verts, mids, n_verts, u, v):
    """Squared distance between vertices ``u`` and ``v``, either of them a midpoint of this round."""
    total = 0.0
    for d in range(3):
        pu = verts[u, d] if u < n_verts else mids[u - n_verts, d]
        pv = verts[v, d] if v < n_verts else mids[v - n_verts, d]
        total += (pu - pv) ** 2
    return total
