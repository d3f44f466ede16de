"""Sparse convolution noise, fBm and turbulence (Frisvad's talk, "Noise").

Sparse convolution noise (Lewis 1989) as defined in the talk::

    noise(p) = 4 / (5 N^(1/3)) * sum_{i=0..7} sum_{j=1..N} alpha_ij * cubic(x_ij - p)
    cubic(v) = (1 - 4 v.v)^3 for v.v < 1/4, else 0
    x_ij     = q_i + xi_ij,  q_i = floor(p - (1/2, 1/2, 1/2)) + (i mod 2, floor(i/2) mod 2, floor(i/4) mod 2)
    alpha_ij = rnd(t_n) * (1 - 2 (j mod 2)),  xi_ij = (rnd(t_{n+1}), rnd(t_{n+2}), rnd(t_{n+3}))
    n_ij     = 4 (N q_i . a + j),  a = (1, 1000, 576)

Coordinates are in noise units: one lattice cell is one unit, so the kernel's
support has radius 1/2 and features are about one unit across.

How it is made fast (the value at each point is the formula's, to rounding):

* Points that share their base cell ``floor(p - 1/2)`` share all eight cells, so
  points are binned by base cell (a counting sort when the cells span a compact
  range, else a lexicographic sort) and each bin generates its ``8 N`` impulses
  once. Impulses farther than 1/2 from the bin's bounding box are dropped before
  any point looks at them; each point then tests the rest branch-free, which the
  compiler vectorises.
* Bins with only one or two points (very sparse sampling) do not pay for the
  whole cell: they walk the impulses per point and stop generating an impulse's
  random numbers as soon as one coordinate is out of reach.
* On regular grids, bins are products of runs along each axis (no sort), and the
  impulses are culled per plane and per row, so the innermost loop only tests x.
* Bins are processed in parallel; a point's sum is always taken in the same
  order, so results are bit-identical whatever the number of threads.
"""

from __future__ import annotations

import math

import numpy as np

from noise._scn_kernels import (
    _cell_bounds,
    _counting_sort,
    _eval_bins,
    _eval_grid,
    _gather_scaled,
    _group_starts,
)
from noise.hashing import seed_key

CELL_SEED_MODES = ("hash", "frisvad")
_MAX_OCTAVE_DOUBLINGS = 40  # finer octaves than 2^40 times the first lose every digit of the position


# ---------------------------------------------------------------------------------------------
# Validation and octave bookkeeping


def _as_points(points: np.ndarray) -> np.ndarray:
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise ValueError(f"points: expected an (n, 3) or (n, 2) array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError("points: expected finite coordinates, found NaN or infinity")
    if arr.shape[1] == 2:
        arr = np.concatenate([arr, np.zeros((arr.shape[0], 1))], axis=1)
    return np.ascontiguousarray(arr)


def _as_axis(values: np.ndarray | None, name: str) -> np.ndarray:
    if values is None:
        return np.zeros(1)
    arr = np.ascontiguousarray(np.asarray(values, dtype=np.float64))
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{name}: expected a non-empty 1-D array of coordinates, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: expected finite coordinates, found NaN or infinity")
    if arr.size > 1 and np.any(np.diff(arr) < 0):
        raise ValueError(f"{name}: expected coordinates in ascending order")
    return arr


def _is_int(value: object) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _check_common(impulses: int, cell_seed: str, seed: int) -> None:
    if not _is_int(impulses) or impulses < 1:
        raise ValueError(f"impulses: expected an integer >= 1, got {impulses!r}")
    if cell_seed not in CELL_SEED_MODES:
        raise ValueError(f"cell_seed: expected one of {CELL_SEED_MODES}, got {cell_seed!r}")
    if not _is_int(seed):
        raise ValueError(f"seed: expected an integer, got {seed!r}")


def _check_fbm(octaves: int, lacunarity: float, H: float) -> None:
    if not _is_int(octaves) or octaves < 1:
        raise ValueError(f"octaves: expected an integer >= 1, got {octaves!r}")
    if not np.isfinite(lacunarity) or lacunarity <= 1.0:
        raise ValueError(f"lacunarity: expected a number > 1, got {lacunarity!r}")
    if not np.isfinite(H) or not 0.0 < H <= 1.0:
        raise ValueError(f"H: expected a number in (0, 1], got {H!r}")
    if (octaves - 1) * math.log2(lacunarity) > _MAX_OCTAVE_DOUBLINGS:
        doublings = (octaves - 1) * math.log2(lacunarity)
        raise ValueError(
            f"lacunarity: {lacunarity!r} over {octaves} octaves puts the finest at 2^{doublings:.0f} "
            f"times the first; expected at most 2^{_MAX_OCTAVE_DOUBLINGS}"
        )


def _check_turbulence(low: int, high: int) -> None:
    for name, value in (("low", low), ("high", high)):
        if not _is_int(value) or value < 0:
            raise ValueError(f"{name}: expected an integer >= 0, got {value!r}")
    if high < low:
        raise ValueError(f"high: expected an octave >= low ({low}), got {high!r}")
    if high > _MAX_OCTAVE_DOUBLINGS:
        raise ValueError(f"high: expected an octave up to {_MAX_OCTAVE_DOUBLINGS}, got {high!r}")


def octaves_for_pitch(octaves: int, lacunarity: float, pitch: float, nyquist_samples: float = 2.0) -> int:
    """Largest octave count ``<= octaves`` whose finest octave is resolved at ``pitch``.

    Octave ``i`` has features about ``lacunarity**-i`` noise units across; it is
    kept while that is at least ``nyquist_samples`` samples of ``pitch`` (noise
    units), since a printer cannot reproduce detail finer than its pixel. At least
    one octave is always kept.
    """
    if not pitch > 0:
        raise ValueError(f"pitch: expected a positive sampling pitch, got {pitch!r}")
    kept = 0
    for i in range(octaves):
        if lacunarity ** (-i) < nyquist_samples * pitch:
            break
        kept = i + 1
    return max(kept, 1)


def _fbm_octaves(
    octaves: int, lacunarity: float, H: float, min_pitch: float | None
) -> list[tuple[float, float]]:
    if min_pitch is not None:
        octaves = octaves_for_pitch(octaves, lacunarity, min_pitch)
    return [(float(lacunarity) ** i, float(lacunarity) ** (-H * i)) for i in range(octaves)]


def _turbulence_octaves(low: int, high: int, min_pitch: float | None) -> list[tuple[float, float]]:
    if min_pitch is not None:
        high = max(low, low + octaves_for_pitch(high - low + 1, 2.0, min_pitch * 2.0**low) - 1)
    return [(2.0**i, 2.0 ** (-i)) for i in range(low, high + 1)]


# ---------------------------------------------------------------------------------------------
# Evaluation on scattered points and on grids


def _noise_scattered(
    pts: np.ndarray, scale: float, key: np.uint64, impulses: int, mode_hash: bool
) -> np.ndarray:
    out = np.empty(pts.shape[0])
    if pts.shape[0] == 0:
        return out
    lo, hi = _cell_bounds(pts, scale)
    span = hi - lo + 1
    if float(np.prod(span.astype(np.float64))) <= 4.0 * pts.shape[0] + 65536:
        order, starts = _counting_sort(pts, scale, lo, span)
    else:
        # Cells spread far apart (sparse samples, huge coordinates): sort by cell instead.
        cells = np.floor(pts * scale - 0.5).astype(np.int64)
        order = np.lexsort((cells[:, 0], cells[:, 1], cells[:, 2])).astype(np.int64)
        starts = _group_starts(cells, order)
    _eval_bins(_gather_scaled(pts, order, scale), order, starts, key, np.int64(impulses), mode_hash, out)
    return out


def _noise_grid(
    axes: tuple[np.ndarray, np.ndarray, np.ndarray],
    scale: float,
    key: np.uint64,
    impulses: int,
    mode_hash: bool,
) -> np.ndarray:
    xs, ys, zs = axes
    out = np.empty((zs.size, ys.size, xs.size))
    _eval_grid(xs, ys, zs, scale, key, np.int64(impulses), mode_hash, out)
    return out


def _octave_sum(evaluate, octaves: list[tuple[float, float]], absolute: bool) -> np.ndarray:
    total = None
    for scale, weight in octaves:
        values = evaluate(scale)
        term = weight * (np.abs(values) if absolute else values)
        total = term if total is None else total + term
    return total


# ---------------------------------------------------------------------------------------------
# Public API


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
        Seed of the stateless random stream ``rnd``: the SplitMix64 sequence keyed
        by the seed, so any point is evaluated independently of the others.
    impulses : int
        Impulses per cell, ``N`` (the talk uses 30).
    cell_seed : {"hash", "frisvad"}
        How a cell picks its impulses. ``"frisvad"`` is the talk's
        ``n = 4 (N q.a + j)`` with ``a = (1, 1000, 576)``. Distinct cells share
        an index whenever ``q.a`` agrees, e.g. ``q = (1000, 0, 0)`` and
        ``(0, 1, 0)``, so the texture repeats exactly along the lattice vectors
        ``(1000, -1, 0)``, ``(576, 0, -1)`` and their combinations, which is
        visible on large prints. ``"hash"`` (the default) mixes the three 64-bit
        cell indices through a 64-bit bijective hash instead, so cells share
        impulses only by 64-bit collision.

    Returns
    -------
    (n,) float64 array
        Noise values: mean 0, standard deviation about 0.148 for N = 30. The
        normalisation keeps values within [-1, 1] in practice but does not bound
        them: about one sample in a million overshoots, by a few percent.
    """
    _check_common(impulses, cell_seed, seed)
    pts = _as_points(points)
    return _noise_scattered(pts, 1.0, seed_key(int(seed)), impulses, cell_seed == "hash")


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
    _check_fbm(octaves, lacunarity, H)
    pts = _as_points(points)
    key, mode_hash = seed_key(int(seed)), cell_seed == "hash"
    return _octave_sum(
        lambda s: _noise_scattered(pts, s, key, impulses, mode_hash),
        _fbm_octaves(octaves, lacunarity, H, min_pitch),
        absolute=False,
    )


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
    _check_turbulence(low, high)
    pts = _as_points(points)
    key, mode_hash = seed_key(int(seed)), cell_seed == "hash"
    return _octave_sum(
        lambda s: _noise_scattered(pts, s, key, impulses, mode_hash),
        _turbulence_octaves(low, high, min_pitch),
        absolute=True,
    )


def unit_noise(
    points: np.ndarray,
    *,
    A: float = 1.0,
    B: float = 1.0,
    seed: int = 0,
    impulses: int = 30,
    cell_seed: str = "hash",
) -> np.ndarray:
    """Noise mapped to [0, 1] as the talk's noise explorer shows it: ``0.5 (A noise(B p) + 1)``.

    Not a marble: printapp's veined marble is :func:`noise.veins`.

    Parameters
    ----------
    points : (n, 3) or (n, 2) float array
        Positions in noise units.
    A : float
        Contrast (the talk's slides show A = 1).
    B : float
        Frequency (B = 1: features one unit across).

    Returns
    -------
    (n,) float64 array, in [0, 1] in practice for ``abs(A) <= 1`` (see :func:`sparse_convolution`).
    """
    if not (np.isfinite(A) and np.isfinite(B)):
        raise ValueError("A, B: expected finite numbers")
    _check_common(impulses, cell_seed, seed)
    pts = _as_points(points)
    return 0.5 * (
        A * _noise_scattered(pts, float(B), seed_key(int(seed)), impulses, cell_seed == "hash") + 1.0
    )


def _grid_axes(x, y, z) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], bool]:
    return (_as_axis(x, "x"), _as_axis(y, "y"), _as_axis(z, "z")), z is None


def _shape_grid(values: np.ndarray, two_d: bool) -> np.ndarray:
    return values[0] if two_d else values


def sparse_convolution_grid(
    x: np.ndarray,
    y: np.ndarray,
    z: np.ndarray | None = None,
    *,
    seed: int = 0,
    impulses: int = 30,
    cell_seed: str = "hash",
) -> np.ndarray:
    """Sparse convolution noise on the regular grid ``x`` by ``y`` (by ``z``): the fast path.

    Equal to :func:`sparse_convolution` at the grid's points (to rounding), several
    times faster because impulses are shared by whole blocks of the grid and culled
    per plane and per row.

    Parameters
    ----------
    x, y, z : 1-D float arrays
        Ascending coordinates along each axis (noise units); without ``z`` the grid
        lies in the plane z = 0.

    Returns
    -------
    (len(y), len(x)) or (len(z), len(y), len(x)) float64 array
    """
    _check_common(impulses, cell_seed, seed)
    axes, two_d = _grid_axes(x, y, z)
    return _shape_grid(_noise_grid(axes, 1.0, seed_key(int(seed)), impulses, cell_seed == "hash"), two_d)


def fbm_grid(
    x: np.ndarray,
    y: np.ndarray,
    z: np.ndarray | None = None,
    *,
    octaves: int,
    lacunarity: float = 2.0,
    H: float = 1.0,
    seed: int = 0,
    impulses: int = 30,
    cell_seed: str = "hash",
    min_pitch: float | None = None,
) -> np.ndarray:
    """:func:`fbm` on a regular grid (see :func:`sparse_convolution_grid` for the layout)."""
    _check_common(impulses, cell_seed, seed)
    _check_fbm(octaves, lacunarity, H)
    axes, two_d = _grid_axes(x, y, z)
    key, mode_hash = seed_key(int(seed)), cell_seed == "hash"
    values = _octave_sum(
        lambda s: _noise_grid(axes, s, key, impulses, mode_hash),
        _fbm_octaves(octaves, lacunarity, H, min_pitch),
        absolute=False,
    )
    return _shape_grid(values, two_d)


def turbulence_grid(
    x: np.ndarray,
    y: np.ndarray,
    z: np.ndarray | None = None,
    *,
    low: int = 0,
    high: int = 4,
    seed: int = 0,
    impulses: int = 30,
    cell_seed: str = "hash",
    min_pitch: float | None = None,
) -> np.ndarray:
    """:func:`turbulence` on a regular grid (see :func:`sparse_convolution_grid` for the layout)."""
    _check_common(impulses, cell_seed, seed)
    _check_turbulence(low, high)
    axes, two_d = _grid_axes(x, y, z)
    key, mode_hash = seed_key(int(seed)), cell_seed == "hash"
    values = _octave_sum(
        lambda s: _noise_grid(axes, s, key, impulses, mode_hash),
        _turbulence_octaves(low, high, min_pitch),
        absolute=True,
    )
    return _shape_grid(values, two_d)
