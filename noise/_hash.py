"""Stateless integer hashing shared by the noise kernels.

All arithmetic is on ``uint64`` with explicit casts: numba promotes mixed
``int64``/``uint64`` expressions to ``float64``, which would silently lose bits.
"""

import numpy as np
from numba import njit

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_INV_2_53 = 1.0 / 9007199254740992.0


@njit(cache=True, inline="always")
def _splitmix64(x: np.uint64) -> np.uint64:
    # Steele, Lea & Flood (2014), SplitMix64 finaliser: a bijection on 64 bits
    # whose output bits all depend on all input bits.
    z = x + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    return z ^ (z >> np.uint64(31))


@njit(cache=True, inline="always")
def _rnd(seed_key: np.uint64, n: np.uint64) -> float:
    """Uniform number in [0, 1) for index ``n`` of the stream ``seed_key``."""
    return float(_splitmix64(seed_key ^ _splitmix64(n)) >> np.uint64(11)) * _INV_2_53


@njit(cache=True, inline="always")
def _hash_cell(seed_key: np.uint64, qx: np.int64, qy: np.int64, qz: np.int64) -> np.uint64:
    h = _splitmix64(seed_key ^ np.uint64(qx))
    h = _splitmix64(h ^ np.uint64(qy))
    return _splitmix64(h ^ np.uint64(qz))


def seed_key(seed: int) -> np.uint64:
    """Map a user seed (any Python int) to the 64-bit key of its random stream."""
    mask = 0xFFFFFFFFFFFFFFFF
    z = (seed + 0x9E3779B97F4A7C15) & mask
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & mask
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & mask
    return np.uint64(z ^ (z >> 31))
