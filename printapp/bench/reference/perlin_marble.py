"""Reference: Perlin's gradient noise, turbulence and marble, written from his definitions.

K. Perlin, "An image synthesizer", SIGGRAPH 1985: a lattice noise whose value at each
integer lattice point is 0 and whose gradient there is a pseudo-random unit vector,
blended between the four surrounding lattice points with the cubic ``3t^2 - 2t^3``;
``turbulence(p) = sum_i |noise(2^i p)| / 2^i`` over the octaves finer than the image
resolves; and marble ``value = (1 + sin(k u + A turbulence(p))) / 2`` with ``u`` the
coordinate across the veins. The lattice hashing is Perlin's permutation table (a
shuffled 0..255, indexed ``P[P[x] + y]``, as in his reference code of 2002). This
module shares nothing with printapp's sparse convolution noise: it is the independent
generator that fitting is tested on.
"""

from __future__ import annotations

import math

import numpy as np


class PerlinNoise:
    """2-D gradient noise of Perlin (1985), seeded: permutation and gradients from ``seed``."""

    def __init__(self, seed: int = 0) -> None:
        rng = np.random.default_rng(seed)
        self.perm = np.concatenate([rng.permutation(256)] * 2)
        angles = rng.uniform(0.0, 2.0 * math.pi, 256)
        self.grad = np.stack([np.cos(angles), np.sin(angles)], axis=-1)

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Noise at points (x, y), lattice spacing 1; values in about [-0.7, 0.7]."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        x0, y0 = np.floor(x), np.floor(y)
        fx, fy = x - x0, y - y0
        ix, iy = x0.astype(np.int64) & 255, y0.astype(np.int64) & 255
        p = self.perm

        def corner(dx: int, dy: int) -> np.ndarray:
            g = self.grad[p[p[(ix + dx) & 255] + ((iy + dy) & 255)]]
            return g[..., 0] * (fx - dx) + g[..., 1] * (fy - dy)

        sx = fx * fx * (3.0 - 2.0 * fx)
        sy = fy * fy * (3.0 - 2.0 * fy)
        bottom = corner(0, 0) * (1 - sx) + corner(1, 0) * sx
        top = corner(0, 1) * (1 - sx) + corner(1, 1) * sx
        return bottom * (1 - sy) + top * sy


def turbulence(noise: PerlinNoise, x: np.ndarray, y: np.ndarray, pixel: float) -> np.ndarray:
    """Perlin's turbulence: ``sum_i |noise(2^i p)| / 2^i`` while ``2^-i`` is coarser than ``pixel``."""
    total = np.zeros(np.broadcast(x, y).shape)
    scale = 1.0
    while scale >= pixel:
        total += np.abs(noise(x / scale, y / scale)) * scale
        scale /= 2.0
    return total


def perlin_marble(
    n: int,
    *,
    period_px: float,
    angle_deg: float,
    strength: float,
    turbulence_px: float = 64.0,
    seed: int = 0,
) -> np.ndarray:
    """An ``n x n`` Perlin marble (rows upwards, as printapp's images), values in [0, 1].

    ``value = (1 + sin(2 pi u / period_px + strength * turbulence(p / turbulence_px))) / 2``
    with ``u = -sin(a) x + cos(a) y`` (pixels) the coordinate across veins that run along
    the angle ``a`` from +x towards +y, and the turbulence's largest features
    ``turbulence_px`` pixels across.
    """
    noise = PerlinNoise(seed)
    c = np.arange(n) + 0.5
    x, y = np.meshgrid(c, c)
    a = math.radians(angle_deg)
    u = -math.sin(a) * x + math.cos(a) * y
    # Offset so that the lattice origin is not at the image's corner.
    t = turbulence(noise, x / turbulence_px + 10.37, y / turbulence_px + 3.71, 1.0 / turbulence_px)
    return 0.5 * (1.0 + np.sin(2.0 * math.pi * u / period_px + strength * t))
