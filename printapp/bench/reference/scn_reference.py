"""Slow reference: sparse convolution noise per point, in plain Python integers and floats.

Written from the talk's formulas independently of the numba kernels, to check them.
"""

import math

MASK = (1 << 64) - 1
GOLDEN = 0x9E3779B97F4A7C15


def mix64(z: int) -> int:
    """SplitMix64's finaliser on a 64-bit integer."""
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK
    return z ^ (z >> 31)


def seed_key(seed: int) -> int:
    """The stream key of a noise seed."""
    return mix64((seed * GOLDEN + 0x632BE59BD9B4E019) & MASK)


def rnd(key: int, n: int) -> float:
    """Output n of the SplitMix64 stream keyed by key, as a double in [0, 1)."""
    return (mix64((key + n * GOLDEN) & MASK) >> 11) / 2.0**53


def cell_base(key: int, q: tuple[int, int, int], n_impulses: int, mode: str) -> int:
    """Index of cell ``q``'s first random number: hashed (``"hash"``) or Frisvad's dot product."""
    if mode == "frisvad":
        dot = q[0] * 1 + q[1] * 1000 + q[2] * 576
        return (4 * n_impulses * dot) & MASK
    h = mix64(key ^ (q[0] & MASK))
    h = mix64(((h + GOLDEN) & MASK) ^ (q[1] & MASK))
    h = mix64(((h + GOLDEN) & MASK) ^ (q[2] & MASK))
    return (4 * n_impulses * h) & MASK


def scn(p: tuple[float, float, float], seed: int = 0, n_impulses: int = 30, mode: str = "hash") -> float:
    """Sparse convolution noise at point ``p``: the eight nearest cells' impulses, summed."""
    key = seed_key(seed)
    base = [math.floor(c - 0.5) for c in p]
    total = 0.0
    for i in range(8):
        q = (base[0] + (i % 2), base[1] + (i // 2) % 2, base[2] + (i // 4) % 2)
        b = cell_base(key, q, n_impulses, mode)
        for j in range(1, n_impulses + 1):
            n = (b + 4 * j) & MASK
            alpha = rnd(key, n) * (1 - 2 * (j % 2))
            x = [q[k] + rnd(key, n + 1 + k) for k in range(3)]
            v2 = sum((x[k] - p[k]) ** 2 for k in range(3))
            if v2 < 0.25:
                total += alpha * (1.0 - 4.0 * v2) ** 3
    return 4.0 / (5.0 * n_impulses ** (1.0 / 3.0)) * total
