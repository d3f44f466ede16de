"""Slow reference: sparse convolution noise per point, in plain Python integers and floats.

Written from the talk's formulas independently of the numba kernels, to check them.
"""

import math

MASK = (1 << 64) - 1


def splitmix64(x: int) -> int:
    z = (x + 0x9E3779B97F4A7C15) & MASK
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK
    return z ^ (z >> 31)


def rnd(key: int, n: int) -> float:
    return (splitmix64(key ^ splitmix64(n & MASK)) >> 11) / 2.0**53


def cell_base(key: int, q: tuple[int, int, int], n_impulses: int, mode: str) -> int:
    if mode == "frisvad":
        dot = q[0] * 1 + q[1] * 1000 + q[2] * 576
        return (4 * n_impulses * dot) & MASK
    h = splitmix64(key ^ (q[0] & MASK))
    h = splitmix64(h ^ (q[1] & MASK))
    h = splitmix64(h ^ (q[2] & MASK))
    return (4 * n_impulses * h) & MASK


def scn(p: tuple[float, float, float], seed: int = 0, n_impulses: int = 30, mode: str = "hash") -> float:
    key = splitmix64(seed & MASK)
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
