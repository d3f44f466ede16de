"""Sparse convolution noise, fBm and turbulence in tangent frames: anisotropic noise that follows a surface.

Each point p carries a tangent t (its frame is (t, b, n) with n the surface normal and
b = n x t) and a stretch s_p >= 1. The noise there is sparse convolution noise whose
kernel is measured in the point's frame, offsets to impulses scaled by 1/s_p along t::

    noise(p) = c_N sqrt(s / s_p) sum_x alpha_x cubic(M_p (x - p)) + mu_N
    |M_p d|^2 = (d.t / s_p)^2 + (d.b)^2 + (d.n)^2 = |d|^2 - (1 - 1/s_p^2) (d.t)^2

so each kernel is a needle s_p long along t and 1 across: features s_p times longer
along t than across it. Only t enters (the kernel is round about t), so b and n need
not be given to evaluate, only to cull. This is how Lagae et al. ("Procedural noise
using sparse Gabor convolution", ACM TOG 28(3), 2009) make their setup-free surface
noise: impulses are scattered in 3-D world space, and each point's kernel is oriented
in that point's tangent plane, so no parametrisation is needed. We follow it for that
reason (a part has no global u, v to stretch along), and because the result is
continuous wherever the frame is: the sum is a continuous function of p, t and s_p; t
enters only through (d.t)^2, so a line field's sign flips do not matter, and where
s_p = 1 t does not enter at all. Their kernel is a Gabor kernel oriented by a
frequency vector; ours is the talk's cubic kernel sheared by a metric, so that the
same impulses give the flat noise when s = 1.

The impulses (a stratified Poisson-like process):

* lattice cells of side L hold N_c impulses each, N_c = max(1, round(N / s)) and
  L^3 = N_c s / N, so that the impulse density is N / s per unit volume and a needle
  of the design's stretch s covers as many impulses as the flat noise's ball of
  radius 1/2 (N of them per unit cell): the same count per kernel, so the same
  near-Gaussian value distribution;
* amplitudes alpha = 2 rnd - 1, uniform in (-1, 1) with independent signs (the talk's
  alpha_ij = rnd (1 - 2 (j mod 2)) alternate signs within a cell instead).

Why independent signs: with them the variance is exactly
N c_N^2 int cubic^2 / 3 whatever the cell shape, the needle's direction or the point's
position, and the autocorrelation is exactly that of the kernel, sheared by M_p: along
t the noise's correlation length is exactly s_p times the one across it. The talk's
alternating signs take from the variance a term that depends on how the kernel
straddles cells (1 - 3 E[S] / (4 int cubic^2) with S = sum over cells of the squared
kernel mass in each cell), which for a needle depends on its direction against the
lattice. ``c_N`` is chosen so that the variance is the flat noise's averaged over
positions in a cell: ``c_N = 4 / (5 N^(1/3)) sqrt(_FLAT_VARIANCE_FRACTION)``; ``mu_N`` is
the flat noise's mean (0 for even N; the talk's signs leave one extra negative impulse
per cell for odd N). ``sqrt(s / s_p)`` keeps the variance where a point's stretch is
blended down towards 1 (near singular points of its tangent field).

Against the flat (tile) path. A tile stretches its world coordinates, q = M p, and
evaluates isotropic noise at q: its impulses lie on a lattice in q, i.e. on cells
s long along t in the world. For s = 1 both are the talk's noise and the framed
functions return exactly :func:`noise.sparse_convolution` and friends. For s > 1 they
are the same random field in law up to the lattice's stratification (same impulse
count per kernel, same variance, an autocorrelation of the same shape sheared the same
way), but not the same realisation, and no method can be for a curved surface: the
flat path's impulse set depends on the direction of t (it is M^-1 of a lattice), so
following a t that turns over a surface with one impulse set (which continuity needs)
cannot reproduce it; blending several sets would change the statistics instead.

How it is made fast is in :mod:`noise._framed_kernels`.
"""

from __future__ import annotations

import math

import numpy as np

from noise._framed_kernels import _CLUSTER_EXTENT, _CLUSTER_POINTS, _clusters, _eval_framed, _morton_order
from noise.hashing import seed_key
from noise.scn import (
    _as_points,
    _check_common,
    _check_fbm,
    _check_turbulence,
    _fbm_octaves,
    _turbulence_octaves,
    fbm,
    sparse_convolution,
    turbulence,
)

_FLAT_VARIANCE_FRACTION = 0.92426
"""The flat noise's variance over its independent-sign (Poisson) value N c^2 int cubic^2 / 3.

``1 - (3/4) E[S] / int cubic^2`` with int cubic^2 = 512 pi / 45045 = 0.0357086 and
E[S] = 0.0036060, the squared kernel mass per unit cell summed over cells and
averaged over the point's position in its cell, computed as the integral of the
kernel's autocorrelation against the probability that two points share a cell,
prod_a (1 - |d_a|)+, on grids of 48^3 to 96^3 (extrapolated in h^2). Checked in the
tests by quadrature and against the flat noise's sampled standard deviation.
"""
_MORTON_CELL = 0.5  # noise units at the base octave: cells of the Z-curve that orders the points


def framed_lattice(stretch: float, impulses: int) -> tuple[int, float]:
    """Impulses per cell and the cell's side (noise units) of the framed noise for ``stretch``.

    ``N_c = max(1, round(impulses / stretch))`` and ``side^3 = N_c stretch / impulses``: the
    impulse density is ``impulses / stretch`` per unit volume.
    """
    per_cell = max(1, math.floor(impulses / stretch + 0.5))
    return per_cell, (per_cell * stretch / impulses) ** (1.0 / 3.0)


def _flat_mean(impulses: int) -> float:
    # The talk's signs alternate from j = 1 (negative): an odd N leaves one negative impulse
    # per cell, of mean amplitude -1/2, spread over the kernel's integral 16 pi / 630.
    if impulses % 2 == 0:
        return 0.0
    return -0.5 * 4.0 / (5.0 * np.cbrt(float(impulses))) * (16.0 * math.pi / 630.0)


def _as_directions(values: np.ndarray, name: str, n: int) -> np.ndarray:
    arr = np.ascontiguousarray(np.asarray(values, dtype=np.float64))
    if arr.shape != (n, 3):
        raise ValueError(f"{name}: expected an ({n}, 3) array like the points, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: expected finite values, found NaN or infinity")
    return arr


def _as_frame_inputs(points, tangents, normals, stretch, blend):
    pts = _as_points(points)
    n = pts.shape[0]
    t = _as_directions(tangents, "tangents", n)
    nrm = _as_directions(normals, "normals", n)
    if not (
        isinstance(stretch, (int, float, np.floating, np.integer)) and np.isfinite(stretch) and stretch >= 1
    ):
        raise ValueError(f"stretch: expected a number >= 1, got {stretch!r}")
    if blend is None:
        w = np.ones(n)
    else:
        w = np.ascontiguousarray(np.asarray(blend, dtype=np.float64))
        if w.shape != (n,) or not np.all((w >= 0.0) & (w <= 1.0)):
            raise ValueError(f"blend: expected ({n},) weights in [0, 1], one per point")
    length = np.linalg.norm(t, axis=1)
    live = w > 0.0
    if np.any(np.abs(length[live] - 1.0) > 1e-6):
        raise ValueError("tangents: expected unit vectors wherever blend > 0")
    return pts, t, nrm, float(stretch), w


def _framed_sum(pts, t, nrm, stretch, w, key, impulses, mode_hash, octaves, absolute) -> np.ndarray:
    per_cell, side = framed_lattice(stretch, impulses)
    s_p = 1.0 + (stretch - 1.0) * w
    squeeze = 1.0 - 1.0 / (s_p * s_p)
    norm = 4.0 / (5.0 * np.cbrt(float(impulses))) * math.sqrt(_FLAT_VARIANCE_FRACTION)
    amp = norm * np.sqrt(stretch / s_p)
    mean = _flat_mean(impulses)
    order = _morton_order(pts, _MORTON_CELL)
    total = np.zeros(pts.shape[0])
    values = np.empty(pts.shape[0])
    for scale, weight in octaves:
        if pts.shape[0] == 0:
            break
        starts = _clusters(pts, order, scale, _CLUSTER_POINTS, _CLUSTER_EXTENT)
        _eval_framed(
            pts, t, nrm, squeeze, amp, order, starts, scale, side, np.int64(per_cell), key, mode_hash, values
        )
        values += mean
        total += weight * (np.abs(values) if absolute else values)
    return total


def sparse_convolution_framed(
    points: np.ndarray,
    tangents: np.ndarray,
    normals: np.ndarray,
    *,
    stretch: float,
    blend: np.ndarray | None = None,
    seed: int = 0,
    impulses: int = 30,
    cell_seed: str = "hash",
) -> np.ndarray:
    """Sparse convolution noise stretched along each point's tangent (see the module docstring).

    Parameters
    ----------
    points : (n, 3) or (n, 2) float array
        Positions in noise units (one unit is the flat noise's cell; features are about
        one unit across t and ``stretch`` units along it).
    tangents : (n, 3) float array
        Unit tangent t per point (a line field: t and -t give the same noise). Ignored
        where ``blend`` is 0.
    normals : (n, 3) float array
        The surface normal per point (any finite vectors: they only speed up the search
        for impulses; the value depends on t alone).
    stretch : float
        The features' length along t over their width, >= 1; 1 gives exactly
        :func:`noise.sparse_convolution`.
    blend : (n,) float array in [0, 1], optional
        Per point, how much of the stretch applies: the point's stretch is
        ``1 + (stretch - 1) blend``, isotropic at 0 (where a tangent field vanishes).
        Default: 1 everywhere.
    seed, impulses, cell_seed
        As for :func:`noise.sparse_convolution`; ``impulses`` is the flat noise's N,
        whose impulse count per kernel the framed noise keeps.

    Returns
    -------
    (n,) float64 array
        Mean and standard deviation those of :func:`noise.sparse_convolution` (averaged
        over positions in a cell: 0 and about 0.148 for N = 30), values continuous in
        the points, tangents and blend.
    """
    _check_common(impulses, cell_seed, seed)
    pts, t, nrm, stretch, w = _as_frame_inputs(points, tangents, normals, stretch, blend)
    if stretch == 1.0:
        return sparse_convolution(pts, seed=seed, impulses=impulses, cell_seed=cell_seed)
    return _framed_sum(
        pts, t, nrm, stretch, w, seed_key(int(seed)), impulses, cell_seed == "hash", [(1.0, 1.0)], False
    )


def fbm_framed(
    points: np.ndarray,
    tangents: np.ndarray,
    normals: np.ndarray,
    *,
    stretch: float,
    octaves: int,
    lacunarity: float = 2.0,
    H: float = 1.0,
    blend: np.ndarray | None = None,
    seed: int = 0,
    impulses: int = 30,
    cell_seed: str = "hash",
    min_pitch: float | None = None,
) -> np.ndarray:
    """fBm over :func:`sparse_convolution_framed`: ``sum_i lacunarity^(-H i) noise(p lacunarity^i)``.

    Every octave has the same frame and stretch, so the whole sum is ``stretch`` times
    longer along t than across it. Parameters as for :func:`noise.fbm` and
    :func:`sparse_convolution_framed`; ``min_pitch`` drops octaves finer than two samples
    across t. With ``stretch`` 1, exactly :func:`noise.fbm`.
    """
    _check_common(impulses, cell_seed, seed)
    _check_fbm(octaves, lacunarity, H)
    pts, t, nrm, stretch, w = _as_frame_inputs(points, tangents, normals, stretch, blend)
    if stretch == 1.0:
        return fbm(
            pts,
            octaves=octaves,
            lacunarity=lacunarity,
            H=H,
            seed=seed,
            impulses=impulses,
            cell_seed=cell_seed,
            min_pitch=min_pitch,
        )
    return _framed_sum(
        pts,
        t,
        nrm,
        stretch,
        w,
        seed_key(int(seed)),
        impulses,
        cell_seed == "hash",
        _fbm_octaves(octaves, lacunarity, H, min_pitch),
        False,
    )


def turbulence_framed(
    points: np.ndarray,
    tangents: np.ndarray,
    normals: np.ndarray,
    *,
    stretch: float,
    low: int = 0,
    high: int = 4,
    blend: np.ndarray | None = None,
    seed: int = 0,
    impulses: int = 30,
    cell_seed: str = "hash",
    min_pitch: float | None = None,
) -> np.ndarray:
    """Turbulence over :func:`sparse_convolution_framed`: ``sum_{i=low}^{high} 2^-i |noise(2^i p)|``.

    Parameters as for :func:`noise.turbulence` and :func:`sparse_convolution_framed`. With
    ``stretch`` 1, exactly :func:`noise.turbulence`.
    """
    _check_common(impulses, cell_seed, seed)
    _check_turbulence(low, high)
    pts, t, nrm, stretch, w = _as_frame_inputs(points, tangents, normals, stretch, blend)
    if stretch == 1.0:
        return turbulence(
            pts, low=low, high=high, seed=seed, impulses=impulses, cell_seed=cell_seed, min_pitch=min_pitch
        )
    return _framed_sum(
        pts,
        t,
        nrm,
        stretch,
        w,
        seed_key(int(seed)),
        impulses,
        cell_seed == "hash",
        _turbulence_octaves(low, high, min_pitch),
        True,
    )
