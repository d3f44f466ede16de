"""The numba kernels of sparse convolution noise (private; :mod:`noise.scn` wraps and documents them).

See :mod:`noise.scn` for the formula and for how the kernels make it fast.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from noise.hashing import hash_cell, stream_uniform

_DENSE_MIN_POINTS = 3  # cells with fewer points are evaluated point by point
_A = (1, 1000, 576)
_FASTMATH = {"nsz", "arcp", "contract", "reassoc"}  # never nnan/ninf: inputs are validated instead


@njit(cache=True, inline="always")
def _cell_base(
    mode_hash: bool, key: np.uint64, n_impulses: np.int64, qx: np.int64, qy: np.int64, qz: np.int64
):
    if mode_hash:
        c = hash_cell(key, qx, qy, qz)
        return np.uint64(4) * (np.uint64(n_impulses) * c)
    # The talk's n = 4 (N q.a + j): wraps in 64 bits like the C original would.
    dot = qx * np.int64(_A[0]) + qy * np.int64(_A[1]) + qz * np.int64(_A[2])
    return np.uint64(np.int64(4) * np.int64(n_impulses) * dot)


@njit(cache=True, inline="always")
def _norm(n_impulses: np.int64) -> float:
    return 4.0 / (5.0 * np.cbrt(float(n_impulses)))


@njit(cache=True, fastmath=_FASTMATH)
def _scn_point(
    px: float, py: float, pz: float, key: np.uint64, n_impulses: np.int64, mode_hash: bool
) -> float:
    """Un-normalised noise sum at one point, for points alone in their cell.

    Every impulse's four random numbers are generated and the kernel is applied
    branch-free: the compiler vectorises the hashing, which beats skipping work
    with unpredictable branches.
    """
    bx = np.int64(np.floor(px - 0.5))
    by = np.int64(np.floor(py - 0.5))
    bz = np.int64(np.floor(pz - 0.5))
    total = 0.0
    for i in range(8):
        qx = bx + (i & 1)
        qy = by + ((i >> 1) & 1)
        qz = bz + ((i >> 2) & 1)
        # q - p is exact (Sterbenz), so precision does not decay at large |p|.
        rx = float(qx) - px
        ry = float(qy) - py
        rz = float(qz) - pz
        base = _cell_base(mode_hash, key, n_impulses, qx, qy, qz)
        for j in range(1, n_impulses + 1):
            n = base + np.uint64(4 * j)
            a = stream_uniform(key, n)
            alpha = -a if j & 1 else a
            dx = rx + stream_uniform(key, n + np.uint64(1))
            dy = ry + stream_uniform(key, n + np.uint64(2))
            dz = rz + stream_uniform(key, n + np.uint64(3))
            w = max(1.0 - 4.0 * (dx * dx + dy * dy + dz * dz), 0.0)
            total += alpha * (w * w * w)
    return total


@njit(cache=True)
def _fill_impulses(
    bx: np.int64,
    by: np.int64,
    bz: np.int64,
    key: np.uint64,
    n_impulses: np.int64,
    mode_hash: bool,
    ox: np.ndarray,
    oy: np.ndarray,
    oz: np.ndarray,
    amp: np.ndarray,
) -> None:
    """The 8 N impulses around base cell b, positions relative to b, in the formula's (i, j) order."""
    k = 0
    for i in range(8):
        di = i & 1
        dj = (i >> 1) & 1
        dk = (i >> 2) & 1
        base = _cell_base(mode_hash, key, n_impulses, bx + di, by + dj, bz + dk)
        for j in range(1, n_impulses + 1):
            n = base + np.uint64(4 * j)
            a = stream_uniform(key, n)
            amp[k] = -a if j & 1 else a
            ox[k] = float(di) + stream_uniform(key, n + np.uint64(1))
            oy[k] = float(dj) + stream_uniform(key, n + np.uint64(2))
            oz[k] = float(dk) + stream_uniform(key, n + np.uint64(3))
            k += 1


@njit(cache=True)
def _cell_bounds(points: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounding box of the points' base cells ``floor(p scale - 1/2)``."""
    lo = np.full(3, np.iinfo(np.int64).max, dtype=np.int64)
    hi = np.full(3, np.iinfo(np.int64).min, dtype=np.int64)
    for k in range(points.shape[0]):
        for a in range(3):
            c = np.int64(np.floor(points[k, a] * scale - 0.5))
            lo[a] = min(lo[a], c)
            hi[a] = max(hi[a], c)
    return lo, hi


@njit(cache=True, inline="always")
def _linear_cell(points: np.ndarray, k: np.int64, scale: float, lo: np.ndarray, span: np.ndarray) -> np.int64:
    cx = np.int64(np.floor(points[k, 0] * scale - 0.5)) - lo[0]
    cy = np.int64(np.floor(points[k, 1] * scale - 0.5)) - lo[1]
    cz = np.int64(np.floor(points[k, 2] * scale - 0.5)) - lo[2]
    return (cz * span[1] + cy) * span[0] + cx


@njit(cache=True, parallel=True)
def _gather_scaled(points: np.ndarray, order: np.ndarray, scale: float) -> np.ndarray:
    out = np.empty((order.shape[0], 3))
    for k in prange(order.shape[0]):
        for a in range(3):
            out[k, a] = points[order[k], a] * scale
    return out


@njit(cache=True)
def _counting_sort(
    points: np.ndarray, scale: float, lo: np.ndarray, span: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Stable order of points by base cell in O(n + cells), and where each non-empty cell starts.

    Cell indices are recomputed rather than stored: on this machine a large fresh
    allocation costs more in page faults than the arithmetic.
    """
    n = points.shape[0]
    n_bins = span[0] * span[1] * span[2]
    counts = np.zeros(n_bins + 1, dtype=np.int64)
    for k in range(n):
        counts[_linear_cell(points, k, scale, lo, span) + 1] += 1
    n_groups = 0
    for b in range(n_bins):
        n_groups += counts[b + 1] > 0
        counts[b + 1] += counts[b]
    starts = np.empty(n_groups + 1, dtype=np.int64)
    g = 0
    for b in range(n_bins):
        if counts[b + 1] > counts[b]:
            starts[g] = counts[b]
            g += 1
    starts[n_groups] = n
    order = np.empty(n, dtype=np.int64)
    for k in range(n):
        cell = _linear_cell(points, k, scale, lo, span)
        order[counts[cell]] = k
        counts[cell] += 1
    return order, starts


@njit(cache=True)
def _group_starts(cells: np.ndarray, order: np.ndarray) -> np.ndarray:
    n = order.shape[0]
    flags = np.zeros(n + 1, dtype=np.bool_)
    flags[0] = True
    flags[n] = True
    for k in range(1, n):
        a, b = order[k], order[k - 1]
        flags[k] = cells[a, 0] != cells[b, 0] or cells[a, 1] != cells[b, 1] or cells[a, 2] != cells[b, 2]
    return np.nonzero(flags)[0].astype(np.int64)


@njit(cache=True, fastmath=_FASTMATH)
def _sum_impulses(px: float, py: float, pz: float, ox, oy, oz, amp, count: np.int64) -> float:
    total = 0.0
    for k in range(count):
        dx = ox[k] - px
        dy = oy[k] - py
        dz = oz[k] - pz
        w = max(1.0 - 4.0 * (dx * dx + dy * dy + dz * dz), 0.0)
        total += amp[k] * (w * w * w)
    return total


@njit(cache=True)
def _cull(src_x, src_y, src_z, src_a, count, lo, hi, dst_x, dst_y, dst_z, dst_a) -> np.int64:
    """Copy, in order, the impulses within reach (1/2) of the box [lo, hi]; return how many."""
    kept = 0
    for i in range(count):
        dx = max(lo[0] - src_x[i], 0.0, src_x[i] - hi[0])
        dy = max(lo[1] - src_y[i], 0.0, src_y[i] - hi[1])
        dz = max(lo[2] - src_z[i], 0.0, src_z[i] - hi[2])
        # Written unconditionally and kept by advancing the count: no branch to mispredict.
        dst_x[kept] = src_x[i]
        dst_y[kept] = src_y[i]
        dst_z[kept] = src_z[i]
        dst_a[kept] = src_a[i]
        kept += dx * dx + dy * dy + dz * dz < 0.25
    return kept


@njit(cache=True, parallel=True)
def _eval_bins(
    points: np.ndarray,
    order: np.ndarray,
    starts: np.ndarray,
    key: np.uint64,
    n_impulses: np.int64,
    mode_hash: bool,
    out: np.ndarray,
) -> None:
    """Noise at ``points`` (noise units, sorted by cell) into ``out[order]``.

    Cell ``g`` holds points ``starts[g]:starts[g + 1]``; contiguous points keep the
    memory traffic sequential, which matters more than any arithmetic here.
    """
    norm = _norm(n_impulses)
    n_groups = starts.shape[0] - 1
    m = 8 * n_impulses
    n_chunks = min(n_groups, 256)
    for chunk in prange(n_chunks):
        ox = np.empty(m)
        oy = np.empty(m)
        oz = np.empty(m)
        amp = np.empty(m)
        ax = np.empty(m + 1)
        ay = np.empty(m + 1)
        az = np.empty(m + 1)
        aa = np.empty(m + 1)
        lo = np.empty(3)
        hi = np.empty(3)
        g_begin = chunk * n_groups // n_chunks
        g_end = (chunk + 1) * n_groups // n_chunks
        for g in range(g_begin, g_end):
            s0 = starts[g]
            s1 = starts[g + 1]
            if s1 - s0 < _DENSE_MIN_POINTS:
                # Few points in the cell: generating the whole cell would cost more.
                for k in range(s0, s1):
                    out[order[k]] = norm * _scn_point(
                        points[k, 0],
                        points[k, 1],
                        points[k, 2],
                        key,
                        n_impulses,
                        mode_hash,
                    )
                continue
            b0 = np.floor(points[s0, 0] - 0.5)
            b1 = np.floor(points[s0, 1] - 0.5)
            b2 = np.floor(points[s0, 2] - 0.5)
            _fill_impulses(
                np.int64(b0), np.int64(b1), np.int64(b2), key, n_impulses, mode_hash, ox, oy, oz, amp
            )
            # Positions relative to b: p - b is exact (Sterbenz), so large |p| lose nothing.
            lo[:] = np.inf
            hi[:] = -np.inf
            for k in range(s0, s1):
                for a, b in ((0, b0), (1, b1), (2, b2)):
                    v = points[k, a] - b
                    lo[a] = min(lo[a], v)
                    hi[a] = max(hi[a], v)
            kept = _cull(ox, oy, oz, amp, m, lo, hi, ax, ay, az, aa)
            for k in range(s0, s1):
                out[order[k]] = norm * _sum_impulses(
                    points[k, 0] - b0, points[k, 1] - b1, points[k, 2] - b2, ax, ay, az, aa, kept
                )


@njit(cache=True)
def _runs(coords: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Run starts of equal base cell along one sorted axis, and each run's cell."""
    n = coords.shape[0]
    cells = np.empty(n, dtype=np.int64)
    for k in range(n):
        cells[k] = np.int64(np.floor(coords[k] * scale - 0.5))
    count = 1
    for k in range(1, n):
        if cells[k] != cells[k - 1]:
            count += 1
    starts = np.empty(count + 1, dtype=np.int64)
    run_cells = np.empty(count, dtype=np.int64)
    starts[0] = 0
    run_cells[0] = cells[0]
    r = 1
    for k in range(1, n):
        if cells[k] != cells[k - 1]:
            starts[r] = k
            run_cells[r] = cells[k]
            r += 1
    starts[count] = n
    return starts, run_cells


@njit(cache=True, parallel=True, fastmath=_FASTMATH)
def _eval_grid(
    xs: np.ndarray,
    ys: np.ndarray,
    zs: np.ndarray,
    scale: float,
    key: np.uint64,
    n_impulses: np.int64,
    mode_hash: bool,
    out: np.ndarray,
) -> None:
    norm = _norm(n_impulses)
    sx, cx = _runs(xs, scale)
    sy, cy = _runs(ys, scale)
    sz, cz = _runs(zs, scale)
    nrx, nry, nrz = cx.shape[0], cy.shape[0], cz.shape[0]
    m = 8 * n_impulses
    for g in prange(nrx * nry * nrz):
        rx = g % nrx
        ry = (g // nrx) % nry
        rz = g // (nrx * nry)
        bx, by, bz = cx[rx], cy[ry], cz[rz]
        ox = np.empty(m)
        oy = np.empty(m)
        oz = np.empty(m)
        amp = np.empty(m)
        _fill_impulses(bx, by, bz, key, n_impulses, mode_hash, ox, oy, oz, amp)
        plane_x = np.empty(m)
        plane_y = np.empty(m)
        plane_a = np.empty(m)
        plane_r = np.empty(m)
        row_x = np.empty(m)
        row_a = np.empty(m)
        row_r = np.empty(m)
        for iz in range(sz[rz], sz[rz + 1]):
            z = zs[iz] * scale - float(bz)
            n_plane = 0
            for i in range(m):
                dz = oz[i] - z
                if dz * dz < 0.25:
                    plane_x[n_plane] = ox[i]
                    plane_y[n_plane] = oy[i]
                    plane_a[n_plane] = amp[i]
                    plane_r[n_plane] = dz * dz
                    n_plane += 1
            for iy in range(sy[ry], sy[ry + 1]):
                y = ys[iy] * scale - float(by)
                n_row = 0
                for i in range(n_plane):
                    dy = plane_y[i] - y
                    r2 = plane_r[i] + dy * dy
                    if r2 < 0.25:
                        row_x[n_row] = plane_x[i]
                        row_a[n_row] = plane_a[i]
                        row_r[n_row] = r2
                        n_row += 1
                for ix in range(sx[rx], sx[rx + 1]):
                    x = xs[ix] * scale - float(bx)
                    total = 0.0
                    for i in range(n_row):
                        dx = row_x[i] - x
                        w = max(1.0 - 4.0 * (row_r[i] + dx * dx), 0.0)
                        total += row_a[i] * (w * w * w)
                    out[iz, iy, ix] = norm * total
