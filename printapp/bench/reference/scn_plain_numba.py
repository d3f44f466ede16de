"""Plain per-point numba sparse convolution noise: the formula, one point at a time.

The baseline that ``printapp bench noise`` measures the fast kernels against, and a
parity reference: for every point it visits the eight cells and all their impulses,
generating every impulse's four random numbers, with no sharing between points.
"""

import numpy as np
from numba import njit, prange

from noise.hashing import hash_cell, seed_key, stream_uniform


@njit(cache=True)
def _plain_point(px, py, pz, key, n_impulses, mode_hash):
    bx = np.int64(np.floor(px - 0.5))
    by = np.int64(np.floor(py - 0.5))
    bz = np.int64(np.floor(pz - 0.5))
    total = 0.0
    for i in range(8):
        qx = bx + (i % 2)
        qy = by + (i // 2) % 2
        qz = bz + (i // 4) % 2
        if mode_hash:
            base = np.uint64(4) * (np.uint64(n_impulses) * hash_cell(key, qx, qy, qz))
        else:
            base = np.uint64(
                np.int64(4) * np.int64(n_impulses) * (qx + np.int64(1000) * qy + np.int64(576) * qz)
            )
        for j in range(1, n_impulses + 1):
            n = base + np.uint64(4 * j)
            alpha = stream_uniform(key, n) * (1 - 2 * (j % 2))
            dx = float(qx) - px + stream_uniform(key, n + np.uint64(1))
            dy = float(qy) - py + stream_uniform(key, n + np.uint64(2))
            dz = float(qz) - pz + stream_uniform(key, n + np.uint64(3))
            v2 = dx * dx + dy * dy + dz * dz
            if v2 < 0.25:
                w = 1.0 - 4.0 * v2
                total += alpha * w * w * w
    return 4.0 / (5.0 * np.cbrt(float(n_impulses))) * total


@njit(cache=True, parallel=True)
def _plain_kernel(points, key, n_impulses, mode_hash, out):
    for k in prange(points.shape[0]):
        out[k] = _plain_point(points[k, 0], points[k, 1], points[k, 2], key, n_impulses, mode_hash)


def plain_sparse_convolution(
    points: np.ndarray, seed: int = 0, impulses: int = 30, cell_seed: str = "hash"
) -> np.ndarray:
    """Sparse convolution noise at (n, 3) points, one point at a time (all cores).

    The arguments mean what they mean for ``noise.sparse_convolution``; ``cell_seed``
    is ``"hash"`` or ``"frisvad"``.
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    out = np.empty(pts.shape[0])
    _plain_kernel(pts, seed_key(int(seed)), np.int64(impulses), cell_seed == "hash", out)
    return out
