"""Slow reference: the vein network of :mod:`noise.ridged`, point by point in plain Python and numpy.

Written from the definitions, not from the kernels: Worley's F1 and F2 by brute force
over every feature point of the 9 x 9 cells around a point, the domain warp as sums of
:func:`noise.sparse_convolution` (the project's noise, which has its own reference), and
Musgrave's ridged multifractal loop (Ebert et al., *Texturing and Modeling*, 3rd ed.,
``RidgedMultifractal``) with the profile ``max(0, 1 - d / width)^sharpness``: octave ``i``
is added with weight ``clamp(gain * s_(i-1), 0, 1)`` where that weight exceeds 0.001.
"""

from __future__ import annotations

import math

import numpy as np

from noise.hashing import seed_key
from noise.tables import stream_seed

NOISE_STD = 0.1503
SHIFT = (4.0, 4.0)
OCTAVE_SHIFT = (0.37, 0.71)
CUTOFF = 1e-3


def _uniform(key: int, i: int, j: int, n: int) -> float:
    """The project's counter-based uniform for cell (i, j, 0), output n (SplitMix64)."""
    from printapp.bench.reference.scn_reference import GOLDEN, MASK, mix64

    h = mix64(key ^ (i & MASK))
    h = mix64(((h + GOLDEN) & MASK) ^ (j & MASK))
    h = mix64(((h + GOLDEN) & MASK) ^ 0)
    return (mix64((h + n * GOLDEN) & MASK) >> 11) / 2.0**53


def cellular_point(x: float, y: float, seed: int, jitter: float = 1.0) -> tuple[float, float]:
    """F1 and F2 at (x, y): distances to the nearest two feature points, one per unit cell."""
    key = int(seed_key(int(seed)))
    ci, cj = math.floor(x), math.floor(y)
    distances = []
    for i in range(ci - 4, ci + 5):
        for j in range(cj - 4, cj + 5):
            fx = i + 0.5 + jitter * (_uniform(key, i, j, 0) - 0.5)
            fy = j + 0.5 + jitter * (_uniform(key, i, j, 1) - 0.5)
            distances.append(math.hypot(fx - x, fy - y))
    distances.sort()
    return distances[0], distances[1]


def warp(
    points: np.ndarray, warp: float, octaves: int, H: float, seed: int, streams: tuple[int, int]
) -> np.ndarray:
    """``p + warp (g_1(p / 2), g_2(p / 2))`` with fBm ``g_k`` of unit standard deviation."""
    from noise import sparse_convolution

    out = np.array(points, dtype=np.float64)
    weights = [2.0 ** (-H * i) for i in range(octaves)]
    norm = warp / (NOISE_STD * math.sqrt(sum(w * w for w in weights)))
    for axis, stream in enumerate(streams):
        g = np.zeros(len(points))
        for i, w in enumerate(weights):
            at = points * (0.5 * 2.0**i) + np.array(OCTAVE_SHIFT) * i
            g += w * sparse_convolution(at, seed=stream_seed(seed, stream))
        out[:, axis] += norm * g
    return out


def ridged(
    distances: list[float], width: float, sharpness: float, gain: float, weights: list[float]
) -> float:
    """Musgrave's ridged multifractal at one point, from its octaves' basis distances."""
    total, previous = 0.0, 1.0
    for i, d in enumerate(distances):
        weight = 1.0 if i == 0 else min(max(gain * previous, 0.0), 1.0)
        if i > 0 and weight <= CUTOFF:
            break
        u = 1.0 - d / width
        s = (u**sharpness if u > 0 else 0.0) * weight
        total += weights[i] * s
        previous = s
    return total / sum(weights)


def vein_network(
    points: np.ndarray,
    *,
    basis: str,
    octaves: int,
    lacunarity: float,
    H: float,
    gain: float,
    width: float,
    sharpness: float,
    warp_amount: float,
    warp_H: float,
    seed: int,
) -> np.ndarray:
    """One layer of :func:`noise.ridged.vein_network` (no ``min_pitch``) at (n, 2) points."""
    from noise import sparse_convolution

    q = warp(points, warp_amount, octaves + 1, warp_H, seed, (1, 2)) + np.array(SHIFT)
    weights = [lacunarity ** (-H * i) for i in range(octaves)]
    basis_values = np.empty((octaves, len(points)))
    for i in range(octaves):
        at = q * lacunarity**i + np.array(OCTAVE_SHIFT) * i
        if basis == "noise":
            basis_values[i] = np.abs(sparse_convolution(at, seed=stream_seed(seed, 0))) / NOISE_STD
        else:
            cell_seed = stream_seed(seed, 3)
            basis_values[i] = [np.subtract(*cellular_point(x, y, cell_seed)[::-1]) for x, y in at]
    return np.array(
        [ridged(list(basis_values[:, k]), width, sharpness, gain, weights) for k in range(len(points))]
    )
