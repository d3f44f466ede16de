"""Sparse convolution noise, fBm and turbulence (Frisvad's talk, "Noise").

Sparse convolution noise (Lewis 1989) as defined in the talk::

    noise(p) = 4 / (5 N^(1/3)) * sum_{i=0..7} sum_{j=1..N} alpha_ij * cubic(x_ij - p)
    cubic(v) = (1 - 4 v.v)^3 for v.v < 1/4, else 0
    x_ij     = q_i + xi_ij,  q_i = floor(p - (1/2, 1/2, 1/2)) + (i mod 2, floor(i/2) mod 2, floor(i/4) mod 2)
    alpha_ij = rnd(t_n) * (1 - 2 (j mod 2)),  xi_ij = (rnd(t_{n+1}), rnd(t_{n+2}), rnd(t_{n+3}))
    n_ij     = 4 (N q_i . a + j),  a = (1, 1000, 576)

Coordinates are in noise units: one lattice cell is one unit, so the kernel's
support has radius 1/2 and features are about one unit across.
"""

import numpy as np
from numba import njit, prange

from noise._hash import _hash_cell, _rnd, seed_key

CELL_SEED_MODES = ("hash", "frisvad")
_A = (1, 1000, 576)


@njit(cache=True, inline="always")
def _cell_index(
    mode_hash: bool, key: np.uint64, n_impulses: np.int64, qx: np.int64, qy: np.int64, qz: np.int64
) -> np.uint64:
    if mode_hash:
        c = _hash_cell(key, qx, qy, qz)
        return np.uint64(4) * (np.uint64(n_impulses) * c)
    # The talk's n = 4 (N q.a + j): wraps in 64 bits like the C original would.
    dot = qx * np.int64(_A[0]) + qy * np.int64(_A[1]) + qz * np.int64(_A[2])
    return np.uint64(np.int64(4) * np.int64(n_impulses) * dot)


@njit(cache=True, inline="always")
def _scn_point(
    px: float, py: float, pz: float, key: np.uint64, n_impulses: np.int64, mode_hash: bool, norm: float
) -> float:
    bx = np.int64(np.floor(px - 0.5))
    by = np.int64(np.floor(py - 0.5))
    bz = np.int64(np.floor(pz - 0.5))
    total = 0.0
    for i in range(8):
        qx = bx + (i & 1)
        qy = by + ((i >> 1) & 1)
        qz = bz + ((i >> 2) & 1)
        # Relative coordinates keep precision at large |p|: q and p are both
        # large, their difference is small and exact in float64.
        rx = float(qx) - px
        ry = float(qy) - py
        rz = float(qz) - pz
        base = _cell_index(mode_hash, key, n_impulses, qx, qy, qz)
        for j in range(1, n_impulses + 1):
            n = base + np.uint64(4 * j)
            dx = rx + _rnd(key, n + np.uint64(1))
            dy = ry + _rnd(key, n + np.uint64(2))
            dz = rz + _rnd(key, n + np.uint64(3))
            r2 = dx * dx + dy * dy + dz * dz
            if r2 < 0.25:
                w = 1.0 - 4.0 * r2
                alpha = _rnd(key, n)
                if j & 1:
                    alpha = -alpha
                total += alpha * w * w * w
    return norm * total


@njit(cache=True, parallel=True)
def _scn_kernel(
    points: np.ndarray,
    key: np.uint64,
    n_impulses: np.int64,
    mode_hash: bool,
    frequency: float,
    out: np.ndarray,
) -> None:
    norm = 4.0 / (5.0 * np.cbrt(float(n_impulses)))
    for k in prange(points.shape[0]):
        out[k] = _scn_point(
            points[k, 0] * frequency,
            points[k, 1] * frequency,
            points[k, 2] * frequency,
            key,
            n_impulses,
            mode_hash,
            norm,
        )


@njit(cache=True, parallel=True)
def _fbm_kernel(
    points: np.ndarray,
    key: np.uint64,
    n_impulses: np.int64,
    mode_hash: bool,
    octaves: np.int64,
    lacunarity: float,
    hurst: float,
    out: np.ndarray,
) -> None:
    norm = 4.0 / (5.0 * np.cbrt(float(n_impulses)))
    for k in prange(points.shape[0]):
        total = 0.0
        scale = 1.0
        for _ in range(octaves):
            total += scale ** (-hurst) * _scn_point(
                points[k, 0] * scale,
                points[k, 1] * scale,
                points[k, 2] * scale,
                key,
                n_impulses,
                mode_hash,
                norm,
            )
            scale *= lacunarity
        out[k] = total


@njit(cache=True, parallel=True)
def _turbulence_kernel(
    points: np.ndarray,
    key: np.uint64,
    n_impulses: np.int64,
    mode_hash: bool,
    low: np.int64,
    high: np.int64,
    out: np.ndarray,
) -> None:
    norm = 4.0 / (5.0 * np.cbrt(float(n_impulses)))
    for k in prange(points.shape[0]):
        total = 0.0
        for i in range(low, high + 1):
            scale = 2.0**i
            total += (
                abs(
                    _scn_point(
                        points[k, 0] * scale,
                        points[k, 1] * scale,
                        points[k, 2] * scale,
                        key,
                        n_impulses,
                        mode_hash,
                        norm,
                    )
                )
                / scale
            )
        out[k] = total


def _as_points(points: np.ndarray) -> np.ndarray:
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise ValueError(f"points: expected an (n, 3) or (n, 2) array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("points: expected finite coordinates, found NaN or infinity")
    if arr.shape[1] == 2:
        arr = np.concatenate([arr, np.zeros((arr.shape[0], 1))], axis=1)
    return np.ascontiguousarray(arr)


def _check_common(impulses: int, cell_seed: str, seed: int) -> None:
    if isinstance(impulses, bool) or not isinstance(impulses, (int, np.integer)) or impulses < 1:
        raise ValueError(f"impulses: expected an integer >= 1, got {impulses!r}")
    if cell_seed not in CELL_SEED_MODES:
        raise ValueError(f"cell_seed: expected one of {CELL_SEED_MODES}, got {cell_seed!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise ValueError(f"seed: expected an integer, got {seed!r}")


def sparse_convolution(
    points: np.ndarray, *, seed: int = 0, impulses: int = 30, cell_seed: str = "hash"
) -> np.ndarray:
    """Sparse convolution noise at the given points.

    Follows Frisvad's talk ("Noise"), after Lewis (1989), exactly: eight
    neighbouring lattice cells, ``impulses`` impulses per cell with alternating
    signs and uniform amplitudes, the compact kernel ``(1 - 4 v.v)^3`` of
    radius 1/2, and the normalisation ``4 / (5 N^(1/3))``.

    Parameters
    ----------
    points : (n, 3) or (n, 2) float array
        Positions in noise units (one lattice cell per unit; features are about
        one unit across). 2-D points lie at z = 0.
    seed : int
        Seed of the stateless random stream ``rnd`` (a 64-bit SplitMix hash of
        seed and index, so any point is evaluated independently of the others).
    impulses : int
        Impulses per cell, ``N`` (the talk uses 30).
    cell_seed : {"hash", "frisvad"}
        How a cell picks its impulses. ``"frisvad"`` is the talk's
        ``n = 4 (N q.a + j)`` with ``a = (1, 1000, 576)``. Distinct cells share
        an index whenever ``q.a`` agrees, e.g. ``q = (1000, 0, 0)`` and
        ``(0, 1, 0)``, so the texture repeats exactly along the lattice vectors
        ``(1000, -1, 0)``, ``(576, 0, -1)`` and their combinations, which is
        visible on large prints. ``"hash"`` (the default) hashes the three
        64-bit cell indices through a bijective 64-bit mixer instead, so no two
        cells within 2^64 share impulses.

    Returns
    -------
    (n,) float64 array
        Noise values; mean 0, in practice within [-1, 1].
    """
    _check_common(impulses, cell_seed, seed)
    pts = _as_points(points)
    out = np.empty(pts.shape[0])
    _scn_kernel(pts, seed_key(int(seed)), np.int64(impulses), cell_seed == "hash", 1.0, out)
    return out


def octaves_for_pitch(octaves: int, lacunarity: float, pitch: float, nyquist_samples: float = 2.0) -> int:
    """Largest octave count ``<= octaves`` whose finest octave is resolved at ``pitch``.

    Octave ``i`` has features about ``lacunarity**-i`` noise units across; it is
    kept while that is at least ``nyquist_samples`` samples of ``pitch`` (noise
    units), since a printer cannot reproduce detail finer than its pixel.
    """
    if pitch <= 0:
        raise ValueError(f"pitch: expected a positive sampling pitch, got {pitch!r}")
    kept = 0
    for i in range(octaves):
        if lacunarity ** (-i) < nyquist_samples * pitch:
            break
        kept = i + 1
    return max(kept, 1)


def fbm(
    points: np.ndarray,
    *,
    octaves: int,
    lacunarity: float = 2.0,
    H: float = 1.0,
    seed: int = 0,
    impulses: int = 30,
    cell_seed: str = "hash",
    min_pitch: float | None = None,
) -> np.ndarray:
    """Fractional Brownian motion over sparse convolution noise.

    ``fBm(p) = sum_{i=0}^{octaves-1} lacunarity^(-H i) noise(p lacunarity^i)``
    (Frisvad's talk, "Noise-based modeling"; Musgrave's fBm).

    Parameters
    ----------
    points : (n, 3) or (n, 2) float array
        Positions in noise units.
    octaves : int
        Number of octaves, >= 1.
    lacunarity : float
        Frequency ratio between octaves, > 1.
    H : float
        Fractional increment (roughness) in (0, 1]; 1 is the monofractal.
    seed, impulses, cell_seed
        As for :func:`sparse_convolution`.
    min_pitch : float, optional
        Sampling pitch in noise units. When given, octaves finer than two
        samples are dropped (see :func:`octaves_for_pitch`).

    Returns
    -------
    (n,) float64 array
    """
    _check_common(impulses, cell_seed, seed)
    if isinstance(octaves, bool) or not isinstance(octaves, (int, np.integer)) or octaves < 1:
        raise ValueError(f"octaves: expected an integer >= 1, got {octaves!r}")
    if not np.isfinite(lacunarity) or lacunarity <= 1.0:
        raise ValueError(f"lacunarity: expected a number > 1, got {lacunarity!r}")
    if not np.isfinite(H) or not 0.0 < H <= 1.0:
        raise ValueError(f"H: expected a number in (0, 1], got {H!r}")
    if min_pitch is not None:
        octaves = octaves_for_pitch(octaves, lacunarity, min_pitch)
    pts = _as_points(points)
    out = np.empty(pts.shape[0])
    _fbm_kernel(
        pts,
        seed_key(int(seed)),
        np.int64(impulses),
        cell_seed == "hash",
        np.int64(octaves),
        float(lacunarity),
        float(H),
        out,
    )
    return out


def turbulence(
    points: np.ndarray,
    *,
    low: int = 0,
    high: int = 4,
    seed: int = 0,
    impulses: int = 30,
    cell_seed: str = "hash",
    min_pitch: float | None = None,
) -> np.ndarray:
    """Turbulence: ``sum_{i=low}^{high} 2^-i |noise(2^i p)|`` (Perlin 1985; the talk).

    Parameters
    ----------
    points : (n, 3) or (n, 2) float array
        Positions in noise units.
    low, high : int
        First and last octave, ``0 <= low <= high``.
    seed, impulses, cell_seed
        As for :func:`sparse_convolution`.
    min_pitch : float, optional
        Sampling pitch in noise units; octaves finer than two samples are dropped.

    Returns
    -------
    (n,) float64 array of non-negative values.
    """
    _check_common(impulses, cell_seed, seed)
    for name, value in (("low", low), ("high", high)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
            raise ValueError(f"{name}: expected an integer >= 0, got {value!r}")
    if high < low:
        raise ValueError(f"high: expected an octave >= low ({low}), got {high!r}")
    if min_pitch is not None:
        high = max(low, low + octaves_for_pitch(high - low + 1, 2.0, min_pitch * 2.0**low) - 1)
    pts = _as_points(points)
    out = np.empty(pts.shape[0])
    _turbulence_kernel(
        pts, seed_key(int(seed)), np.int64(impulses), cell_seed == "hash", np.int64(low), np.int64(high), out
    )
    return out
