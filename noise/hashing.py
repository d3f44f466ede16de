"""Stateless integer hashing and counter-based random numbers (SplitMix64), public for every kernel.

The noise kernels, the gonioreflectometer and the benchmarks draw their random numbers
here, so that every stream is a pure function of (seed, index): no state, any order,
byte-identical results for the same seed.

All arithmetic is on ``uint64`` with explicit casts: numba promotes mixed
``int64``/``uint64`` expressions to ``float64``, which would silently lose bits.
"""

import numpy as np
from numba import njit

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_INV_2_53 = 1.0 / 9007199254740992.0
_MASK = 0xFFFFFFFFFFFFFFFF


@njit(cache=True, inline="always")
def mix64(z: np.uint64) -> np.uint64:
    """A 64-bit hash of ``z``: Stafford's "Mix13" finaliser (numba, inlined into callers)."""
    # Stafford's "Mix13" finaliser, as in SplitMix64 (Steele, Lea & Flood 2014): a
    # bijection on 64 bits in which every output bit depends on every input bit.
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    return z ^ (z >> np.uint64(31))


@njit(cache=True, inline="always")
def stream_uniform(seed_key: np.uint64, n: np.uint64) -> float:
    """Uniform number in [0, 1): output ``n`` of the SplitMix64 stream keyed by ``seed_key``.

    SplitMix64's n-th output is ``mix(key + n * golden)``, so any index is one
    multiply and one mix away: the talk's ``rnd(t_n)`` with no state.
    """
    return float(mix64(seed_key + n * _GOLDEN) >> np.uint64(11)) * _INV_2_53


@njit(cache=True, inline="always")
def hash_cell(seed_key: np.uint64, qx: np.int64, qy: np.int64, qz: np.int64) -> np.uint64:
    """The key of lattice cell (qx, qy, qz) in the stream ``seed_key``: three chained mixes."""
    h = mix64(seed_key ^ np.uint64(qx))
    h = mix64(h + _GOLDEN ^ np.uint64(qy))
    return mix64(h + _GOLDEN ^ np.uint64(qz))


def seed_key(seed: int) -> np.uint64:
    """Map a user seed (any Python int) to the 64-bit key of its random stream."""
    z = (seed * 0x9E3779B97F4A7C15 + 0x632BE59BD9B4E019) & _MASK
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK
    return np.uint64(z ^ (z >> 31))
